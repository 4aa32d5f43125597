"""Is the linear spring valid up to 30 % strain?  The paper's claim put to the test under load.
============================================================================================

Volokh, Chao & Armand find Ateshian's law, Eq. (2), "almost linear up to 30 % strain" and
conclude that the classical linear DEA spring is valid there. This example measures that claim
twice, in numbers:

1. **stress-strain shape**: the relative deviation of ``sigma = H eps`` from Eq. (2) at 30 %
   strain, and the strains at which it reaches 5 % and 10 % (closed form, no contact solve);
2. **pressure under a load**: load-controlled contact solves of a rigid sphere on a bonded
   layer (R = 25 mm, h = 2 mm) and of a ball in a hip socket (R = 25 mm, h = 3 mm, load tilted
   20 degrees), sweeping the load, with the linear law, Eq. (2) for beta = 0.05 and 0.6, the
   cubic of Eq. (3) and the 5th-order polynomial of Remark 2 (all with the same H). Peak
   pressure, contact area and approach are recorded against the load and against the largest
   compressive strain reached; the strain at which the linear law's peak pressure departs from
   Eq. (2)'s by 5 % and 10 % is interpolated on the sweep.

The real knee of ``../shared/data/knee`` is added when that directory exists (its springs cast by
``dea_opt.mesh.springs_from_meshes``); otherwise the script says it is skipped. Any other problem can be
swept by passing a :class:`dea_opt.ContactProblem` to :func:`run` (``extra_problems``).

Run it with::

    python examples/linear_validity.py --out figures/

(``--coarse`` for the fast setting the tests use; ``--knee DIR`` for another knee directory,
``--no-knee`` to leave it out).
It writes ``validity_<geometry>.png``, ``validity_sweep.csv`` (one row per law and load),
``validity_departures.csv`` and ``validity_summary.md`` into ``--out`` (default
``examples/output/linear_validity/``).

Units: mm, N, MPa. Relative deviation means ``(linear - Eq. 2) / Eq. 2``, negative where the
linear spring predicts less. The linear law is driven far past 30 % strain on purpose, so its
:class:`dea_opt.ValidityWarning` is silenced here.
"""

from __future__ import annotations

import argparse
import io
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: the example must run without a display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

import dea_opt  # noqa: E402
from dea_opt.files import write_data  # noqa: E402
from dea_opt.geometry import socket_layer, sphere_on_bed_layer  # noqa: E402

NAME = "linear_validity"
DEFAULT_OUT = Path(__file__).resolve().parent / "output" / NAME
DEFAULT_KNEE = Path(__file__).resolve().parents[2] / "shared" / "data" / "knee"

H_DEFAULT = 0.6  # MPa, the upper end of the paper's 0.3 <= H_A0 <= 0.6
BETAS = (0.05, 0.6)  # the limit values of the paper's range
LEVELS = (0.05, 0.10)  # deviations at which the linear law is said to depart
CLAIM_STRAIN = 0.30  # the paper's limit of validity of the linear spring

SPHERE = {"radius": 25.0, "thickness": 2.0, "extent": 8.0}
HIP = {"radius": 25.0, "thickness": 3.0, "coverage": 90.0, "tilt_deg": 20.0, "gap": 0.0}
#: Mesh and sweep resolution: (default, coarse).
SPHERE_MESH = ({"n_rings": 160, "n_sectors": 32}, {"n_rings": 120, "n_sectors": 8})
HIP_MESH = ({"n_rings": 45, "n_sectors": 90}, {"n_rings": 15, "n_sectors": 30})
N_LOADS = (30, 12)
#: The knee has ~18 000 springs: fewer loads keep its sweep to seconds.
KNEE_N_LOADS = (15, 8)
#: Sphere loads are set by the linear law's peak strain (closed form) over this range.
SPHERE_STRAINS = (0.01, 0.5)
#: Hip loads (N): from a light touch to a few kN, the peaks of gait.
HIP_LOADS = (10.0, 3000.0)
#: Knee loads (N): with H = 0.6 MPa the real knee passes 30 % strain below 100 N and the
#: contact leaves the proximity window of the springs (KNEE_MAX_GAP) above about 300 N.
KNEE_LOADS = (5.0, 300.0)
KNEE_MAX_GAP = 5.0  # mm: springs are cast only where the surfaces are this close
GEOMETRIES = ("sphere", "hip", "knee")


# --- laws -------------------------------------------------------------------------------
def validity_laws(H: float = H_DEFAULT, betas=BETAS) -> dict:
    """The laws compared, all with the same ``H`` (MPa), keyed by a short name.

    ``linear``; then for each beta ``ateshian_b<beta>`` (Eq. 2), ``cubic_b<beta>`` (Eq. 3)
    and ``order5_b<beta>`` (Remark 2).
    """
    laws = {"linear": dea_opt.LinearLaw(H)}
    for b in betas:
        laws[f"ateshian_b{b:g}"] = dea_opt.AteshianLaw(H, b)
        laws[f"cubic_b{b:g}"] = dea_opt.CubicLaw(H, b)
        laws[f"order5_b{b:g}"] = dea_opt.PolynomialLaw(H, b, 5)
    return laws


