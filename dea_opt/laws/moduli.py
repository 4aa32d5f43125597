"""The table of moduli: which ``H`` (MPa) to give a joint's layer, and where the number comes from.

One source for three readers: ``dea-opt init --material`` writes a row's ``H`` with its source
into the scenario's comments, the check before a run (:mod:`dea_opt.run.preflight`) takes the
range of every row as the range of plausible moduli, and the tutorial *Your own joint* prints
the table (the documentation's ``dea-moduli`` directive reads :data:`MODULI`).

A study gives either a Young's modulus ``E`` with a Poisson's ratio ``nu`` (an elastic-foundation
model then uses the confined modulus :func:`confined_modulus`, as OpenSim-JAM's lumped model of
Bei & Fregly does) or the spring's modulus itself (then ``H = E``).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DEFAULT_MATERIAL", "MODULI", "Modulus", "confined_modulus"]


def confined_modulus(E: float, nu: float) -> float:
    """The confined (oedometric) modulus ``(1 - nu) E / ((1 + nu)(1 - 2 nu))`` (MPa) of an
    isotropic layer of Young's modulus ``E`` (MPa) and Poisson's ratio ``nu``."""
    return (1.0 - nu) * E / ((1.0 + nu) * (1.0 - 2.0 * nu))


@dataclass(frozen=True)
class Modulus:
    """One row of the table of moduli.

    Attributes
    ----------
    key : str
        Its name for ``dea-opt init --material``.
    material : str
        The joint and the material.
    source : str
        The publication (or model) the number comes from.
    gives : str
        What the source gives.
    advice : str
        The ``H`` to use, in words.
    H : float
        The modulus ``dea-opt init`` writes (MPa).
    """

    key: str
    material: str
    source: str
    gives: str
    advice: str
    H: float


MODULI: tuple[Modulus, ...] = (
    Modulus(
        "cartilage-slow",
        "cartilage, any joint, slow loading",
        "K. Y. Volokh, E. Y. S. Chao, M. Armand, On foundations of discrete element analysis of contact in "
        "diarthrodial joints (the paper dea-opt implements)",
        "aggregate (equilibrium) modulus 0.3-0.6 MPa",
        "0.3-0.6 MPa for loads held for minutes only; not for gait",
        0.45,
    ),
    Modulus(
        "knee-cartilage",
        "knee cartilage",
        "R. L. Lenhart, J. Kaiser, C. R. Smith, D. G. Thelen, Prediction and validation of load-dependent behavior "
        "of the tibiofemoral and patellofemoral joints during movement, Ann. Biomed. Eng. 43(11):2675-2685, 2015; "
        "its model lenhart2015.osim in OpenSim-JAM (C. R. Smith, github.com/clnsmith/opensim-jam)",
        "elastic foundation, E = 10 MPa, nu = 0.45, 3 mm per layer",
        f"10 MPa read as the spring's modulus; {confined_modulus(10.0, 0.45):.1f} MPa as JAM's lumped model uses it",
        10.0,
    ),
    Modulus(
        "hip-cartilage",
        "hip cartilage",
        "C. L. Abraham, S. A. Maas, J. A. Weiss, B. J. Ellis, C. L. Peters, A. E. Anderson, A new discrete element "
        "analysis method for predicting hip joint contact stresses, J. Biomech. 46(6):1121-1127, 2013 (DEA against "
        "a validated FE model, same material properties)",
        "the modulus: not verified (only the abstract could be read); the abstract gives DEA peak pressures "
        "9.8-13.6 MPa, mean 3.0-3.7 MPa in walking and stairs",
        "not from a source: dea-opt's demo uses 10 MPa (peak strain near 20 %); compare your pressures with theirs",
        10.0,
    ),
    Modulus(
        "ankle-cartilage",
        "ankle cartilage",
        "I. Benemerito, L. Modenese, E. Montefiori, C. Mazzà, M. Viceconti, D. Lacroix, L. Guo, An extended "
        "discrete element method for the estimation of contact pressure at the ankle joint during stance phase, "
        "Proc. IMechE H 234(5):507-516, 2020",
        "the modulus: not verified (only the abstract could be read); the abstract gives DEA peak pressure "
        "6.9-7.3 MPa at toe-off, contact area 4.2-4.7 cm²",
        "not from a source: start at 10 MPa and compare your pressures with theirs",
        10.0,
    ),
    Modulus(
        "uhmwpe-cams",
        "UHMWPE tibial insert (knee replacement)",
        "the CAMS-Knee M+ model of OpenSim-JAM, cams_Mplus_right_contact.osim",
        "E = 463 MPa, nu = 0.45, 3 mm layers",
        f"{confined_modulus(463.0, 0.45):.0f} MPa, lumped (the Grand Challenge model DM.osim of the same toolkit "
        "gives a tenth of it: check yours)",
        round(confined_modulus(463.0, 0.45)),
    ),
    Modulus(
        "uhmwpe-dm",
        "UHMWPE tibial insert (knee replacement)",
        "the Grand Challenge model DM.osim of OpenSim-JAM (../shared/data/tka/material.json)",
        "E = 46.3 MPa, nu = 0.46, 5 mm layers",
        f"{confined_modulus(46.3, 0.46):.0f} MPa, lumped (the CAMS-Knee M+ model gives ten times as much: check yours)",
        round(confined_modulus(46.3, 0.46)),
    ),
    Modulus(
        "uhmwpe-ankle",
        "UHMWPE bearing (ankle replacement)",
        "a finite element foot model with a total ankle arthroplasty, PMC9579782, Table 1",
        "polyethylene E = 475 MPa, nu = 0.38",
        f"{confined_modulus(475.0, 0.38):.0f} MPa (confined)",
        round(confined_modulus(475.0, 0.38)),
    ),
)

#: The row ``dea-opt init`` writes unless told otherwise: cartilage under walking, whose
#: instantaneous modulus the knee's source gives.
DEFAULT_MATERIAL = "knee-cartilage"


def modulus(key: str) -> Modulus:
    """The row named ``key`` (an :class:`~dea_opt.errors.InputError` listing the names otherwise)."""
    from ..errors import InputError

    for row in MODULI:
        if row.key == key:
            return row
    raise InputError(f"--material must be one of {', '.join(row.key for row in MODULI)}, got {key!r}")
