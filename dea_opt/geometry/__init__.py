"""Embedded geometries, made in code: the reference problems of the tests, the paper and the demo.

Two kinds, one package:

- :mod:`~dea_opt.geometry.layers`: the exact spring layers of the closed-form checks
  (:func:`plate_layer`, :func:`sphere_on_bed_layer`, :func:`socket_layer`), each a
  :class:`~dea_opt.layer.SpringLayer` built directly with exact cell areas, no meshes;
- :mod:`~dea_opt.geometry.meshes`: triangle surfaces (``trimesh.Trimesh``): closed cartilage
  volumes (:func:`slab_mesh`, :func:`spherical_shell_mesh`) and pairs of them in contact
  (:class:`MeshPair`: :func:`plate_meshes`, :func:`sphere_on_bed_meshes`, :func:`hip_meshes`,
  :func:`knee_meshes`), whose springs come from ray casting (:mod:`dea_opt.mesh`).

Units: mm and degrees.
"""

from .layers import plate_layer, socket_layer, sphere_on_bed_layer
from .meshes import (
    MeshPair,
    hip_meshes,
    knee_meshes,
    plate_meshes,
    slab_mesh,
    sphere_on_bed_meshes,
    spherical_shell_mesh,
)

__all__ = [
    "MeshPair",
    "hip_meshes",
    "knee_meshes",
    "plate_layer",
    "plate_meshes",
    "slab_mesh",
    "socket_layer",
    "sphere_on_bed_layer",
    "sphere_on_bed_meshes",
    "spherical_shell_mesh",
]