def law_family(law: dea_opt.Law) -> tuple[str, float | None]:
    """``(family, beta)`` of a law, e.g. ``("order5", 0.6)``; beta is None for linear."""
    family = law.name if law.name != "polynomial" else f"order{law.order}"
    return family, getattr(law, "beta", None)


def law_deviation(H: float, beta: float, strain) -> np.ndarray:
    """Relative deviation of ``sigma = H eps`` from Eq. (2): ``H eps / sigma_Eq2 - 1``."""
    strain = np.asarray(strain, dtype=float)
    return dea_opt.LinearLaw(H).stress(strain) / dea_opt.AteshianLaw(H, beta).stress(strain) - 1.0


def law_departure_strain(beta: float, level: float) -> float:
    """Compressive strain (> 0) at which the linear law's stress is ``level`` off Eq. (2).

    The deviation grows monotonically with compression, so the root is unique on (0, 1).
    ``H`` cancels out of the ratio.
    """
    return float(brentq(lambda s: abs(law_deviation(1.0, beta, -s)) - level, 1e-9, 0.99, xtol=1e-12))


def best_single_modulus(beta: float, strain: float = CLAIM_STRAIN) -> dict:
    """The linear modulus that best fits Eq. (2) over compressive strains (0, ``strain``].

    A biomechanist may fit ``H`` to the test rather than take Eq. (2)'s initial slope. The
    secant ratio ``r = sigma / (H eps)`` rises from 1 at zero strain to ``r_max`` at
    ``strain``; the modulus ``k H`` minimising the worst relative error ``|k / r - 1|`` is
    ``k = 2 r_max / (1 + r_max)``, with worst error ``(r_max - 1) / (r_max + 1)``.
    """
    r_max = 1.0 / (1.0 + float(law_deviation(1.0, beta, -strain)))
    return {"modulus_ratio": 2.0 * r_max / (1.0 + r_max), "worst_error": (r_max - 1.0) / (r_max + 1.0)}


def shape_analysis(betas=BETAS, levels=LEVELS, claim_strain: float = CLAIM_STRAIN) -> dict:
    """The stress-strain shape test of the claim, per beta.

    Returns
    -------
    dict
        ``{beta: {"deviation_at_claim": float, "departure": {level: strain},
        "best_modulus_ratio": float, "best_worst_error": float}}``.
    """
    out = {}
    for b in betas:
        best = best_single_modulus(b, claim_strain)
        out[b] = {
            "deviation_at_claim": float(law_deviation(1.0, b, -claim_strain)),
            "departure": {level: law_departure_strain(b, level) for level in levels},
            "best_modulus_ratio": best["modulus_ratio"],
            "best_worst_error": best["worst_error"],
        }
    return out


# --- closed forms of the linear sphere on a bed ----------------------------------------
def sphere_linear_force(approach, H: float, radius: float, thickness: float):
    """Load (N) that pushes a rigid sphere ``approach`` (mm) into a linear bonded layer.

    Integrating ``p = H (d - gap) / h`` with the exact gap ``R - sqrt(R^2 - rho^2)`` over the
    contact disc gives ``F = pi H d^2 (R - d / 3) / h``.
    """
    d = np.asarray(approach, dtype=float)
    return np.pi * H * d**2 * (radius - d / 3.0) / thickness


def sphere_linear_approach(force: float, H: float, radius: float, thickness: float) -> float:
    """Inverse of :func:`sphere_linear_force` (mm) on ``0 <= d <= R``."""
    return float(
        brentq(lambda d: sphere_linear_force(d, H, radius, thickness) - force, 0.0, radius, xtol=1e-15, rtol=1e-14)
    )


def sphere_linear_peak(approach, H: float, thickness: float):
    """Peak pressure (MPa) of the linear sphere: ``H d / h`` under the pole."""
    return H * np.asarray(approach, dtype=float) / thickness


def sphere_loads(
    H: float, n: int, strains=SPHERE_STRAINS, radius=SPHERE["radius"], thickness=SPHERE["thickness"]
) -> np.ndarray:
    """Loads (N) at which the linear sphere reaches peak strains geometric over ``strains``."""
    peak_strain = np.geomspace(*strains, n)
    return sphere_linear_force(peak_strain * thickness, H, radius, thickness)


# --- problems ---------------------------------------------------------------------------
def sphere_problem(
    law, *, radius=SPHERE["radius"], thickness=SPHERE["thickness"], extent=SPHERE["extent"], n_rings=160, n_sectors=32
) -> dea_opt.ContactProblem:
    """Rigid sphere (body 2, free in uz) on a bonded layer, pushed down by a unit load."""
    layer = sphere_on_bed_layer(radius=radius, thickness=thickness, extent=extent, n_rings=n_rings, n_sectors=n_sectors)
    return dea_opt.ContactProblem(layer, law, force=(0.0, 0.0, -1.0), reference=(0.0, 0.0, radius), free=("uz",))


