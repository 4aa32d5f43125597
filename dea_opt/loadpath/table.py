"""The per-frame table of a load path: one row per frame, certified or not, with validity and regions.

A frame whose answer is certified gets its numbers; a frame that failed (a load the springs
cannot carry, a certificate that failed, a solver error) gets its load, its status and its
message, and NaN wherever a number would come from the answer: a number in the table is
always a certified one. Every column's unit is the suffix of its name (``peak_pressure_MPa``,
``Fz_N``; :mod:`dea_opt.units`).
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import InputError

__all__ = [
    "MOTION_UNITS",
    "REGION_COLUMNS",
    "TABLE_COLUMNS",
    "FrameRegions",
    "failed_row",
    "make_table",
    "motion_columns",
    "region_prefixes",
    "solved_row",
]

#: Columns of every table, in order, with what they hold (each name ends with its unit,
#: :mod:`dea_opt.units`). The motion of each free dof (:data:`MOTION_UNITS`) follows them, then the
#: validity columns of each check (``validity_<check>``, from
#: :meth:`dea_opt.validity.Validity.columns`), then :data:`REGION_COLUMNS` for each region when
#: the layer has labels.
TABLE_COLUMNS = {
    "frame": "the frame's index, from 0",
    "time_s": "the frame's time",
    "Fx_N": "the applied force on the loaded body, x",
    "Fy_N": "the applied force, y",
    "Fz_N": "the applied force, z",
    "Mx_Nmm": "the applied moment about the loaded body's reference point, x",
    "My_Nmm": "the applied moment, y",
    "Mz_Nmm": "the applied moment, z",
    "peak_pressure_MPa": "the largest pressure",
    "mean_pressure_MPa": "the mean pressure over the contact",
    "contact_area_mm2": "the area of the springs in contact",
    "cop_x_mm": "the centre of pressure, x",
    "cop_y_mm": "the centre of pressure, y",
    "cop_z_mm": "the centre of pressure, z",
    "resultant_N": "the size of the spring forces' resultant",
    "max_compressive_strain": "the largest compressive strain",
    "n_springs": "the number of springs",
    "iterations": "the solver's iterations",
    "build_time_s": "the time to build the problem",
    "solve_time_s": "the time to solve it",
    "certificate_residual": "the largest of the certificate's relative residuals",
    "certificate_worst": "its name",
    "success": "certified",
    "status": "the solver's status, or why the frame failed",
    "message": "why the frame failed (empty when certified)",
    "valid": "certified and inside the model's validity",
    "validity_failed": "the failed validity checks, joined by ;",
}

#: Units of the motion columns (``body2_uz_mm``, ``body2_rx_rad``), by dof: one column per free
#: dof, after :data:`TABLE_COLUMNS`.
MOTION_UNITS = {"ux": "mm", "uy": "mm", "uz": "mm", "rx": "rad", "ry": "rad", "rz": "rad"}

#: Columns of each region, after the region's prefix (``medial_force_share``), with what they hold.
REGION_COLUMNS = {
    "force_x_N": "the resultant of the region's springs on body 2, x",
    "force_y_N": "its y",
    "force_z_N": "its z",
    "resultant_N": "its size",
    "force_share": "its component along the contact force over the contact force's size (1)",
    "force_magnitude_sum_N": "the sum of the springs' force magnitudes (no force on anything)",
    "peak_pressure_MPa": "the region's largest pressure",
    "mean_pressure_MPa": "its mean pressure over its contact",
    "contact_area_mm2": "its contact area",
    "cop_x_mm": "its centre of pressure, x",
    "cop_y_mm": "its centre of pressure, y",
    "cop_z_mm": "its centre of pressure, z",
}

_RESULT_COLUMNS = (
    "peak_pressure_MPa",
    "mean_pressure_MPa",
    "contact_area_mm2",
    "cop_x_mm",
    "cop_y_mm",
    "cop_z_mm",
    "resultant_N",
    "max_compressive_strain",
)


def region_prefixes(names) -> dict:
    """``{name: column prefix}``: letters, digits and ``_`` only, never starting with a digit, unique."""
    out, used = {}, set()
    for name in names:
        prefix = re.sub(r"[^0-9A-Za-z_]+", "_", str(name)).strip("_") or "region"
        if prefix[0].isdigit():
            prefix = f"region_{prefix}"
        candidate, k = prefix, 2
        while candidate in used or candidate in TABLE_COLUMNS:
            candidate, k = f"{prefix}_{k}", k + 1
        used.add(candidate)
        out[str(name)] = candidate
    return out


class FrameRegions:
    """The regions of one layer (a mask per label) and their columns for a frame.

    Parameters
    ----------
    labels : array_like, shape (N,)
        A region label per spring.
    prefixes : dict {name: prefix}, optional
        Column prefixes of the names (from the first frame, so that a path keeps its columns).
    """

    def __init__(self, labels, prefixes: dict | None = None):
        labels = np.asarray(labels)
        if labels.ndim != 1:
            raise InputError(f"region labels must be one label per spring, got shape {labels.shape}")
        names = np.unique(labels)
        self.masks = {str(name): labels == name for name in names}
        known = dict(prefixes or {})
        fresh = region_prefixes([n for n in self.masks if n not in known] + list(known))
        self.prefixes = {n: known.get(n, fresh[n]) for n in self.masks}

    def columns(self, solution=None) -> dict:
        """The region columns of a certified ``solution``, or NaN for every one (``None``)."""
        from ..anatomy.regions import region_statistics

        row = {}
        for name, mask in self.masks.items():
            prefix = self.prefixes[name]
            if solution is None:
                row.update({f"{prefix}_{c}": math.nan for c in REGION_COLUMNS})
                continue
            stats = region_statistics(solution, mask, name)
            cop, vector = stats.center_of_pressure, stats.force_vector
            row.update(
                {
                    f"{prefix}_force_x_N": vector[0],
                    f"{prefix}_force_y_N": vector[1],
                    f"{prefix}_force_z_N": vector[2],
                    f"{prefix}_resultant_N": stats.resultant,
                    f"{prefix}_force_share": stats.share,
                    f"{prefix}_force_magnitude_sum_N": stats.force_magnitude_sum,
                    f"{prefix}_peak_pressure_MPa": stats.peak_pressure,
                    f"{prefix}_mean_pressure_MPa": stats.mean_pressure,
                    f"{prefix}_contact_area_mm2": stats.contact_area,
                    f"{prefix}_cop_x_mm": cop[0],
                    f"{prefix}_cop_y_mm": cop[1],
                    f"{prefix}_cop_z_mm": cop[2],
                }
            )
        return row


def motion_columns(problem) -> dict:
    """``{column: index in u}``: the free dofs the frames solve for, as columns ``body<b>_<dof>_<unit>``
    (``body2_uz_mm``, ``body2_ry_rad``: :data:`MOTION_UNITS`): the motion each certified frame found
    (``Solution.u``; for finite kinematics on top of the frame's pose, as the free coordinates act)."""
    from ..units import dof_name

    return {dof_name(name): int(i) for name, i in zip(problem.free_names, problem.free_indices)}


def _motion(solution, motion: dict | None) -> dict:
    if not motion:
        return {}
    u = None if solution is None else np.asarray(solution.u, dtype=float)
    return {column: math.nan if u is None else float(u[i]) for column, i in motion.items()}


def _load_columns(k: int, t: float, load) -> dict:
    return {
        "frame": k,
        "time_s": float(t),
        "Fx_N": load[0],
        "Fy_N": load[1],
        "Fz_N": load[2],
        "Mx_Nmm": load[3],
        "My_Nmm": load[4],
        "Mz_Nmm": load[5],
    }


def solved_row(
    k: int, t: float, load, solution, regions: FrameRegions | None = None, motion: dict | None = None
) -> dict:
    """The row of frame ``k`` at time ``t`` (s) under ``load`` (the 6-vector on the loaded body)
    whose ``solution`` passed its certificate; ``motion`` (:func:`motion_columns`) the free dofs
    whose motion it reports."""
    cop = solution.center_of_pressure
    name, value = solution.certificate.worst()
    validity = solution.validity.columns()
    row = {
        **_load_columns(k, t, load),
        "peak_pressure_MPa": solution.peak_pressure,
        "mean_pressure_MPa": solution.mean_pressure,
        "contact_area_mm2": solution.contact_area,
        "cop_x_mm": cop[0],
        "cop_y_mm": cop[1],
        "cop_z_mm": cop[2],
        "resultant_N": float(np.linalg.norm(solution.contact_force)),
        "max_compressive_strain": solution.max_compressive_strain,
        "n_springs": len(solution.pressure),
        "iterations": solution.iterations,
        "build_time_s": solution.build_time,
        "solve_time_s": solution.solve_time,
        "certificate_residual": value,
        "certificate_worst": name,
        "success": True,
        "status": solution.status,
        "message": "",
        **_motion(solution, motion),
        **validity,
    }
    row["valid"] = bool(validity["valid"])
    if regions is not None:
        row.update(regions.columns(solution))
    return row


def failed_row(
    k: int,
    t: float,
    load,
    n_springs: int,
    status: str,
    message: str,
    solution=None,
    regions: FrameRegions | None = None,
    motion: dict | None = None,
) -> dict:
    """The row of a frame without a certified answer: its load, status and message, NaN results
    (the motion of ``motion``'s free dofs too: an uncertified answer's motion is not a result).

    ``solution`` is the uncertified answer when there is one (its iterations, times and
    certificate residual are kept: they say how it failed).
    """
    row = {**_load_columns(k, t, load), **{c: math.nan for c in _RESULT_COLUMNS}}
    if solution is not None:
        name, value = solution.certificate.worst()
        row.update(
            iterations=solution.iterations,
            build_time_s=solution.build_time,
            solve_time_s=solution.solve_time,
            certificate_residual=value,
            certificate_worst=name,
        )
    else:
        row.update(
            iterations=0, build_time_s=0.0, solve_time_s=0.0, certificate_residual=math.nan, certificate_worst=""
        )
    row.update(
        n_springs=int(n_springs),
        success=False,
        status=str(status),
        message=" ".join(str(message).split()),
        valid=False,
        validity_failed="",
    )
    row.update(_motion(None, motion))
    if regions is not None:
        row.update(regions.columns(None))
    return row


def make_table(rows: list, region_prefixes: dict | None = None, motion: dict | None = None):
    """The rows as a DataFrame: :data:`TABLE_COLUMNS`, the motion of the free dofs (``motion``,
    :func:`motion_columns`), the validity checks, then the regions'."""
    import pandas as pd

    validity: list[str] = []
    regions: list[str] = []
    region_names = {f"{p}_{c}" for p in (region_prefixes or {}).values() for c in REGION_COLUMNS}
    moved = list(motion or {})
    for row in rows:
        for key in row:
            if key in TABLE_COLUMNS or key in (motion or {}):
                continue
            target = regions if key in region_names else validity
            if key not in target:
                target.append(key)
    columns = [*TABLE_COLUMNS, *moved, *validity, *sorted(regions, key=_region_order(region_prefixes or {}))]
    table = pd.DataFrame(rows, columns=columns)
    for key in validity:  # a failed frame has no validity numbers
        table[key] = pd.to_numeric(table[key], errors="coerce")
    table["success"] = table["success"].astype(bool)
    table["valid"] = table["valid"].astype(bool)
    for key in ("status", "message", "validity_failed", "certificate_worst"):
        table[key] = table[key].fillna("").astype(str)
    return table


def _region_order(prefixes: dict):
    rank = {p: i for i, p in enumerate(prefixes.values())}
    suffixes = {c: i for i, c in enumerate(REGION_COLUMNS)}

    def key(column):
        for prefix, i in rank.items():
            suffix = column[len(prefix) + 1 :]
            if column.startswith(f"{prefix}_") and suffix in suffixes:
                return (i, suffixes[suffix])
        return (len(rank), 0)

    return key
