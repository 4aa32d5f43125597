"""A real knee from its cartilage meshes: pressure map, medial/lateral load share, linear vs Eq. (2).
==================================================================================================

Reads the femoral cartilage and the medial and lateral tibial cartilage as triangle surfaces
(STL, OBJ, PLY, OFF, VTK, VTP; in mm), casts one spring from every tibial face that faces the
femur within ``--max-gap`` (2 mm), measures the cartilage thickness through both closed
surfaces, and pushes the femur (body 2) onto the fixed tibia (body 1) with ``--load`` (1000 N)
along -z at the midpoint of the two plateaus' centroids. The femur may sink (``uz``) and
tilt in varus-valgus (``ry``: x is medial-lateral, z runs from the tibia to the femur), so
the load finds its own split between the compartments.

It is solved with the linear spring ``LinearLaw(H)`` and with Ateshian's law, Eq. (2),
``AteshianLaw(H, beta)`` with the same H (10 MPa: the stiffness cartilage shows under a
short load; strains stay below 30 %), beta = 0.05 and 0.6 (the paper's range), and the
script reports what the choice of law changes: peak pressure, contact area and the medial
share of the load.

Run it with::

    python examples/knee_from_meshes.py --out figures/
    python examples/knee_from_meshes.py path/to/knee_dir --out figures/
    python examples/knee_from_meshes.py femur.stl medial_tibia.stl lateral_tibia.stl --out figures/

With no path it reads ``../shared/data/knee`` beside the repository (the pymskt knee, MIT).
A directory must hold ``femoral_cartilage.stl``, ``medial_tibial_cartilage.stl`` and
``lateral_tibial_cartilage.stl``. Files are recognised by name (``fem``; ``medial`` or
``med_``; ``lateral`` or ``lat_``; ``tib``), the others take the roles left in the order
femur, medial, lateral. With two files (femur and one tibia) the springs are split into
compartments across x at the centre of pressure, the medial side at ``--medial-side``
(``+x`` for the shipped right knee), and the load acts at the tibia's area centroid. ``--coarse`` drops
beta = 0.6 (the tests' setting).

It writes into ``--out`` (default ``examples/output/knee_from_meshes/``):
``knee_pressure_<law>.png`` (pressure maps on one colour scale), ``knee_<law>.vtu`` /
``.csv`` / ``.json`` (the contact surface for ParaView, one row per spring, the summary with
the compartments), ``knee_comparison.csv`` (one row per law) and ``knee_summary.md``.

Units: mm, N, MPa; rotations in degrees in the tables.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

import dea_opt
from dea_opt import io as dio
from dea_opt.anatomy import regional_statistics, split_by_axis
from dea_opt.files import write_atomic
from dea_opt.mesh import concatenate_meshes, load_mesh, springs_from_meshes

NAME = "knee_from_meshes"
DEFAULT_OUT = Path(__file__).resolve().parent / "output" / NAME
DEFAULT_KNEE = Path(__file__).resolve().parents[2] / "shared" / "data" / "knee"
FILES = {
    "femur": "femoral_cartilage.stl",
    "medial": "medial_tibial_cartilage.stl",
    "lateral": "lateral_tibial_cartilage.stl",
}

H_DEFAULT = 10.0  # MPa
LOAD = 1000.0  # N, about 1.4 body weights: a stance-phase axial load
MAX_GAP = 2.0  # mm: springs only where the surfaces are this close (contact stays well inside)
BETAS = ((0.05, 0.6), (0.05,))  # (default, coarse)
MEDIAL_SIDE = "+x"  # where the medial compartment lies when only one tibia mesh is given


# --- reading the meshes -----------------------------------------------------------------
def _role(path: Path) -> str | None:
    name = path.name.lower()
    for role, keys in (
        ("femur", ("fem",)),
        ("medial", ("medial", "med_")),
        ("lateral", ("lateral", "lat_")),
        ("tibia", ("tib",)),
    ):
        if any(k in name for k in keys):
            return role
    return None


def find_meshes(paths=()) -> dict:
    """The mesh files by role: ``{"femur", "medial", "lateral"}`` or ``{"femur", "tibia"}``.

    Parameters
    ----------
    paths : sequence of path
        Nothing (the shipped knee directory), one directory, or two or three mesh files.

    Raises
    ------
    FileNotFoundError
        A path or an expected file does not exist (the message says which).
    ValueError
        The files cannot be told apart, or there are not two or three of them.
    """
    paths = [Path(p) for p in paths] or [DEFAULT_KNEE]
    if len(paths) == 1 and paths[0].is_dir():
        found = {role: paths[0] / name for role, name in FILES.items()}
        missing = [str(p) for p in found.values() if not p.is_file()]
        if missing:
            raise FileNotFoundError(f"no knee meshes in {paths[0]}: missing {', '.join(missing)}")
        return found
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise FileNotFoundError(f"no such mesh file or knee directory: {', '.join(missing)}")
    if len(paths) not in (2, 3):
        raise ValueError(
            f"give a knee directory, or 2 (femur, tibia) or 3 (femur, medial, lateral) mesh "
            f"files; got {len(paths)} paths"
        )
    roles = [_role(p) for p in paths]
    wanted = ("femur", "medial", "lateral") if len(paths) == 3 else ("femur", "tibia")
    known = [r for r in roles if r is not None]
    if len(set(known)) != len(known) or not set(known) <= set(wanted):
        raise ValueError(
            f"cannot tell the meshes apart by name ({', '.join(p.name for p in paths)}); "
            f"name them {'/'.join(wanted)} or give them in that order"
        )
    # Names recognised take their role; the others take the roles left, in order.
    left = iter([w for w in wanted if w not in known])
    return {(r or next(left)): p for r, p in zip(roles, paths)}


def knee_layer(meshes: dict, max_gap: float = MAX_GAP):
    """Springs from the tibial cartilage (body 1) to the femoral cartilage (body 2).

    Returns
    -------
    layer : SpringLayer
        Labelled ``medial``/``lateral`` when the two plateaus came as separate meshes.
    reference : tuple of 3 floats
        Where the load acts and rotations are taken (mm): the midpoint of the two plateaus'
        area centroids, or the one tibia's area centroid.
    """
    femur = load_mesh(meshes["femur"])
    if "tibia" in meshes:
        tibia, labels = load_mesh(meshes["tibia"]), None
        centre = (tibia.area_faces @ tibia.triangles_center) / tibia.area
    else:
        parts = {side: load_mesh(meshes[side]) for side in ("medial", "lateral")}
        tibia, labels = concatenate_meshes(parts)
        # The midpoint of the compartments, not the area centroid of both: a plateau that is
        # larger must not pull the load toward its own side.
        centre = 0.5 * sum((m.area_faces @ m.triangles_center) / m.area for m in parts.values())
    # thickness1/2 = None: measured through each closed cartilage surface to its bone side.
    layer = springs_from_meshes(tibia, femur, labels=labels, max_gap=max_gap)
    return layer, tuple(float(c) for c in centre)


def knee_problem(layer, reference, law, load: float = LOAD) -> dea_opt.ContactProblem:
    """The femur pushed along -z with ``load`` (N) at ``reference``, free in ``uz`` and ``ry``."""
    return dea_opt.ContactProblem(layer, law, force=(0.0, 0.0, -float(load)), reference=reference, free=("uz", "ry"))


def knee_laws(H: float = H_DEFAULT, betas=BETAS[0]) -> dict:
    """``{"linear": LinearLaw(H), "ateshian_b<beta>": AteshianLaw(H, beta), ...}`` (MPa)."""
    return {"linear": dea_opt.LinearLaw(H), **{f"ateshian_b{b:g}": dea_opt.AteshianLaw(H, b) for b in betas}}


# --- the analysis -----------------------------------------------------------------------
def compartments(solution, medial_side: str = MEDIAL_SIDE) -> dict:
    """``{"medial": RegionStats, "lateral": RegionStats}`` of a knee solution.

    From the springs' labels when they have them; otherwise by a cut across x at the centre
    of pressure (:func:`dea_opt.anatomy.split_by_axis`), medial on ``medial_side``.
    """
    if solution.problem.layer.labels is not None:
        return regional_statistics(solution)
    names = ("lateral", "medial") if medial_side == "+x" else ("medial", "lateral")
    return split_by_axis(solution, "x", names=names)


def solve_laws(problem: dea_opt.ContactProblem, laws: dict) -> dict:
    """``{name: Solution}``: one certified Newton solve per law."""
    out = {}
    for name, law in laws.items():
        with warnings.catch_warnings():
            # A linear law past 30 % strain would warn; the table reports the strain anyway.
            warnings.simplefilter("ignore", dea_opt.ValidityWarning)
            out[name] = dea_opt.solve(problem.with_law(law), "newton")
    return out


def comparison_table(solutions: dict, medial_side: str = MEDIAL_SIDE) -> pd.DataFrame:
    """One row per law, and how far each lies from the linear law.

    Columns: ``law, peak_pressure`` (MPa), ``mean_pressure`` (MPa), ``contact_area``
    (mm^2), ``medial_share``, ``lateral_share`` (fractions of the contact force: each
    compartment's resultant along it), ``medial_peak``, ``lateral_peak`` (MPa), ``medial_area``, ``lateral_area`` (mm^2),
    ``uz`` (mm), ``ry_deg``, ``max_strain``, ``iterations``, ``solve_time`` (s), then
    ``dev_peak`` and ``dev_area`` (relative to the linear law) and ``d_medial_share``
    (percentage points).
    """
    rows = []
    for name, s in solutions.items():
        parts = compartments(s, medial_side)
        rows.append(
            {
                "law": name,
                "peak_pressure": s.peak_pressure,
                "mean_pressure": s.mean_pressure,
                "contact_area": s.contact_area,
                **{f"{side}_share": parts[side].share for side in ("medial", "lateral")},
                **{f"{side}_peak": parts[side].peak_pressure for side in ("medial", "lateral")},
                **{f"{side}_area": parts[side].contact_area for side in ("medial", "lateral")},
                "uz": float(s.u[8]),
                "ry_deg": float(np.degrees(s.u[10])),
                "max_strain": s.max_compressive_strain,
                "iterations": s.iterations,
                "solve_time": s.solve_time,
            }
        )
    table = pd.DataFrame(rows)
    linear = table.iloc[0] if "linear" not in set(table["law"]) else table.set_index("law").loc["linear"]
    table["dev_peak"] = table["peak_pressure"] / linear["peak_pressure"] - 1.0
    table["dev_area"] = table["contact_area"] / linear["contact_area"] - 1.0
    table["d_medial_share"] = 100.0 * (table["medial_share"] - linear["medial_share"])
    return table


def summary_markdown(table: pd.DataFrame, *, n_springs: int, load: float, H: float, files: dict) -> str:
    """The comparison as Markdown; every number comes from ``table``."""
    lines = [
        f"# Knee: {n_springs} springs, {load:g} N along -z, H = {H:g} MPa",
        "",
        "| law | peak [MPa] | contact area [mm^2] | medial / lateral share | peak medial / lateral [MPa] "
        "| max strain | peak vs linear | area vs linear | medial share vs linear |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in table.itertuples(index=False):
        lines.append(
            f"| {r.law} | {r.peak_pressure:.3f} | {r.contact_area:.1f} | "
            f"{100 * r.medial_share:.1f} % / {100 * r.lateral_share:.1f} % | "
            f"{r.medial_peak:.3f} / {r.lateral_peak:.3f} | {r.max_strain:.3f} | {100 * r.dev_peak:+.2f} % | "
            f"{100 * r.dev_area:+.2f} % | {r.d_medial_share:+.2f} points |"
        )
    lines += ["", "Meshes: " + ", ".join(f"{role} `{path}`" for role, path in files.items()), ""]
    return "\n".join(lines)


# --- the script -------------------------------------------------------------------------
def _side_on_map(solution, parts: dict) -> str:
    """Where the medial compartment shows on :func:`dea_opt.io.plot_pressure`'s plane view."""
    layer = solution.problem.layer
    _, axes = dio.best_fit_frame(layer.points, layer.areas, layer.normals)  # the frame the map uses
    offset = (parts["medial"].center_of_pressure - parts["lateral"].center_of_pressure) @ axes[0]
    return "right" if offset > 0 else "left"


def _write_text(path: Path, text: str) -> Path:
    return write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def run(
    paths=(),
    out=DEFAULT_OUT,
    coarse: bool = False,
    H: float = H_DEFAULT,
    betas=None,
    load: float = LOAD,
    max_gap: float = MAX_GAP,
    medial_side: str = MEDIAL_SIDE,
) -> dict:
    """Build the knee, solve it with each law, and write the maps and tables into ``out``.

    Returns
    -------
    dict
        ``meshes`` (role -> path), ``problem`` (linear), ``solutions`` (law -> Solution),
        ``table`` (:func:`comparison_table`), ``markdown`` and ``files`` (name -> path).
    """
    out = Path(out)
    meshes = find_meshes(paths)
    layer, reference = knee_layer(meshes, max_gap)
    laws = knee_laws(H, BETAS[1 if coarse else 0] if betas is None else betas)
    problem = knee_problem(layer, reference, laws["linear"], load)
    solutions = solve_laws(problem, laws)
    table = comparison_table(solutions, medial_side)
    # One colour scale for every map, so that the laws can be compared by eye.
    top = max(s.peak_pressure for s in solutions.values())
    files = {}
    for name, s in solutions.items():
        regions = None if layer.labels is not None else compartments(s, medial_side)
        files[f"{name}_vtu"] = dio.to_vtk(s, out / f"knee_{name}.vtu")
        files[f"{name}_csv"] = dio.to_csv(s, out / f"knee_{name}.csv")
        files[f"{name}_json"] = dio.to_json(s, out / f"knee_{name}.json", regions=regions)
        share = compartments(s, medial_side)
        title = (
            f"{s.problem.law.describe()}: peak {s.peak_pressure:.3g} MPa, area {s.contact_area:.0f} mm$^2$,\n"
            f"medial ({_side_on_map(s, share)}) {100 * share['medial'].share:.1f} % / lateral "
            f"{100 * share['lateral'].share:.1f} % of the contact force"
        )
        files[f"{name}_png"] = dio.plot_pressure(
            s, out / f"knee_pressure_{name}.png", vmax=top, title=title, dpi=100, figsize=(6.4, 4.6)
        )
    markdown = summary_markdown(table, n_springs=len(layer), load=load, H=H, files=meshes)
    files["comparison"] = _write_text(out / "knee_comparison.csv", table.to_csv(index=False))
    files["summary"] = _write_text(out / "knee_summary.md", markdown)
    return {
        "meshes": meshes,
        "problem": problem,
        "solutions": solutions,
        "table": table,
        "markdown": markdown,
        "files": files,
    }


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "paths",
        nargs="*",
        type=Path,
        help=f"a knee directory, or femur + medial + lateral (or femur + tibia) mesh files (default {DEFAULT_KNEE})",
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    parser.add_argument("--coarse", action="store_true", help="only beta = 0.05 besides the linear law (the tests)")
    parser.add_argument("--H", type=float, default=H_DEFAULT, help="modulus of every law in MPa (default 10)")
    parser.add_argument("--betas", type=float, nargs="+", help="Ateshian betas (default 0.05 0.6)")
    parser.add_argument("--load", type=float, default=LOAD, help="axial load on the femur in N (default 1000)")
    parser.add_argument("--max-gap", type=float, default=MAX_GAP, help="largest gap that gets a spring, mm")
    parser.add_argument(
        "--medial-side",
        choices=("+x", "-x"),
        default=MEDIAL_SIDE,
        help="side of the medial compartment when one tibia mesh is given (default +x)",
    )
    return parser.parse_args(argv)


def main(argv=None) -> dict:
    """Command-line entry point; returns what :func:`run` returns (exit code 2 without meshes)."""
    args = parse_args(argv)
    start = time.perf_counter()
    try:
        result = run(
            args.paths,
            args.out,
            coarse=args.coarse,
            H=args.H,
            betas=args.betas,
            load=args.load,
            max_gap=args.max_gap,
            medial_side=args.medial_side,
        )
    except (FileNotFoundError, ValueError) as exc:  # dea_opt's InputError is a ValueError too
        print(f"knee_from_meshes: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    print(result["markdown"])
    for path in result["files"].values():
        print(f"wrote {path}")
    print(f"{time.perf_counter() - start:.1f} s in all")
    return result


if __name__ == "__main__":
    main()
