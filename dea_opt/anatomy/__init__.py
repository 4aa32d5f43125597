"""The joint's anatomy: its anatomical frame, and the regions (compartments) its load splits into.

:mod:`~dea_opt.anatomy.frame` holds :class:`AnatomicalFrame` (which way is medial, anterior
and proximal, and where the origin is: the frame maps are drawn in);
:mod:`~dea_opt.anatomy.regions` the regional statistics (:func:`regional_statistics`,
:func:`split_by_axis`, :func:`label_by_axis`: how the load splits between parts of the contact).
"""

from .frame import AXES, AnatomicalFrame
from .regions import RegionStats, label_by_axis, region_statistics, regional_statistics, split_by_axis

__all__ = [
    "AXES",
    "AnatomicalFrame",
    "RegionStats",
    "label_by_axis",
    "region_statistics",
    "regional_statistics",
    "split_by_axis",
]
