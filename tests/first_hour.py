"""A small knee of one's own, as a new user brings it: three cartilage files (two tibial
plateaus, body 1; two femoral caps, body 2) about 70 mm from the origin, as a scanner puts them,
in millimetres or in metres; a scenario on them, and a stance as a CSV and as an OpenSim
JointReaction ``.sto`` (the tibia's reaction, in N and N m, as OpenSim writes it).

The geometry is the tutorial's (*Your own joint*): casting it takes a fraction of a second, so
the tests of the first hour (``test_first_mistakes.py``, ``test_init.py``) run on it anywhere.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: Where the scanner put the joint (mm).
WHERE = np.array([-70.0, -6.0, -19.0])
#: The stance's forces on the femur (N, along -z) and varus-valgus moments (N mm about y).
FRAMES = 11
STO_PREFIX = "knee_r_on_tibia_r_in_tibia_r"


def write_meshes(folder: Path, scale: float = 1.0) -> dict:
    """``{"medial", "lateral", "femur"}`` -> the STL files written into ``folder`` (mm times
    ``scale``: 1e-3 writes metres)."""
    import trimesh

    from dea_opt.geometry import slab_mesh, spherical_shell_mesh

    folder.mkdir(parents=True, exist_ok=True)
    parts = {
        "medial": slab_mesh(24.0, 24.0, 3.0, 20, 20, center=(20.0, 0.0)),
        "lateral": slab_mesh(24.0, 24.0, 3.0, 20, 20, center=(-20.0, 0.0)),
        "femur": trimesh.util.concatenate(
            [
                spherical_shell_mesh(r, 2.0, 25.0, center=(x, 0.0, r), axis=(0.0, 0.0, -1.0), step=2.0)
                for x, r in ((20.0, 45.0), (-20.0, 40.0))
            ]
        ),
    }
    files = {}
    for name, mesh in parts.items():
        mesh.apply_translation(WHERE)
        mesh.apply_scale(scale)
        files[name] = folder / f"{name}.stl"
        mesh.export(files[name])
    return files


def scenario_text(files: dict, *, load: str | None = None, scale: float | None = None, extra: str = "") -> str:
    """A scenario a new user writes for the meshes ``files``: the reference at the contact's
    centre, the femur free to sink and tilt; ``load`` replaces ``[load]`` (e.g. a
    ``[load_path]`` table)."""
    scale_line = f"scale = {scale}\n" if scale is not None else ""
    load = load if load is not None else "[load]\nforce = [0.0, 0.0, -1000.0]\n"
    return (
        '[geometry]\nkind = "meshes"\n'
        f'mesh1 = {{ medial = "{files["medial"]}", lateral = "{files["lateral"]}" }}\n'
        f'mesh2 = "{files["femur"]}"\n{scale_line}'
        '[law]\nkind = "linear"\nH = 10.0\n'
        '[body2]\nreference = "contact"\nfree = ["uz", "ry"]\n'
        f"{load}{extra}"
        '[output]\nformats = ["json"]\n'
    )


def stance() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(times (T,), forces (T, 3) N on the femur, moments (T, 3) N mm)``: 200 to 1000 N
    pressing the femur down, with a varus-valgus moment up to 4000 N mm."""
    times = np.linspace(0.0, 0.6, FRAMES)
    phase = np.sin(np.pi * times / 0.6)
    forces = np.zeros((FRAMES, 3))
    forces[:, 2] = -(200.0 + 800.0 * phase)
    moments = np.zeros((FRAMES, 3))
    moments[:, 1] = 4000.0 * np.sin(2.0 * np.pi * times / 0.6)
    return times, forces, moments


def write_csv(path: Path, forces=None, moments=None, columns=("Fx", "Fy", "Fz", "Mx", "My", "Mz")) -> Path:
    """The stance (or ``forces``/``moments``) as a load-path CSV with ``columns``."""
    times, f0, m0 = stance()
    forces = f0 if forces is None else forces
    moments = m0 if moments is None else moments
    values = np.column_stack([times, forces, moments])[:, : 1 + len(columns)]
    lines = [",".join(("time", *columns))] + [",".join(f"{v:.9g}" for v in row) for row in values]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_sto(path: Path, moment_factor: float = 1e-3) -> Path:
    """The stance as an OpenSim JointReaction file: the tibia's reaction (the femur's load
    negated), moments in N m (``moment_factor`` 1e-3; 1.0 writes N mm, the mistake)."""
    times, forces, moments = stance()
    labels = ["time", *(f"{STO_PREFIX}_{q}" for q in ("fx", "fy", "fz", "mx", "my", "mz"))]
    rows = np.column_stack([times, -forces, -moments * moment_factor])
    header = [f"{STO_PREFIX}_JointReaction", "version=1", f"nRows={len(rows)}", f"nColumns={len(labels)}"]
    header += ["inDegrees=yes", "endheader", "\t".join(labels)]
    path.write_text("\n".join(header + ["\t".join(f"{v:.9g}" for v in row) for row in rows]) + "\n")
    return path


def sto_columns(sign: str = "-", moments: bool = True) -> str:
    """The ``columns`` table of :func:`write_sto`'s file (``sign`` "-": the femur's load)."""
    quantities = ("fx", "fy", "fz", "mx", "my", "mz") if moments else ("fx", "fy", "fz")
    named = ", ".join(f'{q[0].upper()}{q[1]} = "{sign}{STO_PREFIX}_{q}"' for q in quantities)
    return "{ " + named + " }"