def hip_problem(
    law,
    *,
    radius=HIP["radius"],
    thickness=HIP["thickness"],
    coverage=HIP["coverage"],
    tilt_deg=HIP["tilt_deg"],
    gap=HIP["gap"],
    n_rings=45,
    n_sectors=90,
) -> dea_opt.ContactProblem:
    """Femoral head (body 2, free to translate) in a socket, unit load ``tilt_deg`` off vertical.

    The socket is a spherical cap of half-angle ``coverage`` (degrees) opening upward around
    the head's centre at the origin; the load points down and tilts toward +x.
    """
    layer = socket_layer(
        radius=radius, thickness=thickness, coverage=coverage, n_rings=n_rings, n_sectors=n_sectors, gap=gap
    )
    t = np.radians(tilt_deg)
    return dea_opt.ContactProblem(
        layer, law, force=(np.sin(t), 0.0, -np.cos(t)), reference=(0.0, 0.0, 0.0), free=("ux", "uy", "uz")
    )


# --- the knee, when the mesh tools exist ------------------------------------------------
def find_mesh_builder():
    """``dea_opt.mesh.springs_from_meshes``, what turns the knee's meshes into springs; None when
    the mesh tools do not import (the knee is then skipped, the rest of the study runs)."""
    try:
        from dea_opt.mesh import springs_from_meshes  # noqa: PLC0415 - the mesh tools load only for the knee
    except ImportError:
        return None
    return springs_from_meshes


def concatenate_layers(layers: dict) -> dea_opt.SpringLayer:
    """One layer from several ``{label: SpringLayer}``, each spring labelled with its key."""
    parts = list(layers.values())
    return dea_opt.SpringLayer(
        np.vstack([p.points for p in parts]),
        np.vstack([p.normals for p in parts]),
        np.concatenate([p.areas for p in parts]),
        np.concatenate([p.thickness for p in parts]),
        np.concatenate([p.gap for p in parts]),
        labels=np.concatenate([np.full(len(p), label) for label, p in layers.items()]),
    )


def knee_problem(law, data_dir=DEFAULT_KNEE, builder=None, max_gap: float = KNEE_MAX_GAP) -> dea_opt.ContactProblem:
    """Femoral cartilage (body 2) on the medial and lateral tibial cartilage (body 1).

    Springs are cast from each tibial plateau to the femur with
    ``builder(tibia, femur, max_gap=max_gap)`` (default :func:`find_mesh_builder`); thickness
    comes from the closed cartilage surfaces. The femur carries a unit axial load (-z, tibia
    toward femur is +z) and may move along z and rotate in varus-valgus (about y, x being
    medial-lateral). Springs are labelled ``medial`` / ``lateral``.
    """
    builder = builder or find_mesh_builder()
    if builder is None:
        raise RuntimeError("this dea-opt has no mesh-to-springs builder")
    data_dir = Path(data_dir)
    femur = data_dir / "femoral_cartilage.stl"
    layer = concatenate_layers(
        {
            side: builder(str(data_dir / f"{side}_tibial_cartilage.stl"), str(femur), max_gap=max_gap)
            for side in ("medial", "lateral")
        }
    )
    centre = layer.areas @ layer.points / layer.areas.sum()
    return dea_opt.ContactProblem(layer, law, force=(0.0, 0.0, -1.0), reference=tuple(centre), free=("uz", "ry"))


# --- the sweep --------------------------------------------------------------------------
SWEEP_COLUMNS = [
    "geometry",
    "law",
    "family",
    "beta",
    "load_N",
    "peak_pressure_MPa",
    "mean_pressure_MPa",
    "contact_area_mm2",
    "approach_mm",
    "max_strain",
    "iterations",
    "solve_time_s",
]


