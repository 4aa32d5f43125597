"""A synthetic hip contact force over one walking cycle, shaped like Bergmann's curves.

The shipped file ``dea_opt/data/hip_gait.csv`` is made by :func:`hip_gait_load` with its
defaults; ``python -m dea_opt.gait`` writes it again, so its numbers are reproducible.

**Synthetic.** These are not measured data. The magnitude follows the shape of the
averaged walking curves measured with instrumented hip prostheses (Bergmann et al.,
J Biomech 2001): a double hump over stance, the first peak about 2.4 x body weight
shortly after heel strike, a valley at mid-stance, a second peak before toe-off, and a
small load in swing. The direction tilts medially about 20 degrees from the socket axis
in stance and swings from anterior to posterior. Use them to exercise load paths, not as
patient data.

Frame: the force acts on the femoral head (body 2) and pushes it into a socket that opens
toward +z, so ``Fz < 0``. Moments are zero: DEA contact is frictionless.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["BODY_WEIGHT", "HIP_GAIT_CSV", "hip_gait_load", "load_hip_gait", "write_hip_gait_csv"]

#: Body weight the shipped curve is scaled to (N), about 76 kg.
BODY_WEIGHT = 750.0
#: Duration of one walking cycle (s).
CYCLE_TIME = 1.1
#: The shipped file.
HIP_GAIT_CSV = Path(__file__).with_name("data") / "hip_gait.csv"

# Resultant in body weights at per cent of the cycle: heel strike at 0, first peak (2.4 BW)
# at 16 %, valley at 30 %, second peak at 50 %, toe-off near 62 %, swing after.
_MAGNITUDE = (
    (0, 0.35),
    (5, 0.95),
    (10, 1.95),
    (16, 2.40),
    (23, 2.00),
    (30, 1.70),
    (38, 1.80),
    (50, 2.30),
    (56, 1.75),
    (62, 0.75),
    (68, 0.30),
    (80, 0.22),
    (90, 0.28),
    (100, 0.35),
)
# Medial tilt from the socket axis (degrees): about 20 in stance, smaller in swing.
_FRONTAL = ((0, 14.0), (10, 19.0), (16, 20.0), (50, 20.0), (62, 16.0), (75, 10.0), (90, 11.0), (100, 14.0))
# Anterior (+) to posterior (-) tilt (degrees) over stance.
_SAGITTAL = ((0, 6.0), (16, 8.0), (35, 0.0), (50, -8.0), (62, -5.0), (80, 2.0), (100, 6.0))

_HEADER = (
    "# SYNTHETIC hip contact force over one walking cycle, shaped like Bergmann et al. (2001)\n"
    "# averaged walking curves: double hump, peaks about 2.4 x body weight. NOT measured data.\n"
    "# Made by dea_opt.gait.hip_gait_load(n_frames={n}, body_weight={bw:g}, cycle_time={ct:g});\n"
    "# regenerate with: python -m dea_opt.gait\n"
    "# Force on the femoral head (body 2) in N, pushing it into a socket that opens toward +z;\n"
    "# moments in N mm (zero: frictionless contact); time in s.\n"
)


def _curve(anchors, percent):
    from scipy.interpolate import PchipInterpolator

    x, y = np.array(anchors, dtype=float).T
    # PCHIP never overshoots its anchors, so the peaks are exactly where they are listed.
    return PchipInterpolator(x, y)(percent)


def hip_gait_load(n_frames: int = 101, body_weight: float = BODY_WEIGHT, cycle_time: float = CYCLE_TIME):
    """The synthetic hip load as a table, one row per frame.

    Parameters
    ----------
    n_frames : int
        Frames spread evenly over one cycle, both ends included (0 % and 100 %).
    body_weight : float
        Body weight in N; forces scale with it.
    cycle_time : float
        Duration of the cycle in s.

    Returns
    -------
    pandas.DataFrame
        Columns ``time`` (s), ``Fx, Fy, Fz`` (N), ``Mx, My, Mz`` (N mm).
    """
    import pandas as pd

    from ._checks.inputs import positive_integer
    from ._checks.memory import check_memory

    n_frames = positive_integer("n_frames", n_frames)
    # Seven columns and about as many temporaries of one float each per frame.
    check_memory(
        16 * 8.0 * n_frames,
        f"a hip gait load of n_frames = {n_frames}",
        "ask for fewer frames (101 resolve the cycle; 1000 are plenty)",
    )
    percent = np.linspace(0.0, 100.0, n_frames)
    magnitude = body_weight * _curve(_MAGNITUDE, percent)
    frontal = np.radians(_curve(_FRONTAL, percent))
    sagittal = np.radians(_curve(_SAGITTAL, percent))
    force = magnitude[:, None] * np.column_stack(
        [
            np.sin(frontal) * np.cos(sagittal),
            np.sin(sagittal),
            -np.cos(frontal) * np.cos(sagittal),
        ]
    )
    zeros = np.zeros_like(percent)
    return pd.DataFrame(
        {
            "time": percent / 100.0 * cycle_time,
            "Fx": force[:, 0],
            "Fy": force[:, 1],
            "Fz": force[:, 2],
            "Mx": zeros,
            "My": zeros,
            "Mz": zeros,
        }
    )


def write_hip_gait_csv(
    path=HIP_GAIT_CSV, n_frames: int = 101, body_weight: float = BODY_WEIGHT, cycle_time: float = CYCLE_TIME
) -> Path:
    """Write :func:`hip_gait_load` as CSV with its provenance header (atomically)."""
    from .files import write_data

    table = hip_gait_load(n_frames, body_weight, cycle_time)
    header = _HEADER.format(n=n_frames, bw=body_weight, ct=cycle_time)
    return write_data(path, header + table.to_csv(index=False, float_format="%.6f", lineterminator="\n"))


def load_hip_gait():
    """The shipped 101-frame cycle (:data:`HIP_GAIT_CSV`) as a DataFrame."""
    import pandas as pd

    return pd.read_csv(HIP_GAIT_CSV, comment="#")


if __name__ == "__main__":  # pragma: no cover - regenerates the shipped file
    print(write_hip_gait_csv())
