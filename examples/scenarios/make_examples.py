"""Write the data files of the example scenarios (run from anywhere; files land beside this script).

* ``plate_springs.csv``: the core's plate case as a springs table.
* ``meshes/hip_socket.stl``, ``meshes/hip_head.stl``: the lunate hip of ``dea_opt.geometry``.
* ``hip_joint_reaction.sto``: the synthetic hip cycle (``dea_opt.gait``) at 21 frames, written as
  OpenSim's JointReaction would: the force of the acetabulum on the femur (minus the load that
  presses the head into the socket), in N, and its moment in N m, in the frame of the meshes.
* ``knee/knee_walk.csv`` and ``knee/knee_walk.sto``: a synthetic 51-frame stance of the real knee
  (``../shared/data/knee``): a double-hump compressive force of 200 to 1050 N on the femur along
  -z and a varus-valgus moment of +-8 N m about y (``knee_walk``); the same numbers as a CSV
  (N, N mm) and as a JointReaction file (the tibia's reaction on the femur's load: N, N m).
"""

import math
from pathlib import Path

from dea_opt.gait import hip_gait_load
from dea_opt.geometry import hip_meshes, plate_layer
from dea_opt.scenario import write_springs

HERE = Path(__file__).resolve().parent
STO_HEADER = """hip_r_JointReaction
version=1
nRows={rows}
nColumns=7
inDegrees=yes

Units are S.I. units (second, meters, Newtons, ...)
If the header above contains a line with 'inDegrees', this indicates whether rotational values are in degrees (yes) or radians (no).

endheader
"""
STO_COLUMNS = ["time"] + [f"hip_r_on_femur_r_in_acetabulum_{c}" for c in ("fx", "fy", "fz", "mx", "my", "mz")]


def write_joint_reaction(path, frames: int = 21) -> None:
    """The synthetic hip cycle as an OpenSim Storage file (tab-separated, S.I. units)."""
    table = hip_gait_load(frames)
    rows = ["\t".join(STO_COLUMNS)]
    for _, row in table.iterrows():
        values = [
            row["time"],
            -row["Fx"],
            -row["Fy"],
            -row["Fz"],
            -row["Mx"] / 1000,
            -row["My"] / 1000,
            -row["Mz"] / 1000,
        ]
        rows.append("\t".join(f"{v + 0.0:.6f}" for v in values))  # + 0.0: no "-0.000000"
    Path(path).write_text(STO_HEADER.format(rows=len(table)) + "\n".join(rows) + "\n")


KNEE_STO_HEADER = """knee_r_JointReaction
version=1
nRows={rows}
nColumns=7
inDegrees=yes
endheader
"""
KNEE_STO_COLUMNS = ["time"] + [f"knee_r_on_tibia_r_in_tibia_r_{c}" for c in ("fx", "fy", "fz", "mx", "my", "mz")]


def knee_walk(frames: int = 51, duration: float = 0.6) -> list[tuple]:
    """``(time s, Fx, Fy, Fz N, Mx, My, Mz N mm)`` on the femur over a synthetic stance."""
    rows = []
    for i in range(frames):
        s = i / (frames - 1)
        fz = -(200.0 + 1000.0 * (0.6 * math.sin(math.pi * s) + 0.4 * math.sin(2 * math.pi * s) ** 2))
        rows.append((duration * s, 0.0, 0.0, fz, 0.0, 8000.0 * math.sin(2 * math.pi * s), 0.0))
    return rows


def write_knee_walk(folder) -> None:
    """:func:`knee_walk` as ``knee_walk.csv`` (N, N mm) and ``knee_walk.sto`` (the reaction on the
    tibia, its negative: N, N m)."""
    rows = knee_walk()
    text = ["time,Fx,Fy,Fz,Mx,My,Mz"] + [",".join(f"{v + 0.0:.6g}" for v in row) for row in rows]
    (Path(folder) / "knee_walk.csv").write_text("\n".join(text) + "\n")
    sto = ["\t".join(KNEE_STO_COLUMNS)]
    for t, *load in rows:
        values = [t, *(-v for v in load[:3]), *(-v / 1000 for v in load[3:])]
        sto.append("\t".join(f"{v + 0.0:.6f}" for v in values))
    (Path(folder) / "knee_walk.sto").write_text(KNEE_STO_HEADER.format(rows=len(rows)) + "\n".join(sto) + "\n")


def main():
    write_springs(plate_layer(40.0, 10.0, 400, 10, thickness=2.0), HERE / "plate_springs.csv")
    pair = hip_meshes(step=7.5)
    (HERE / "meshes").mkdir(exist_ok=True)
    pair.mesh1.export(HERE / "meshes" / "hip_socket.stl")
    pair.mesh2.export(HERE / "meshes" / "hip_head.stl")
    write_joint_reaction(HERE / "hip_joint_reaction.sto")
    (HERE / "knee").mkdir(exist_ok=True)
    write_knee_walk(HERE / "knee")


if __name__ == "__main__":
    main()
