"""Reading an OpenSim model: ``dea_opt.opensim.read_model`` and the scenario of ``import-osim``.

Run from the repository's top::

    python benchmarks/bench_opensim.py                 # ../shared/data/tka/DM.osim, 5 repeats
    python benchmarks/bench_opensim.py path/to/model.osim --repeats 10

Prints one line per measure: ``first_s``, a fresh process's first read (``python -c``, with the
imports of dea_opt.opensim and numpy counted: what ``dea-opt import-osim`` waits for);
``read_s``, the best of ``repeats`` reads in this process (XML, components, frames, joints,
contact, 149 ligaments and the not-modelled report at the default pose); ``scenario_s``, the
scenario text made from a read model; ``poses_s`` and ``ligaments_s``, the pose of every body and
every bundle's lengths, strains and forces at the default coordinates. Target (the OpenSim
issue): reading DM.osim and building the scenario within 2 s.
"""

from __future__ import annotations

import argparse
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
    print(
        f"  target: read and build the scenario within 2 s (a fresh process): {total:.3f} s, {'met' if total <= 2 else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