def load_sweep(
    problem: dea_opt.ContactProblem, laws: dict, loads, *, geometry: str = "problem", check=None
) -> pd.DataFrame:
    """Solve ``problem`` for every law and load magnitude (load control).

    Parameters
    ----------
    problem : ContactProblem
        Its body-2 force gives the load direction; its magnitude is ignored, and so is any
        moment (each load is a pure force along that direction, in N).
    laws : dict {name: Law}
    loads : array_like
        Load magnitudes in N, increasing (each solve warm-starts from the previous one).
    geometry : str
        Label written into the table.
    check : callable(Solution), optional
        Called on every solution, e.g. to reject contact that reached the model's edge.

    Returns
    -------
    pandas.DataFrame
        One row per (law, load): ``geometry, law, family, beta, load_N, peak_pressure_MPa,
        mean_pressure_MPa, contact_area_mm2, approach_mm, max_strain, iterations,
        solve_time_s``. ``approach_mm`` is body 2's translation along the load.
    """
    direction = np.asarray(problem.body2.force, dtype=float)
    direction = direction / np.linalg.norm(direction)
    rows = []
    for name, law in laws.items():
        family, beta = law_family(law)
        base = problem.with_law(law)
        x0 = None
        for load in np.asarray(loads, dtype=float):
            with warnings.catch_warnings():
                # Exploring the linear law beyond 30 % strain is the point of this study.
                warnings.simplefilter("ignore", dea_opt.ValidityWarning)
                s = dea_opt.solve(base.with_load(force=tuple(load * direction)), "newton", x0=x0)
            if check is not None:
                check(s)
            x0 = s.u[base.free_indices]
            rows.append(
                {
                    "geometry": geometry,
                    "law": name,
                    "family": family,
                    "beta": beta,
                    "load_N": float(load),
                    "peak_pressure_MPa": s.peak_pressure,
                    "mean_pressure_MPa": s.mean_pressure,
                    "contact_area_mm2": s.contact_area,
                    "approach_mm": float(s.u[6:9] @ direction),
                    "max_strain": s.max_compressive_strain,
                    "iterations": s.iterations,
                    "solve_time_s": s.solve_time,
                }
            )
    return pd.DataFrame(rows, columns=SWEEP_COLUMNS)


def sphere_edge_check(n_sectors: int):
    """A ``check`` for :func:`load_sweep`: fail if contact reaches the bed's outer ring.

    Beyond it the bed has no springs, so the answer would be that of a truncated bed.
    """

    def check(solution):
        if solution.in_contact[-n_sectors:].any():
            raise RuntimeError("contact reached the edge of the bed: raise `extent` or lower the loads")

    return check


def window_check(max_gap: float, margin: float = 0.05):
    """A ``check`` for :func:`load_sweep` on mesh-cast springs: fail if contact reaches the
    springs cast at the edge of the proximity window (gap near ``max_gap``, mm).

    Farther surface points have no spring, so such an answer misses contact.
    """

    def check(solution):
        gap = solution.problem.layer.gap[solution.in_contact]
        if gap.size and gap.max() > (1.0 - margin) * max_gap:
            raise RuntimeError(
                f"contact reached springs with gap {gap.max():.3g} mm, at the edge of "
                f"the max_gap = {max_gap:g} mm window: raise max_gap or lower the loads"
            )

    return check


# --- the pressure analysis --------------------------------------------------------------
def _law_rows(frame: pd.DataFrame, name: str) -> pd.DataFrame:
    return frame[frame["law"] == name].sort_values("load_N").reset_index(drop=True)


def relative_to(frame: pd.DataFrame, approx: str, reference: str, quantity: str) -> np.ndarray:
    """``(q_approx - q_ref) / q_ref`` at each load of the sweep."""
    a, r = _law_rows(frame, approx), _law_rows(frame, reference)
    if not np.allclose(a["load_N"], r["load_N"]):
        raise ValueError(f"{approx} and {reference} were swept over different loads")
    return a[quantity].to_numpy() / r[quantity].to_numpy() - 1.0


def departure(
    frame: pd.DataFrame, approx: str, reference: str, level: float, quantity: str = "peak_pressure_MPa"
) -> dict | None:
    """Where ``|q_approx / q_ref - 1|`` first reaches ``level`` along the sweep (interpolated).

    Returns
    -------
    dict or None
        ``{"load_N", "strain_reference", "strain_approx"}``: the load and the largest
        compressive strain of the reference (Eq. 2) and of the approximation there; None when
        the sweep never reaches ``level``. Interpolation is linear in the deviation between
        the two sweep points that bracket it (loads geometrically).
    """
    dev = np.abs(relative_to(frame, approx, reference, quantity))
    a, r = _law_rows(frame, approx), _law_rows(frame, reference)
    above = np.flatnonzero(dev >= level)
    if not above.size:
        return None
    k = int(above[0])
    if k == 0:
        t, k = 1.0, 1  # already past the level at the first load: report the first point
    else:
        t = (level - dev[k - 1]) / (dev[k] - dev[k - 1])
    loads = r["load_N"].to_numpy()

    def lerp(values):
        return float(values[k - 1] + t * (values[k] - values[k - 1]))

    return {
        "load_N": float(np.exp(lerp(np.log(loads)))),
        "strain_reference": lerp(r["max_strain"].to_numpy()),
        "strain_approx": lerp(a["max_strain"].to_numpy()),
    }


def deviation_at_strain(
    frame: pd.DataFrame, approx: str, reference: str, strain: float, quantity: str = "peak_pressure_MPa"
) -> float | None:
    """Deviation of ``quantity`` where the reference solution's largest strain is ``strain``."""
    r = _law_rows(frame, reference)
    s = r["max_strain"].to_numpy()
    if not s[0] <= strain <= s[-1]:
        return None
    return float(np.interp(strain, s, relative_to(frame, approx, reference, quantity)))


