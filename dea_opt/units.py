"""Units in the names of what dea-opt writes: every column of its CSV files and every key of its JSON.

One convention for every output (``frames.csv``, ``contact.csv``, ``sweep.csv``, ``summary.json``,
``contact.json``, ...), and for the tables and dicts that are written to them
(:attr:`~dea_opt.loadpath.PathResult.table`, :meth:`~dea_opt.Solution.summary`): a number's unit is
the **suffix of its name**, ``peak_pressure_MPa``, ``contact_area_mm2``, ``Fz_N``, ``Mx_Nmm``,
``time_s``, ``body2_rx_rad``. A name without a suffix holds a count, an index, a dimensionless
ratio (a strain, a share, a relative residual), a flag or a text (:data:`UNITLESS` lists every one).
In JSON, an object that holds a ``unit`` key (a validity check's ``value`` and ``limit``, a range's
``min``, ``max`` and ``at_peak``) states the unit of its numbers there, and an object whose own
key ends with a unit gives it to its numbers (``peak_pressure_MPa: {lower: 2.1, upper: 1.9}``).
:func:`dea_opt.run.units.unnamed_units` finds any number of a JSON document left out by these rules.

Why names and not a sidecar schema (a Frictionless Table Schema beside each CSV): the unit then
travels with the column wherever it goes (a spreadsheet, ``pandas.read_csv``, R's ``read.csv``,
a column copied into another table, a plot's axis), with no second file to lose and no tool to
read it; and Table Schema has no standard field for a unit, so a schema would state it in free
text that no tool reads either. The suffixes are plain ASCII (``mm2``, ``Nmm``, ``MPa_s``): valid
identifiers in pandas, R and MATLAB.

Python attributes (``solution.peak_pressure``) stay named by their quantity; their docstrings give
the unit.
"""

from __future__ import annotations

__all__ = [
    "SUFFIXES",
    "UNITLESS",
    "UNITLESS_OBJECTS",
    "dof_name",
    "label",
    "split_unit",
    "unit_name",
    "with_unit",
]

#: Suffix of each unit (the text after the last ``_`` of a name; ``MPa_s`` takes two).
SUFFIXES = {
    "mm": "mm",
    "mm^2": "mm2",
    "N": "N",
    "N mm": "Nmm",
    "MPa": "MPa",
    "MPa s": "MPa_s",
    "s": "s",
    "rad": "rad",
    "deg": "deg",
    "bytes": "bytes",
    "%": "percent",
}
_UNITS = {suffix: unit for unit, suffix in SUFFIXES.items()}

