"""Write the data files of the example scenarios (run from anywhere; files land beside this script).

* ``plate_springs.csv``: the core's plate case as a springs table.
* ``meshes/hip_socket.stl``, ``meshes/hip_head.stl``: the lunate hip of ``dea_opt.geometry``.
"""

from pathlib import Path

from dea_opt.geometry import hip_meshes, plate_layer
from dea_opt.scenario import write_springs

HERE = Path(__file__).resolve().parent


def main():
    write_springs(plate_layer(40.0, 10.0, 400, 10, thickness=2.0), HERE / "plate_springs.csv")
    pair = hip_meshes(step=7.5)
    (HERE / "meshes").mkdir(exist_ok=True)
    pair.mesh1.export(HERE / "meshes" / "hip_socket.stl")
    pair.mesh2.export(HERE / "meshes" / "hip_head.stl")


if __name__ == "__main__":
    main()