def load_at_strain(rows: pd.DataFrame, strain: float) -> float:
    """Load (N) at which one law's sweep reaches ``strain`` (log-interpolated; NaN if not)."""
    s = rows["max_strain"].to_numpy()
    if not s[0] <= strain <= s[-1]:
        return float("nan")
    return float(np.exp(np.interp(strain, s, np.log(rows["load_N"].to_numpy()))))


def pressure_analysis(frames: dict, betas=BETAS, levels=LEVELS, claim_strain=CLAIM_STRAIN) -> pd.DataFrame:
    """Linear (and cubic, 5th-order) against Eq. (2) under load, per geometry and beta.

    Returns
    -------
    pandas.DataFrame
        One row per (geometry, approximation, beta): ``dev_peak_at_claim``,
        ``dev_area_at_claim``, ``dev_approach_at_claim`` (relative deviations where Eq. (2)'s
        largest strain is ``claim_strain``; NaN if the sweep does not reach it),
        ``load_N_at_claim`` (the load that strains Eq. (2) that far), ``max_strain_reached``
        (Eq. 2's largest strain in the sweep, reached at its largest load ``max_load_N``) and,
        per level
        ``L`` in per cent, ``strain_ref_L`` (Eq. 2's strain), ``strain_approx_L`` and ``load_N_L``
        at which the peak pressure first departs by ``L`` (NaN if never).
    """
    rows = []
    for geometry, frame in frames.items():
        names = set(frame["law"])
        for b in betas:
            reference = f"ateshian_b{b:g}"
            for approx in ("linear", f"cubic_b{b:g}", f"order5_b{b:g}"):
                if approx not in names or reference not in names:
                    continue
                ref_rows = _law_rows(frame, reference)
                row = {
                    "geometry": geometry,
                    "approximation": approx.split("_")[0],
                    "beta": b,
                    "max_strain_reached": float(ref_rows["max_strain"].max()),
                    "max_load_N": float(ref_rows["load_N"].max()),
                    "load_N_at_claim": load_at_strain(ref_rows, claim_strain),
                }
                for quantity, key in (
                    ("peak_pressure_MPa", "peak"),
                    ("contact_area_mm2", "area"),
                    ("approach_mm", "approach"),
                ):
                    value = deviation_at_strain(frame, approx, reference, claim_strain, quantity)
                    row[f"dev_{key}_at_claim"] = np.nan if value is None else value
                for level in levels:
                    tag = f"{round(100 * level):d}"
                    found = departure(frame, approx, reference, level) or {}
                    row[f"strain_ref_{tag}"] = found.get("strain_reference", np.nan)
                    row[f"strain_approx_{tag}"] = found.get("strain_approx", np.nan)
                    row[f"load_N_{tag}"] = found.get("load_N", np.nan)
                rows.append(row)
    columns = [
        "geometry",
        "approximation",
        "beta",
        "max_strain_reached",
        "max_load_N",
        "load_N_at_claim",
        "dev_peak_at_claim",
        "dev_area_at_claim",
        "dev_approach_at_claim",
    ]
    columns += [
        f"{key}_{round(100 * level):d}" for level in levels for key in ("strain_ref", "strain_approx", "load_N")
    ]
    return pd.DataFrame(rows, columns=columns)  # the columns stay even when nothing was swept


