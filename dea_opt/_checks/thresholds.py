"""Thresholds that decide a yes-or-no question, named once so that a change is made in one place.

Lengths in mm. Relative thresholds say what they are relative to. Each is used by the
modules named beside it; none of them is a solver tolerance (those are options of the
formulations) or a floor that only keeps a division away from zero.
"""

#: A unit vector within this of a coordinate axis is that axis: map axes are then labelled
#: ``x (mm)`` rather than by their direction (io.plots).
AXIS_ALIGNED = 1e-9

#: A vector shorter than this (mm, or 1 for directions) is zero: a region's plane normal
#: (regions).
ZERO_LENGTH = 1e-12

#: A face whose area is below this times the squared size of its mesh is degenerate and is
#: dropped (mesh.repair).
DEGENERATE_AREA = 1e-14

#: Largest departure of a pose's last row from ``(0, 0, 0, 1)`` (mesh.springs).
POSE_LAST_ROW = 1e-9

#: Largest entry of ``|R^T R - I|`` for the 3x3 block of a pose to count as a rotation
#: (mesh.springs).
POSE_ROTATION = 1e-6

#: A ray is parallel to a triangle's plane when ``|det|`` in the Moller-Trumbore test is
#: below this times the squared length of the triangle's first edge (mesh.raycast).
RAY_PARALLEL = 1e-12

#: Barycentric slack of the ray/triangle test: a ray through an edge or a vertex meets
#: every triangle that shares it, so no ray slips between two faces (mesh.raycast).
RAY_EDGE = 1e-9

#: A crossing nearer than this times ``max(mesh size, 1 mm)`` to a ray's start is the face
#: the ray started from (mesh.raycast, mesh.springs).
SELF_HIT = 1e-7

#: Slack on ``cos(max_angle)`` so that two faces exactly at the angle limit make a spring
#: (mesh.springs).
ANGLE_SLACK = 1e-12

#: Compressive strain beyond which the linear law is no longer valid (Volokh, Chao &
#: Armand); a load path beyond it warns (loadpath).
LINEAR_VALIDITY = 0.3
