"""How dea-opt writes files: atomically, and a run's outputs together.

:mod:`~dea_opt.files.atomic` writes a file atomically (a temporary file beside the target,
``fsync``, then a rename: an interrupted run leaves the old file or the new one, never half of
one) and keeps a run's finished files staged until the run publishes them all at once
(:mod:`dea_opt.run.publish`); :mod:`~dea_opt.files.locks` is the one file lock behind an output
folder's lock, a sweep's journal and claims, and the spring cache. The file formats themselves
are :mod:`dea_opt.io`'s.
"""

from .atomic import atomic_open, atomic_path, write_atomic, write_data

__all__ = ["atomic_open", "atomic_path", "write_atomic", "write_data"]
