"""Finite kinematics on the real knee: one solve against the small kinematics, and a gait.

Run::

    python benchmarks/bench_finite.py                # the knee at 1000 N, and the 101-frame gait
    python benchmarks/bench_finite.py --frames 21

Targets of the finite-kinematics issue, on the knee of ``../shared/data/knee`` (13 306 springs
cast from the tibial onto the femoral cartilage, linear law, H = 10 MPa):

* 1000 N along -z with ``uz, rx, ry`` free: the finite solve (re-casts included) within 5x the
  small-kinematics ``dea.solve``. Both are the best of ``repeats`` calls, each on a fresh problem
  (the finite one re-casts from the start cast every time), the calls interleaved (a small
  solve, a small solve with its validation re-cast, a finite solve, and again) so that neither
  kind meets the process only while it is still warming up; the first calls are reported too,
  and the small solve followed by its validation re-cast (``recast_at_solution``, what the small
  model needs to count the springs the window drops at its answer) for scale.
* the same with the femur flexed 15 degrees about the knee's flexion axis (the line through the
  centres of spheres fitted to the posterior femoral condyles, :func:`flexion_axis`; the springs
  cast there), 1000 N along -z and a flexion moment of 2000 N mm (about -x), H = 40 MPa (the
  speed issue's case: the femur flexes about 4 degrees further and turns 2 degrees in the frontal plane,
  bringing the medial condyle, 1 mm off at the cast, into contact; the springs are updated
  several times): finite within 5x small too (``goal``
  5, ``meets``);
* a 101-frame gait with finite kinematics under 10 s: flexion prescribed (0 to 10 to 0 degrees
  about the same axis, the pose of each frame), ``uz`` and the varus-valgus ``ry`` found,
  300-1300 N with two peaks and a varus moment of +-400 N mm; and its wall time within 2x its
  solving time (``wall_ratio``: the wall time of ``solve_path`` over the sum of the frames'
  ``solve_time_s``; ``built_ratio`` over the sum of ``build_time_s`` and ``solve_time_s``), what a
  path spends around its solves (re-casting each frame's start, certificates, validity, the
  table) against ``goal`` 2. ``valid`` counts the frames whose answer lies inside the model.

The knee's frame (``../shared/data/knee/README.md``): x medial-lateral, z from the tibia to the
femur, and -y anterior (the trochlea, whole across x, lies at -y; the notch between the condyles
at +y). Flexion is a positive turn about the axis pointing from the medial to the lateral
condyle's centre: it lifts the anterior femur off the plateaus and rolls the posterior condyles
onto them. (A turn the other way is hyperextension: 15 degrees of it drive the trochlea 7 mm into
the tibia, deeper than the cartilage.)

Prints the rows and writes ``benchmarks/results/finite.csv``.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
KNEE = HERE.parents[1] / "shared" / "data" / "knee"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
COLUMNS = [
    "case",
    "n_springs",
    "small_s",
    "small_first_s",
    "small_recast_s",
    "finite_s",
    "finite_first_s",
    "ratio",
    "goal",
    "meets",
    "pair_ratio_median",
    "rotation_deg",
    "small_rotation_deg",
    "updates",
    "frames",
    "wall_s",
    "per_frame_s",
    "small_path_s",
    "solve_sum_s",
    "wall_ratio",
    "built_ratio",
    "success",
    "valid",
    "status",
    "peak_rss_mb",
    "load_1m",
    "kernels",
]


#: Finite over small kinematics on each knee case, at most (speed issue).
GOAL = 5.0
#: A finite gait's wall time over its frames' solving time, at most (speed issue).
GAIT_GOAL = 2.0
#: The femur's flexion of the flexed case (deg) about the knee's flexion axis (:func:`flexion_axis`).
FLEXION_DEG = 15.0
#: The femoral cartilage's vertices posterior of this (mm, y) that :func:`flexion_axis` fits: the
#: posterior condyles, the notch (x = -76 mm) between them.
CONDYLES_Y, NOTCH_X = -5.0, -76.0
#: The single-solve cases: ``(name, flexed, force (N), moment (N mm), H (MPa))``, all with
#: ``uz, rx, ry`` free.
CASES = {
    "straight": ("knee 1000 N, uz rx ry", False, (0.0, 0.0, -1000.0), (0.0, 0.0, 0.0), 10.0),
    "flexed": ("knee flexed 15 deg, 1000 N + 2000 N mm, H 40", True, (0.0, 0.0, -1000.0), (-2000.0, 0.0, 0.0), 40.0),
}


def knee(flexed: bool = False):
    """``(cast, reference)``: the knee's springs (tibia onto femur, max_gap 2 mm) and body 2's
    reference (the centre of the two plateaus); ``flexed``: cast with the femur flexed
    :data:`FLEXION_DEG` about :func:`flexion_axis`."""
    from dea_opt import mesh as M

    femur = M.load_mesh(KNEE / "femoral_cartilage.stl")
    medial = M.load_mesh(KNEE / "medial_tibial_cartilage.stl")
    lateral = M.load_mesh(KNEE / "lateral_tibial_cartilage.stl")
    tibia, labels = M.concatenate_meshes({"medial": medial, "lateral": lateral})
    centre = [(m.area_faces @ m.triangles_center) / m.area for m in (medial, lateral)]
    reference = 0.5 * (centre[0] + centre[1])
    pose = flexion_pose(np.radians(FLEXION_DEG), *flexion_axis(femur)) if flexed else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cast = M.cast_springs(tibia, femur, labels=labels, max_gap=2.0, pose=pose)
    return cast, tuple(reference)


def flexion_axis(femur) -> tuple[np.ndarray, np.ndarray]:
    """``(point (3,), direction (3,))``: the knee's flexion axis, through the centres of spheres
    fitted (least squares) to the medial and lateral posterior condyles of the femoral cartilage,
    pointing from the medial centre to the lateral one (a positive turn about it is flexion). The
    posterior condyles are nearly circular in the sagittal plane (radius about 21.5 mm here), so a
    turn about their centres keeps them on the plateaus."""
    vertices = np.asarray(femur.vertices)
    centres = []
    for side in (vertices[:, 0] > NOTCH_X, vertices[:, 0] <= NOTCH_X):  # medial (x > notch), lateral
        points = vertices[side & (vertices[:, 1] > CONDYLES_Y)]
        # |P - c|^2 = r^2 as a linear system in (c, r^2 - |c|^2)
        lhs = np.column_stack([2.0 * points, np.ones(len(points))])
        solution = np.linalg.lstsq(lhs, (points * points).sum(axis=1), rcond=None)[0]
        centres.append(solution[:3])
    direction = centres[1] - centres[0]
    return 0.5 * (centres[0] + centres[1]), direction / np.linalg.norm(direction)


def flexion_pose(angle: float, point, direction) -> np.ndarray:
    """The 4x4 pose of the femur turned ``angle`` (rad) about the axis through ``point`` along
    ``direction`` (unit)."""
    from dea_opt.formulations.finite import rotation

    R = rotation(angle * np.asarray(direction))
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = R, np.asarray(point) - R @ np.asarray(point)
    return pose


def _missing() -> dict | None:
    if not all((KNEE / name).is_file() for name in KNEE_FILES):
        return {"status": f"skipped: the knee meshes are not in {KNEE}", "success": False}
    return None


def solve_case(repeats: int = 20, case: str = "straight") -> dict:
    """A knee case of :data:`CASES`, ``uz, rx, ry`` free: finite against small, best of ``repeats``."""
    import os

    from common import peak_rss_mb

    import dea_opt as dea
    from dea_opt.mesh import recast_at_solution

    name, flexed, force, moment, H = CASES[case]
    missing = _missing()
    if missing:
        return {"case": name, **missing}
    cast, reference = knee(flexed)
    kw = {"force": force, "moment": moment, "reference": reference, "free": ("uz", "rx", "ry")}
    law = dea.LinearLaw(H)

    def timed(make, after=None):
        problem = make()
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = dea.solve(problem)
            if after is not None:
                after(out)
        return time.perf_counter() - start, out

    small_times, recast_times, finite_times = [], [], []
    for _ in range(repeats):  # interleaved: every kind of solve meets the machine in the same states
        elapsed, small = timed(lambda: dea.ContactProblem(cast.layer, law, **kw))
        small_times.append(elapsed)
        elapsed, _ = timed(
            lambda: dea.ContactProblem(cast.layer, law, **kw), after=lambda s: recast_at_solution(s, cast)
        )
        recast_times.append(elapsed)
        elapsed, finite = timed(lambda: dea.ContactProblem(cast.layer, law, kinematics="finite", targets=cast, **kw))
        finite_times.append(elapsed)
    ratio = min(finite_times) / min(small_times)
    return {
        "case": name,
        "n_springs": len(cast.layer),
        "small_s": min(small_times),
        "small_first_s": small_times[0],
        "small_recast_s": min(recast_times),
        "finite_s": min(finite_times),
        "finite_first_s": finite_times[0],
        "ratio": ratio,
        "goal": GOAL,
        "meets": bool(ratio <= GOAL),
        # each finite solve against the small one just before it: the machine's slow spells apart
        "pair_ratio_median": float(np.median(np.array(finite_times) / np.array(small_times))),
        "rotation_deg": float(np.degrees(np.linalg.norm(finite.u[9:12]))),
        "small_rotation_deg": float(np.degrees(np.linalg.norm(small.u[9:12]))),
        "updates": finite.info["recast"]["updates"] + finite.info["recast"]["recasts"],
        "success": bool(small.success and finite.success),
        # inside the model: the finite answer, and the small one (its rotation is past its range here)
        "valid": f"finite {bool(finite.validity.valid)}, small {bool(small.validity.valid)}",
        "status": str(finite.status),
        "peak_rss_mb": peak_rss_mb(),
        "load_1m": os.getloadavg()[0],
        "kernels": _kernels(),
    }


def _kernels() -> str:
    """Which loops ran: the walk of the rays across mesh 2 (``dea_opt/mesh/_walk.c``) and the finite
    system's passes (``dea_opt/formulations/finite/_finite.c``), each ``compiled`` or ``numpy``."""
    from dea_opt.formulations.finite.geometry import compiled_system
    from dea_opt.mesh.walk import compiled_walk

    return "/".join("numpy" if kernel is None else "compiled" for kernel in (compiled_walk(), compiled_system()))


