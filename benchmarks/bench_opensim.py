"""Reading an OpenSim model: ``dea_opt.opensim.read_model`` and the scenario of ``import-osim``.

Run from the repository's top::

    python benchmarks/bench_opensim.py                 # ../shared/data/tka/DM.osim, 5 repeats
    python benchmarks/bench_opensim.py path/to/model.osim --repeats 10

Prints one line per measure: ``first_s``, a fresh process's first read (``python -c``, with the
imports of dea_opt.opensim and numpy counted: what ``dea-opt import-osim`` waits for);
``read_s``, the best of ``repeats`` reads in this process (XML, components, frames, joints,
contact, 149 ligaments and the not-modelled report at the default pose); ``scenario_s``, the
scenario text made from a read model; ``poses_s`` and ``ligaments_s``, the pose of every body and
every bundle's lengths, strains and forces at the default coordinates. Target: reading DM.osim
and building the scenario within 2 s.

Then the TKA through its 101-frame gait (``examples/tka_gait.py``'s scenario: the femur's flexion
prescribed from fluoroscopy, its five other coordinates free, 89 bundles, the medial and lateral
compartments of one contact cast from the insert's 15 042 faces): ``gait_build_s`` the joint built
from the scenario (the springs cast), ``gait_solve_s`` the 101 frames solved (finite kinematics,
each frame from the previous answer, its springs following the femur on the way and cast again at
each answer), both in wall-clock and CPU time, with the solve's work (Newton steps, tangents by
differences, follows, casts); ``--no-gait`` leaves it out. Target: the gait within 10 s on the
2-core machine. The machine is shared: the load average is printed beside the numbers, and a
before/after comparison runs both checkouts alternately in the same minutes.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
DM = HERE.parents[1] / "shared" / "data" / "tka" / "DM.osim"


def _best(fn, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", nargs="?", default=str(DM))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-gait", action="store_true", help="leave the 101-frame gait out")
    args = parser.parse_args(argv)
    model_path = Path(args.model)
    if not model_path.is_file():
        print(f"skipped: {model_path} is not there")
        return
    code = (
        "import time; t = time.perf_counter(); from dea_opt.opensim import read_model; "
        "from dea_opt.opensim.export import scenario_text; "
        f"m = read_model({str(model_path)!r}); scenario_text(m); print(time.perf_counter() - t)"
    )
    first = float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)

    from dea_opt.opensim import read_model
    from dea_opt.opensim.export import scenario_text

    model = read_model(model_path)
    measures = {
        "first_s": first,
        "read_s": _best(lambda: read_model(model_path), args.repeats),
        "scenario_s": _best(lambda: scenario_text(model), args.repeats),
        "poses_s": _best(model.poses, args.repeats),
        "ligaments_s": _best(model.ligament_state, args.repeats),
    }
    summary = model.summary()
    print(
        f"{model_path.name}: {summary['bodies']} bodies, {summary['joints']} joints, {summary['ligaments']} "
        f"ligaments, {len(model.not_modelled)} not modelled; best of {args.repeats}"
    )
    for name, value in measures.items():
        print(f"  {name:12s} {value:8.4f}")
    total = measures["first_s"]
    from bench_joint import cpu_name

    print(f"CPU: {cpu_name()}; load average {' '.join(f'{v:.1f}' for v in os.getloadavg())} (the machine is shared)")
    print(
        f"  read and build the scenario (a fresh process): {total:.3f} s against the goal of 2 s: {total / 2:.2f}, "
        f"{'met' if total <= 2 else 'NOT met'}"
    )
    if not args.no_gait:
        gait(model_path.parent)


def gait(tka: Path) -> None:
    """The 101-frame gait of ``examples/tka_gait.py``, timed."""
    import tempfile
    import warnings

    sys.path.insert(0, str(HERE.parent / "examples"))
    import tka_gait

    from dea_opt.run.joint_path import solve_joint_path
    from dea_opt.scenario import load_scenario
    from dea_opt.scenario.joint_build import build_joint
    from dea_opt.scenario.joint_path import read_joint_path

    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as folder:
        scenario = load_scenario(tka_gait.write_scenario(Path(folder), tka))
        start, cpu = time.perf_counter(), time.process_time()
        joint, _ = build_joint(scenario)
        path = read_joint_path(scenario, joint)
        build = (time.perf_counter() - start, time.process_time() - cpu)
        start, cpu = time.perf_counter(), time.process_time()
        solutions = solve_joint_path(joint, path)
        solve = (time.perf_counter() - start, time.process_time() - cpu)
    certified = sum(1 for s in solutions if s is not None and s.success)
    done = [s for s in solutions if s is not None]
    steps = sum(s.iterations for s in done)
    casts = sum(s.info["casts"] for s in done)
    follows = sum(s.info["follows"] for s in done)
    tangents = sum(s.info["tangents"] for s in done)
    print(
        f"gait: {len(solutions)} frames, {certified} certified; in all {steps} Newton steps, {tangents} tangents by "
        f"differences, {follows} follows of the faces and {casts} casts at a solved pose"
    )
    print(f"  gait_build_s {build[0]:8.3f} wall {build[1]:8.3f} CPU")
    print(f"  gait_solve_s {solve[0]:8.3f} wall {solve[1]:8.3f} CPU")
    print(
        f"  the gait against the goal of 10 s: {solve[0] / 10:.2f} (wall), {solve[1] / 10:.2f} (CPU): "
        f"{'met' if solve[0] <= 10 else 'NOT met'}; load average {' '.join(f'{v:.1f}' for v in os.getloadavg())}"
    )


if __name__ == "__main__":
    main()
