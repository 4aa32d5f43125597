"""The one compiled part, declared here (pyproject.toml holds everything else): Walker.follow's loop
(``dea_opt/mesh/_walk.c``), optional, so that an install without a C compiler still succeeds and
walks in numpy (``dea_opt.mesh.walk.compiled_walk`` is then None)."""

from setuptools import Extension, setup

setup(ext_modules=[Extension("dea_opt.mesh._walk", ["dea_opt/mesh/_walk.c"], optional=True)])