def gait_loads(frames: int) -> tuple[np.ndarray, np.ndarray]:
    """``(loads (T, 6), flexion (T,) rad)`` of the synthetic knee gait."""
    phase = np.linspace(0.0, 1.0, frames)
    fz = -(300 + 700 * np.exp(-(((phase - 0.15) / 0.08) ** 2)) + 600 * np.exp(-(((phase - 0.5) / 0.08) ** 2)))
    loads = np.zeros((frames, 6))
    loads[:, 2], loads[:, 4] = fz, 400 * np.sin(2 * np.pi * phase)
    return loads, np.radians(10.0) * np.sin(np.pi * phase) ** 2


def gait_case(frames: int = 101) -> dict:
    """The knee gait with finite kinematics: flexion prescribed, ``uz, ry`` found, every frame warm."""
    import os

    from common import peak_rss_mb

    import dea_opt as dea
    from dea_opt import mesh as M

    missing = _missing()
    if missing:
        return {"case": f"knee gait {frames} frames", **missing}
    cast, reference = knee()
    loads, flexion = gait_loads(frames)
    axis = flexion_axis(M.load_mesh(KNEE / "femoral_cartilage.stl"))
    poses = np.array([flexion_pose(f, *axis) for f in flexion])
    law = dea.LinearLaw(10.0)
    problem = dea.ContactProblem(
        cast.layer, law, reference=reference, free=("uz", "ry"), kinematics="finite", targets=cast
    )
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = dea.solve_path(problem, loads, poses, outputs=dea.PathOutputs(keep_solutions=False))
    wall = time.perf_counter() - start
    small = dea.ContactProblem(cast.layer, law, reference=reference, free=("uz", "ry"))
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dea.solve_path(small, loads, outputs=dea.PathOutputs(keep_solutions=False))
    table = result.table
    solving = float(table["solve_time_s"].sum())
    built = solving + float(table["build_time_s"].sum())
    return {
        "case": f"knee gait {frames} frames",
        "n_springs": int(table["n_springs"].median()),
        "frames": frames,
        "wall_s": wall,
        "per_frame_s": wall / frames,
        "small_path_s": time.perf_counter() - start,
        "solve_sum_s": solving,
        "wall_ratio": wall / solving,
        "built_ratio": wall / built,
        "goal": GAIT_GOAL,
        "meets": bool(wall / solving <= GAIT_GOAL),
        "success": bool(table["success"].all()),
        "valid": f"{int(table['valid'].sum())}/{frames}",
        "status": ", ".join(sorted(set(map(str, table["status"])))),
        "peak_rss_mb": peak_rss_mb(),
        "load_1m": os.getloadavg()[0],
        "kernels": _kernels(),
    }


def run(frames: int, timeout: float, isolate: bool = True, repeats: int = 20) -> list[dict]:
    """Both cases, each in a fresh process unless ``isolate`` is False."""
    from common import run_isolated

    cases = [
        *(("solve_case", {"repeats": repeats, "case": case}) for case in CASES),
        ("gait_case", {"frames": frames}),
    ]
    rows = []
    for func, kwargs in cases:
        rows.append(run_isolated("bench_finite", func, kwargs, timeout) if isolate else globals()[func](**kwargs))
    return rows


def main(argv=None) -> int:
    sys.path.insert(0, str(HERE))
    from common import print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=101)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--out", default=str(HERE / "results"))
    args = parser.parse_args(argv)
    rows = run(args.frames, args.timeout, repeats=args.repeats)
    print_table(rows, COLUMNS)
    write_csv(Path(args.out) / "finite.csv", rows, COLUMNS)
    return 0


if __name__ == "__main__":
    sys.exit(main())