# --- the summary ------------------------------------------------------------------------
def _pct(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{100 * x:+.2f} %"


def _strain(x) -> str:
    return "not reached" if x is None or not np.isfinite(x) else f"{x:.3f}"


def verdicts(shape: dict, pressure: pd.DataFrame, levels=LEVELS, claim_strain=CLAIM_STRAIN) -> dict:
    """Whether the claim holds, per tolerance: the linear law stays within it up to 30 % strain.

    Returns
    -------
    dict
        ``{level: {"shape": bool, "pressure": {geometry: bool}, "holds_for": str}}`` where
        ``shape`` is true if the law deviation stays below ``level`` up to ``claim_strain`` for
        every beta, ``pressure[g]`` likewise for the peak pressure of geometry ``g`` (a sweep
        that never reaches the level counts as holding only if it went past ``claim_strain``),
        and ``holds_for`` is ``"shape and pressure"``, ``"shape only"``, ``"pressure only"``
        (every geometry), ``"pressure on <geometries> only"`` or ``"neither"``.
    """
    linear = pressure[pressure["approximation"] == "linear"]
    out = {}
    for level in levels:
        tag = f"{round(100 * level):d}"
        # Strains are compared as the summary prints them (3 decimals), so that the verdict
        # and the table never disagree about a value that rounds to the claim.
        shape_ok = all(round(v["departure"][level], 3) >= claim_strain for v in shape.values())
        per_geometry = {}
        for geometry, rows in linear.groupby("geometry", sort=False):
            strains = rows[f"strain_ref_{tag}"].to_numpy()
            reached = rows["max_strain_reached"].to_numpy()
            ok = np.where(
                np.isfinite(strains), np.round(strains, 3) >= claim_strain, np.round(reached, 3) >= claim_strain
            )
            per_geometry[geometry] = bool(ok.all())
        holding = [g for g, ok in per_geometry.items() if ok]
        pressure_all = bool(per_geometry) and len(holding) == len(per_geometry)
        if shape_ok and pressure_all:
            holds_for = "shape and pressure"
        elif shape_ok:
            holds_for = "shape only"
        elif pressure_all:
            holds_for = "pressure only"
        elif holding:
            holds_for = f"pressure on {', '.join(holding)} only"
        else:
            holds_for = "neither"
        out[level] = {"shape": shape_ok, "pressure": per_geometry, "holds_for": holds_for}
    return out


def summary_markdown(H: float, shape: dict, pressure: pd.DataFrame, verdict: dict, *, coarse: bool, notes=()) -> str:
    """The Markdown summary; every number in it comes from the arguments."""
    claim = f"{100 * CLAIM_STRAIN:.0f} %"
    lines = [
        "# Is the linear spring valid up to 30 % strain?",
        "",
        f"Computed by `examples/linear_validity.py`{' --coarse' if coarse else ''}; every law has "
        f"H = {H:g} MPa. Deviation = (linear - Eq. 2) / Eq. 2; strain = largest compressive "
        "engineering strain.",
        "",
        "## 1. Stress-strain shape: sigma = H eps against Eq. (2)",
        "",
        f"| beta | deviation at {claim} strain | strain at 5 % deviation | strain at 10 % deviation "
        f"| best single modulus over 0-{claim} | its worst error |",
        "|---|---|---|---|---|---|",
    ]
    for b, v in shape.items():
        lines.append(
            f"| {b:g} | {_pct(v['deviation_at_claim'])} | {_strain(v['departure'][0.05])} | "
            f"{_strain(v['departure'][0.10])} | {v['best_modulus_ratio']:.3f} H | "
            f"{100 * v['best_worst_error']:.2f} % |"
        )
    lines += [
        "",
        "## 2. Peak pressure under a load: linear solve against the Eq. (2) solve",
        "",
        "Departure = the load at which the linear peak pressure first differs from Eq. (2)'s by "
        "5 % or 10 %; strain there is given for the Eq. (2) solution (what the cartilage reaches) "
        "and, in brackets, for the linear solution (what a linear DEA reports).",
        "",
        f"| geometry | beta | Eq. (2) strain reached | load at {claim} strain | peak deviation at {claim} "
        f"| area deviation at {claim} | 5 % departure: strain [linear] / load "
        "| 10 % departure: strain [linear] / load |",
        "|---|---|---|---|---|---|---|---|",
    ]
    linear = pressure[pressure["approximation"] == "linear"]
    for row in linear.itertuples(index=False):
        cells = []
        for tag in ("5", "10"):
            s, sa, load = (
                getattr(row, f"strain_ref_{tag}"),
                getattr(row, f"strain_approx_{tag}"),
                getattr(row, f"load_N_{tag}"),
            )
            cells.append("not reached" if not np.isfinite(s) else f"{s:.3f} [{sa:.3f}] / {load:.4g} N")
        load = "not reached" if not np.isfinite(row.load_N_at_claim) else f"{row.load_N_at_claim:.4g} N"
        lines.append(
            f"| {row.geometry} | {row.beta:g} | up to {row.max_strain_reached:.3f} at "
            f"{row.max_load_N:.4g} N | {load} | "
            f"{_pct(row.dev_peak_at_claim)} | {_pct(row.dev_area_at_claim)} | "
            f"{cells[0]} | {cells[1]} |"
        )
    higher = pressure[pressure["approximation"] != "linear"]
    if len(higher):
        lines += [
            "",
            f"Truncated series under load, peak deviation at {claim} strain: "
            + "; ".join(
                f"{r.approximation} beta {r.beta:g} on {r.geometry} {_pct(r.dev_peak_at_claim)}"
                for r in higher.itertuples(index=False)
            )
            + ".",
        ]
    lines += [
        "",
        "## Verdict",
        "",
        f"The claim holds at a tolerance if the linear law stays within it up to {claim} strain.",
        "",
    ]
    for level, v in verdict.items():
        pct = f"{100 * level:.0f} %"
        tag = f"{round(100 * level):d}"
        shape_words = ", ".join(
            f"beta {b:g}: within {pct} up to strain {_strain(s['departure'][level])}" for b, s in shape.items()
        )
        press_words = []
        for r in linear.itertuples(index=False):
            reached = getattr(r, f"strain_ref_{tag}")
            press_words.append(
                f"{r.geometry} beta {r.beta:g}: within {pct} up to strain {reached:.3f}"
                if np.isfinite(reached)
                else f"{r.geometry} beta {r.beta:g}: within {pct} over the whole sweep, to strain "
                f"{r.max_strain_reached:.3f}"
            )
        pressure_words = (
            (
                ", ".join(f"{'holds' if ok else 'fails'} on {g}" for g, ok in v["pressure"].items())
                + f" ({'; '.join(press_words)})"
            )
            if v["pressure"]
            else "was not tested (no geometry swept)"
        )
        lines.append(
            f"- **{pct} tolerance**: the {claim} claim holds for **{v['holds_for']}**. "
            f"Shape {'holds' if v['shape'] else 'fails'} ({shape_words}); "
            f"pressure under load {pressure_words}."
        )
    for note in notes:
        lines += ["", note]
    return "\n".join(lines) + "\n"


# --- pictures and files -----------------------------------------------------------------
_FAMILY_COLOUR = {"linear": "k", "ateshian": "tab:blue", "cubic": "tab:orange", "order5": "tab:green"}
_BETA_STYLE = {0.05: "-", 0.6: "--"}
_BETA_COLOUR = {0.05: "tab:blue", 0.6: "tab:red"}
_PANELS = (
    ("peak_pressure_MPa", "peak pressure [MPa]"),
    ("contact_area_mm2", "contact area [mm^2]"),
    ("approach_mm", "approach [mm]"),
)


def plot_sweep(frame: pd.DataFrame, title: str, betas=BETAS):
    """Top row: peak pressure, area, approach against load; bottom: against strain, deviation."""
    fig, axes = plt.subplots(2, 3, figsize=(14, 8))
    strain_max = min(1.0, float(frame["max_strain"].max()))
    for name in dict.fromkeys(frame["law"]):
        rows = _law_rows(frame, name)
        family, beta = rows.loc[0, "family"], rows.loc[0, "beta"]
        style = dict(
            color=_FAMILY_COLOUR.get(family, "0.4"),
            ls="-" if beta is None or pd.isna(beta) else _BETA_STYLE.get(beta, ":"),
            lw=1.4,
            label=name,
        )
        for j, (column, label) in enumerate(_PANELS):
            axes[0, j].plot(rows["load_N"], rows[column], **style)
            axes[0, j].set(xscale="log", xlabel="load [N]", ylabel=label)
        for j, (column, label) in enumerate(_PANELS[:2]):
            axes[1, j].plot(rows["max_strain"], rows[column], **style)
            axes[1, j].set(xlabel="largest compressive strain", ylabel=label, xlim=(0, strain_max))
    axes[0, 0].legend(fontsize=7, ncol=2)
    dx = axes[1, 2]
    for b in betas:
        reference = f"ateshian_b{b:g}"
        r = _law_rows(frame, reference)
        dev = relative_to(frame, "linear", reference, "peak_pressure_MPa")
        dx.plot(
            r["max_strain"],
            100 * np.abs(dev),
            "-",
            color=_BETA_COLOUR.get(b),
            marker=".",
            label=f"peak pressure under load, beta {b:g}",
        )
        s = np.linspace(1e-3, strain_max, 200)
        dx.plot(
            s,
            100 * np.abs(law_deviation(1.0, b, -s)),
            ":",
            color=_BETA_COLOUR.get(b),
            label=f"stress at equal strain, beta {b:g}",
        )
        for level in LEVELS:  # the interpolated departures the summary reports
            found = departure(frame, "linear", reference, level)
            if found is not None:
                dx.plot(found["strain_reference"], 100 * level, "x", color=_BETA_COLOUR.get(b), ms=8)
    for level in LEVELS:
        dx.axhline(100 * level, color="0.7", lw=0.8)
    dx.axvline(CLAIM_STRAIN, color="0.5", lw=0.8, ls="--")
    dx.set(
        xlim=(0, strain_max),
        ylim=(0, 40),
        xlabel="largest compressive strain of Eq. (2)",
        ylabel="|linear - Eq. 2| / Eq. 2 [%]",
        title="linear law against Eq. (2)",
    )
    dx.legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def write_atomic(path, data) -> Path:
    """Write ``data`` (str or bytes) to ``path`` so that no half-written file is ever seen."""
    return write_data(path, data)


def figure_bytes(fig) -> bytes:
    """The figure as PNG bytes (closed afterwards, so loops do not leak figures)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)  # already tight_layout-ed: one draw is enough
    plt.close(fig)
    return buffer.getvalue()


# --- the script -------------------------------------------------------------------------
def _knee_case(law, knee_dir):
    """``(problem, None)`` for the real knee, or ``(None, why it is skipped)``."""
    knee_dir = Path(knee_dir)
    if not knee_dir.is_dir():
        return None, f"Knee skipped: no knee data at {knee_dir}."
    builder = find_mesh_builder()
    if builder is None:
        return None, f"Knee skipped: {knee_dir} exists but dea_opt.mesh.springs_from_meshes does not import."
    try:
        return knee_problem(law, knee_dir, builder), None
    except Exception as exc:  # noqa: BLE001 - an optional part must not stop the study
        return None, f"Knee skipped: building its springs failed ({type(exc).__name__}: {exc})."


def run(
    out=DEFAULT_OUT,
    coarse: bool = False,
    H: float = H_DEFAULT,
    geometries=GEOMETRIES,
    knee_dir=DEFAULT_KNEE,
    extra_problems=None,
    verbose: bool = True,
) -> dict:
    """Sweep the geometries, analyse, and write the pictures, tables and summary.

    Parameters
    ----------
    out : path
        Output directory.
    coarse : bool
        Coarser meshes and fewer loads (the tests' setting).
    H : float
        Aggregate modulus of every law, MPa.
    geometries : sequence of {"sphere", "hip", "knee"}
        The embedded cases to sweep. The knee runs only if ``knee_dir`` exists and the
        installed dea-opt can cast springs from meshes; otherwise a note says it is skipped.
    knee_dir : path
        The knee's cartilage meshes.
    extra_problems : dict {name: (ContactProblem, loads)}, optional
        Further problems to sweep (e.g. a knee built another way); each problem's body-2
        force gives the load direction, ``loads`` the increasing magnitudes in N.
    verbose : bool
        Print progress and what is skipped.

    Returns
    -------
    dict
        ``frames`` ({geometry: DataFrame of :func:`load_sweep`}), ``shape``
        (:func:`shape_analysis`), ``pressure`` (:func:`pressure_analysis`), ``verdict``
        (:func:`verdicts`), ``summary`` (the Markdown text), ``notes``, ``timings`` (s per
        geometry) and ``files``.
    """
    say = print if verbose else (lambda *a, **k: None)
    unknown = set(geometries) - set(GEOMETRIES)
    if unknown:
        raise ValueError(f"geometries must be taken from {GEOMETRIES}, got {sorted(unknown)}")
    level = 1 if coarse else 0
    n = N_LOADS[level]
    laws = validity_laws(H)
    cases, notes = {}, []
    if "sphere" in geometries:
        mesh = SPHERE_MESH[level]
        cases["sphere"] = (
            sphere_problem(laws["linear"], **mesh),
            sphere_loads(H, n),
            sphere_edge_check(mesh["n_sectors"]),
        )
    if "hip" in geometries:
        cases["hip"] = (hip_problem(laws["linear"], **HIP_MESH[level]), np.geomspace(*HIP_LOADS, n), None)
    if "knee" in geometries:
        knee, note = _knee_case(laws["linear"], knee_dir)
        if knee is None:
            notes.append(note)
        else:
            cases["knee"] = (knee, np.geomspace(*KNEE_LOADS, KNEE_N_LOADS[level]), window_check(KNEE_MAX_GAP))
    for name, (problem, loads) in (extra_problems or {}).items():
        cases[name] = (problem, np.asarray(loads, dtype=float), None)
    for note in notes:
        say(note)

    frames, timings = {}, {}
    for geometry, (problem, loads, check) in cases.items():
        start = time.perf_counter()
        frames[geometry] = load_sweep(problem, laws, loads, geometry=geometry, check=check)
        timings[geometry] = time.perf_counter() - start
        say(f"{geometry}: {len(laws)} laws x {len(loads)} loads solved in {timings[geometry]:.2f} s")

    shape = shape_analysis()
    pressure = pressure_analysis(frames)
    verdict = verdicts(shape, pressure)
    summary = summary_markdown(H, shape, pressure, verdict, coarse=coarse, notes=notes)
    out = Path(out)
    files = {
        f"png_{g}": write_atomic(
            out / f"validity_{g}.png", figure_bytes(plot_sweep(frame, f"{g}: load control, H = {H:g} MPa"))
        )
        for g, frame in frames.items()
    }
    table = pd.concat(frames.values(), ignore_index=True) if frames else pd.DataFrame(columns=SWEEP_COLUMNS)
    files["sweep_csv"] = write_atomic(out / "validity_sweep.csv", table.to_csv(index=False))
    files["departures_csv"] = write_atomic(out / "validity_departures.csv", pressure.to_csv(index=False))
    files["summary_md"] = write_atomic(out / "validity_summary.md", summary)
    return {
        "frames": frames,
        "shape": shape,
        "pressure": pressure,
        "verdict": verdict,
        "summary": summary,
        "notes": notes,
        "timings": timings,
        "files": files,
    }


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    parser.add_argument("--coarse", action="store_true", help="coarser meshes and fewer loads (the tests use it)")
    parser.add_argument("--H", type=float, default=H_DEFAULT, help="aggregate modulus of every law, MPa")
    parser.add_argument(
        "--knee", type=Path, default=DEFAULT_KNEE, help="directory with the knee's cartilage meshes (skipped if absent)"
    )
    parser.add_argument("--no-knee", action="store_true", help="do not try the knee")
    return parser.parse_args(argv)


def main(argv=None) -> dict:
    """Command-line entry point; returns what :func:`run` returns."""
    args = parse_args(argv)
    geometries = tuple(g for g in GEOMETRIES if not (args.no_knee and g == "knee"))
    result = run(args.out, coarse=args.coarse, H=args.H, geometries=geometries, knee_dir=args.knee)
    print()
    print(result["summary"])
    for path in result["files"].values():
        print(f"wrote {path}")
    return result


if __name__ == "__main__":
    main()
