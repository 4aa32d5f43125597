"""What decides whether an input, a resource or a dependency is acceptable (private).

:mod:`~dea_opt._checks.inputs` (boundary checks of the public constructors, each raising a
named :class:`~dea_opt.errors.InputError`), :mod:`~dea_opt._checks.thresholds` (the thresholds
that decide yes-or-no questions), :mod:`~dea_opt._checks.memory` (memory checked before a
large allocation), :mod:`~dea_opt._checks.threads` (BLAS on one thread where a second only
slows the passes over the springs) and :mod:`~dea_opt._checks.dependencies` (optional
dependencies imported where they are needed).
"""
