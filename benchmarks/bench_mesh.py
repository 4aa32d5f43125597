"""Springs from meshes: :func:`dea_opt.mesh.springs_from_meshes` on two meshes of about F faces each.

Run::

    python benchmarks/bench_mesh.py                              # 1e4 and 1e5 faces, hip and sphere-bed
    python benchmarks/bench_mesh.py --faces 1e5 --pairs hip --engines grid

Pairs: ``hip`` (:func:`dea_opt.geometry.hip_meshes`, the lunate socket and the head, both
closed so their thickness is measured by casting through them) and ``sphere_on_bed``
(:func:`dea_opt.geometry.sphere_on_bed_meshes`, a closed bed under a rigid cap), refined so that
the two meshes have about ``F`` faces each (their geometric mean). Engines: ``embree``
(embreex) and ``grid`` (the numpy uniform-grid caster).

``cold_s``: fresh mesh objects (no trimesh caches, no ray-casting structure), the imports
warmed; the best of ``repeats`` calls, each on new copies. ``warm_s``: the same meshes again
(trimesh's caches and the caster are reused, as in a load path with poses). Each case runs in
a fresh subprocess. Target (speed issue): two 1e5-face meshes in <= 2 s.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

COLUMNS = [
    "pair",
    "engine",
    "target_faces",
    "faces1",
    "faces2",
    "n_springs",
    "mesh_build_s",
    "cold_s",
    "cold_first_s",
    "warm_s",
    "repeats",
    "peak_rss_mb",
    "success",
    "status",
]

#: Faces of each pair's meshes at its default resolution, and how they scale with it.
_HIP_FACES = (10160, 16800)  # at step = 3 deg; faces ~ step^-2


def make_pair(pair: str, faces: float):
    """The mesh pair ``pair`` with about ``faces`` faces per mesh (geometric mean of the two)."""
    import numpy as np

    from dea_opt.geometry import hip_meshes, sphere_on_bed_meshes

    if pair == "hip":
        step = 3.0 * np.sqrt(np.sqrt(_HIP_FACES[0] * _HIP_FACES[1]) / faces)
        return hip_meshes(step=float(step))
    if pair == "sphere_on_bed":
        n_bed = max(int(round(np.sqrt(faces / 4.0))), 4)  # a closed slab: ~4 n^2 faces
        step = 2.0 * np.sqrt(11520 / faces)  # the cap: 11520 faces at step = 2 deg
        return sphere_on_bed_meshes(n_bed=n_bed, step=float(step))
    raise ValueError(f"pair must be 'hip' or 'sphere_on_bed', got {pair!r}")


def one(
    pair: str, faces: float, engine: str, repeats: int = 3, budget: float = 30.0, blas_threads: int | None = None
) -> dict:
    """Time springs_from_meshes on ``pair`` at about ``faces`` faces with ``engine``."""
    from common import blas_limit

    with blas_limit(blas_threads):
        return _one(pair, faces, engine, repeats, budget)


def _one(pair, faces, engine, repeats, budget) -> dict:
    from common import peak_rss_mb

    from dea_opt.mesh import springs_from_meshes

    # Warm the imports and the engine's one-time set-up on a small pair.
    small = make_pair(pair, 2000)
    springs_from_meshes(small.mesh1, small.mesh2, engine=engine, **small.options)
    start = time.perf_counter()
    meshes = make_pair(pair, faces)
    mesh_build = time.perf_counter() - start
    cold = []
    spent = 0.0
    layer = None
    while len(cold) < repeats and (not cold or spent + min(cold) <= budget):
        m1, m2 = meshes.mesh1.copy(), meshes.mesh2.copy()  # no caches, no ray structure
        start = time.perf_counter()
        layer = springs_from_meshes(m1, m2, engine=engine, **meshes.options)
        cold.append(time.perf_counter() - start)
        spent += cold[-1]
    start = time.perf_counter()
    springs_from_meshes(m1, m2, engine=engine, **meshes.options)
    warm = time.perf_counter() - start
    return {
        "pair": pair,
        "engine": engine,
        "target_faces": int(faces),
        "faces1": len(meshes.mesh1.faces),
        "faces2": len(meshes.mesh2.faces),
        "n_springs": len(layer),
        "mesh_build_s": mesh_build,
        "cold_s": min(cold),
        "cold_first_s": cold[0],
        "warm_s": warm,
        "repeats": len(cold),
        "peak_rss_mb": peak_rss_mb(),
        "success": True,
        "status": "ok",
    }


def run(
    pair: str, faces: float, engine: str, timeout: float = 600.0, isolate: bool = True, blas_threads: int | None = None
) -> dict:
    from common import run_isolated

    kwargs = {"pair": pair, "faces": float(faces), "engine": engine, "blas_threads": blas_threads}
    if isolate:
        row = run_isolated("bench_mesh", "one", kwargs, timeout)
    else:
        try:
            row = one(**kwargs)
        except Exception as exc:  # noqa: BLE001
            row = {"status": f"error: {type(exc).__name__}: {exc}"[:300], "success": False}
    return {"pair": pair, "engine": engine, "target_faces": int(faces), **row}


def main(argv=None):
    from common import header, print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--faces", nargs="+", type=float, default=[1e4, 1e5])
    parser.add_argument("--pairs", nargs="+", default=["hip", "sphere_on_bed"], choices=["hip", "sphere_on_bed"])
    parser.add_argument("--engines", nargs="+", default=["embree", "grid"], choices=["embree", "grid"])
    parser.add_argument("--out", type=Path, default=HERE / "results" / "mesh.csv")
    args = parser.parse_args(argv)
    preamble = header("dea-opt springs-from-meshes benchmark")
    print(preamble, end="")
    rows = [run(pair, faces, engine) for faces in args.faces for pair in args.pairs for engine in args.engines]
    print_table(rows, COLUMNS)
    write_csv(args.out, rows, COLUMNS, preamble)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
