"""Joint benchmark: three bodies, two layers of 15 000 springs and 100 ligament bundles.

Run::

    python benchmarks/bench_joint.py                    # the static solve and the 101-frame path
    python benchmarks/bench_joint.py --springs 5000 --repeats 3

(1) One static solve of the joint (``dea.solve(joint)``: building its arrays, Newton, the
certificate per body and element, each layer's two-body answer and validity), against the two
layers solved alone (``dea.solve`` of each layer's two-body problem: the femur on the fixed tibia,
the patella on the femur held where it is), each from fresh objects, best of ``--repeats``.
Target: at most 2x, measured in one run both as wall-clock time and as the process's CPU time
(the machine is shared: other jobs stretch wall-clock times, CPU times much less). (2) A 101-frame
load path of the same joint (:func:`dea_opt.run.joint_path.solve_joint_path`, each frame from the
previous answer). Target: at most 10 s. Prints the machine's CPU, the timings, each ratio against
its goal and the load average; writes ``benchmarks/results/joint.csv``. Speed is measured here,
never asserted in tests.

The two layers alone are each layer's two-body problem with the translations of its moving body
free (rotations free would leave a socket's turn about its centre unresisted): the joint solves
twelve dofs with rotations and 100 nonlinear bundles, whose toe region costs Newton 7 iterations
where each linear layer alone needs 2.
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import time
import warnings
from pathlib import Path

import numpy as np

import dea_opt as dea
from dea_opt.geometry import socket_layer

HERE = Path(__file__).resolve().parent


def cpu_name() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else what ``platform`` says."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def layers(n_springs: int):
    """Two socket layers of about ``n_springs`` each: the tibia's around the femur's centre at the
    origin, and the femur's around the patella's centre 60 mm above (normals toward each centre)."""
    rings = max(int(round(np.sqrt(n_springs / 2))), 4)
    sectors = max(n_springs // rings, 8)
    tibia = socket_layer(radius=25.0, thickness=3.0, coverage=70.0, n_rings=rings, n_sectors=sectors, gap=0.05)
    cap = socket_layer(radius=15.0, thickness=4.0, coverage=60.0, n_rings=rings, n_sectors=sectors, gap=0.05)
    femur = dea.SpringLayer(cap.points + [0, 0, 60.0], cap.normals, cap.areas, cap.thickness, cap.gap)
    return tibia, femur


def bundles(n: int, seed: int = 7) -> list:
    """``n`` bundles: 60 % femur-tibia, 20 % patella-tibia, 20 % patella-femur, random insertions
    around each body, slack or slightly stretched at the start (Blankevoort's law)."""
    rng = np.random.default_rng(seed)
    centres = {"tibia": np.array([0, 0, -20.0]), "femur": np.array([0, 0, 20.0]), "patella": np.array([0, 0, 60.0])}
    pairs = [("femur", "tibia")] * int(0.6 * n) + [("patella", "tibia")] * int(0.2 * n)
    pairs += [("patella", "femur")] * (n - len(pairs))
    out = []
    for i, (a, b) in enumerate(pairs):
        p1 = centres[a] + rng.normal(0, 12.0, 3)
        p2 = centres[b] + rng.normal(0, 12.0, 3)
        out.append(
            dea.Ligament(
                a,
                p1,
                b,
                p2,
                stiffness=float(rng.uniform(500, 3000)),
                reference_strain=float(rng.uniform(-0.01, 0.04)),
                name=f"bundle{i}",
            )
        )
    return out


FEMUR_LOAD = np.array([40.0, -30.0, -1500.0, 2000.0, -1500.0, 800.0])
PATELLA_LOAD = np.array([10.0, 5.0, -300.0, 0.0, 0.0, 100.0])


def joint(tibia, femur, ligaments, femur_load=FEMUR_LOAD, patella_load=PATELLA_LOAD) -> dea.Joint:
    bodies = {
        "tibia": dea.Body(free=()),
        "femur": dea.Body(reference=(0, 0, 0), force=femur_load[:3], moment=femur_load[3:]),
        "patella": dea.Body(reference=(0, 0, 60.0), force=patella_load[:3], moment=patella_load[3:]),
    }
    law = dea.LinearLaw(10.0)
    contacts = [
        dea.Contact(tibia, law, body1="tibia", body2="femur"),
        dea.Contact(femur, law, body1="femur", body2="patella"),
    ]
    return dea.Joint(bodies, contacts, ligaments)


def alone(tibia, femur) -> list:
    """Each layer's two-body problem: the femur's translations on the tibia, the patella's on the femur."""
    law = dea.LinearLaw(10.0)
    return [
        dea.ContactProblem(tibia, law, force=FEMUR_LOAD[:3], reference=(0, 0, 0), free=("ux", "uy", "uz")),
        dea.ContactProblem(femur, law, force=PATELLA_LOAD[:3], reference=(0, 0, 60.0), free=("ux", "uy", "uz")),
    ]


def best(fn, repeats: int) -> tuple[float, float, object]:
    """``(wall s, CPU s, result)``: the best of ``repeats`` runs of ``fn`` by each clock."""
    walls, cpus, out = [], [], None
    for _ in range(repeats):
        start, cpu = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus), out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--springs", type=int, default=15000, help="springs per layer")
    parser.add_argument("--bundles", type=int, default=100)
    parser.add_argument("--frames", type=int, default=101)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore", dea.ValidityWarning)
    tibia, femur = layers(args.springs)
    ligaments = bundles(args.bundles)
    print(f"CPU: {cpu_name()} ({os.cpu_count()} logical cores); numpy {np.__version__}")
    print(f"joint: 3 bodies, layers of {len(tibia)} and {len(femur)} springs, {len(ligaments)} bundles")

    print(f"load average {' '.join(f'{v:.1f}' for v in os.getloadavg())} (the machine is shared)")
    t_joint, c_joint, s = best(lambda: dea.solve(joint(tibia, femur, ligaments)), args.repeats)
    assert s.success, s.message
    t_alone, c_alone, pair = best(lambda: [dea.solve(p) for p in alone(tibia, femur)], args.repeats)
    assert all(p.success for p in pair)
    ratio, cpu_ratio = t_joint / t_alone, c_joint / c_alone
    print(
        f"(1) static: joint {t_joint * 1e3:.1f} ms wall, {c_joint * 1e3:.1f} ms CPU ({s.iterations} Newton iterations, "
        f"certified); the two layers alone {t_alone * 1e3:.1f} ms wall, {c_alone * 1e3:.1f} ms CPU "
        f"({'+'.join(str(p.iterations) for p in pair)} iterations)"
    )
    for what, value in (("wall", ratio), ("CPU", cpu_ratio)):
        print(f"    ratio ({what}) {value:.2f}x against the goal of 2x: {'met' if value <= 2 else 'NOT met'}")

    from dea_opt.run.joint_path import solve_joint_path
    from dea_opt.scenario.joint_path import JointPath

    phase = np.linspace(0.0, 1.0, args.frames)
    shape = 0.3 + 0.7 * np.sin(np.pi * phase) ** 2
    femur_loads = np.outer(shape, FEMUR_LOAD) + np.outer(np.sin(2 * np.pi * phase), [20, 10, 0, 500, 300, 100])
    patella_loads = np.outer(shape, PATELLA_LOAD)
    path = JointPath(phase, {"femur": femur_loads, "patella": patella_loads}, {})
    base = joint(tibia, femur, ligaments)
    start, cpu = time.perf_counter(), time.process_time()
    solutions = solve_joint_path(base, path)
    t_path, c_path = time.perf_counter() - start, time.process_time() - cpu
    certified = sum(1 for x in solutions if x is not None and x.success)
    print(
        f"(2) path: {args.frames} frames in {t_path:.2f} s wall, {c_path:.2f} s CPU "
        f"({t_path / args.frames * 1e3:.1f} ms a frame), {certified} certified; against the goal of 10 s: "
        f"{t_path / 10:.2f} (wall), {c_path / 10:.2f} (CPU): {'met' if t_path <= 10 else 'NOT met'}"
    )
    results = HERE / "results"
    results.mkdir(exist_ok=True)
    with open(results / "joint.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(
            ["cpu", "springs_per_layer", "bundles", "joint_s", "alone_s", "ratio", "joint_cpu_s", "alone_cpu_s"]
            + ["cpu_ratio", "frames", "path_s", "path_cpu_s", "certified"]
        )
        writer.writerow(
            [cpu_name(), len(tibia), len(ligaments), t_joint, t_alone, ratio, c_joint, c_alone, cpu_ratio]
            + [args.frames, t_path, c_path, certified]
        )
    return ratio, t_path


if __name__ == "__main__":
    main()