#: Names that carry no unit, and what they hold: counts, indices, dimensionless ratios, flags,
#: texts. A name ``<prefix>_<one of these>`` (a region's ``medial_force_share``, a check's
#: ``validity_strain``) is unitless too.
UNITLESS = {
    "frame": "the frame's index (from 0)",
    "frames": "a number of frames",
    "index": "an index",
    "nx": "a component of the unit normal",
    "ny": "a component of the unit normal",
    "nz": "a component of the unit normal",
    "normal": "a unit vector",
    "medial": "a component of a unit vector",
    "anterior": "a component of a unit vector",
    "proximal": "a component of a unit vector",
    "strain": "a strain, tension positive (1)",
    "max_compressive_strain": "the largest compressive strain (1)",
    "in_contact": "1 where the spring is compressed, else 0",
    "source_face": "the face of mesh 1 the spring was cast from (-1: unknown)",
    "label": "a region label",
    "n_springs": "a number of springs",
    "springs": "a number of springs",
    "iterations": "a number of iterations",
    "certificate_residual": "the largest of the certificate's relative residuals (1)",
    "force_share": "the region's force along the contact force over the contact force's size (1)",
    "share": "the region's force along the contact force over the contact force's size (1)",
    "success": "whether the answer passed its certificate",
    "valid": "whether the answer lies inside the model's validity",
    "exit_code": "the exit code of dea-opt run",
    "count": "a count",
    "iterations_total": "the solver's iterations over the frames",
    "iterations_mean": "the solver's iterations a frame, on average",
    "frames_outside_validity": "the certified frames outside validity (indices, or their count)",
    "worst_frame": "the frame of a check's worst value",
    "peak_frame": "the frame of the largest peak pressure",
    "sites_above_threshold": "the springs (or faces) ever above the exposure's threshold",
    "worst_residual": "the largest of the certificate's relative residuals (1)",
    "recast_force_error": "the re-cast springs' force against the answer's, relative (1)",
    "force_error": "the re-cast springs' force against the answer's, relative (1)",
    "kept": "springs kept by the re-cast",
    "gained": "springs gained by the re-cast",
    "dropped": "springs the proximity window dropped",
    "rejected": "springs the re-cast rejected",
    "dropped_springs": "a validity check: springs the proximity window dropped",
    "lost_through_layer": "a validity check: loaded springs lost through the layer",
    "gap_error": "a validity check: the linearised motion's error along a normal, over the thickness (1)",
    "stability": "a validity check: the most negative stiffness, relative (1)",
    "mean_force_share": "a region's force share, on average over the frames (1)",
    "min_force_share": "its smallest (1)",
    "max_force_share": "its largest (1)",
    "relative_time": "time over the fastest (1)",
    "d_pressure": "the largest pressure difference from the reference, over its peak pressure (1)",
    "d_displacement": "the largest displacement difference from the reference, relative (1)",
    "check_tol": "the certificate's tolerance (1)",
    "solver_tol": "the solver's tolerance (1)",
    "repeat": "the repetition's index",
    "residual": "a measured point's residual over its standard deviation (1)",
    "spring": "a spring's index",
    "dataset": "a data set's index",
    "noise": "the relative standard deviation of a map's readings (1)",
    "cost": "half the sum of the squared weighted residuals (1)",
    "degrees_of_freedom": "the residuals less what the fit absorbs",
    "n_residuals": "a number of residuals",
    "nfev": "a number of solves",
    "points": "a number of measured points",
    "points_matched": "the measured points matched to springs",
    "correlation": "a correlation coefficient (1)",
    "beta": "the Ateshian law's beta (1)",
    "thickness_scale": "a factor on the thickness (1)",
    "pid": "a process id",
    "certified": "a number of certified frames",
    "bundle": "a ligament bundle's index",
    "runs": "a number of runs",
    "equilibrium": "a certificate residual, relative to the problem's scale (1)",
    "tension": "a certificate residual, relative (1)",
    "complementarity": "a certificate residual, relative (1)",
    "consistency": "a certificate residual, relative (1)",
    "energy": "a certificate residual: the energy a Newton step could release, relative (1)",
}

#: Objects of the JSON outputs whose numbers carry no unit, and what they hold.
UNITLESS_OBJECTS = {
    "certificate": "the certificate's residuals, each relative to the problem's scale (1), and their tolerance",
    "info": "the solver's own report: counts and relative residuals",
    "label_codes": "the integer code of each text label (the VTK files' label array)",
    "lost": "springs lost by the re-cast, by reason",
    "overrides": "the --set values by scenario key, as given (their units: dea-opt schema)",
    "failures": "frames without a certified answer, counted by status",
}


def with_unit(name: str, unit: str) -> str:
    """``name`` with the suffix of ``unit`` (``"peak_pressure", "MPa"`` -> ``"peak_pressure_MPa"``);
    ``name`` itself for a dimensionless unit (``""``, ``"1"``)."""
    if unit in ("", "1"):
        return name
    return f"{name}_{SUFFIXES[unit]}"


def split_unit(name: str) -> tuple[str, str | None]:
    """``(quantity, unit)`` of a name: ``"peak_pressure_MPa"`` -> ``("peak_pressure", "MPa")``;
    ``(name, None)`` when it has no unit suffix."""
    head, _, tail = name.rpartition("_")
    if head.endswith("_MPa") and tail == "s":
        return head[: -len("_MPa")], "MPa s"
    if head and tail in _UNITS:
        return head, _UNITS[tail]
    return name, None


def unit_name(name: str) -> str:
    """The unit of a name, as text for a label: ``"MPa"``, ``"mm^2"``, or ``""`` for a unitless one."""
    return split_unit(name)[1] or ""


def label(name: str) -> str:
    """An axis label of a column: ``"peak_pressure_MPa"`` -> ``"peak pressure (MPa)"``."""
    quantity, unit = split_unit(name)
    text = quantity.replace("_", " ")
    return f"{text} ({unit})" if unit else text


def dof_name(dof: str, what: str = "motion") -> str:
    """The column of a degree of freedom ``body2.uz`` (or ``body2_uz``): its motion
    (``body2_uz_mm``, ``body2_rx_rad``) or, ``what="force"``, the generalized force along it
    (``body2_uz_N``, ``body2_rx_Nmm``)."""
    name = dof.replace(".", "_")
    rotation = name.rsplit("_", 1)[-1].startswith("r")
    if what == "force":
        return with_unit(name, "N mm" if rotation else "N")
    return with_unit(name, "rad" if rotation else "mm")
