"""The compiled parts, declared here (pyproject.toml holds everything else): Walker.follow's loop
(``dea_opt/mesh/_walk.c``) and a finite-kinematics system's passes over its springs
(``dea_opt/formulations/finite/_finite.c``). Both optional, so that an install without a C compiler
still succeeds and runs the same loops in numpy (``dea_opt._checks.dependencies.compiled`` then
gives None for them)."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension("dea_opt.mesh._walk", ["dea_opt/mesh/_walk.c"], optional=True),
        Extension("dea_opt.formulations.finite._finite", ["dea_opt/formulations/finite/_finite.c"], optional=True),
    ]
)
