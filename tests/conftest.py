"""Shared fixtures: the reference problems of the core tests, with their closed forms."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

import dea_opt as d
from dea_opt import formulations
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer

#: The methods every test is parametrized over.
METHODS = ("newton", "qp", "nlp")
#: Tight options so the three formulations can be compared to 1e-6.
TIGHT = {"newton": {}, "qp": {"tol": 1e-12}, "nlp": {}}

SHARED = Path(__file__).resolve().parents[2] / "shared"
KNEE = SHARED / "data" / "knee"


def applies(method, law) -> bool:
    """Whether ``method`` takes ``law``, as the registry's capabilities say (``auto`` takes any)."""
    return method == "auto" or formulations.takes(method, law)


def method_law_pairs(methods, laws) -> list:
    """``pytest.param(method, law)`` for the pairs the capabilities allow, and only those (no
    run-time skips for pairs that do not apply)."""
    return [
        pytest.param(method, law, id=f"{getattr(law, 'name', type(law).__name__)}-{method}")
        for law in laws
        for method in methods
        if applies(method, law)
    ]


def solve_quietly(problem, method, **options):
    """Solve with the tight options of ``method``, silencing ValidityWarning on purpose."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, method, **{**TIGHT[method], **options})


@pytest.fixture(scope="session")
def plate():
    return plate_layer(40.0, 10.0, 400, 10, thickness=2.0)


@pytest.fixture(scope="session")
def socket():
    return socket_layer(radius=25.0, thickness=2.0, coverage=90.0, n_rings=60, n_sectors=120)


@pytest.fixture(scope="session")
def bed():
    return sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=120, n_sectors=64)
