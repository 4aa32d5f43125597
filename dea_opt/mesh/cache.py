"""Springs cast once per distinct geometry and pose: a content-addressed cache a sweep's workers share.

The cases of a sweep usually vary the law, the load or the solver, not the meshes: without a
cache every case read and cleaned the same meshes and cast the same springs again. Within a
sweep (:func:`active`), :func:`cast` looks a cast up by its key and computes it only when no
worker has:

* the key is the SHA-256 of the meshes' vertex and face bytes, the cast's options (thickness
  specifications, proximity window, flip, labels, the ray engine that runs), the pose and the
  cache's format and dea-opt's version, so another geometry, window or pose is another entry;
* an entry is ``<folder>/<key>.npz``: what the rays found (the faces with a spring, gaps,
  faces met and where, the two thicknesses, every face's outcome, the warnings the cast gave)
  and nothing that the meshes give again; :func:`dea_opt.mesh.springs.assemble_cast` turns
  it back into the very :class:`~dea_opt.mesh.SpringCast` (same bytes);
* it is written atomically (a complete file or none) while its lock (``<key>.lock``,
  :mod:`dea_opt.files.locks`, released by the kernel when a process dies) is held, so concurrent workers cast
  it once: the others wait for the lock and read the file. An entry that cannot be read (or
  whose key differs) is cast again and replaced.

Within one worker process the meshes read from files (by path, size and modification time),
the meshes checked for casting and the casts themselves are also kept in memory. Units: mm.
"""

from __future__ import annotations

import contextlib
import contextvars
import hashlib
import json
import os
import warnings
import zipfile
from pathlib import Path

import numpy as np

from .._version import __version__

__all__ = ["FORMAT", "active", "cast", "cast_key", "directory", "mesh_part", "stats"]

#: Version of the entries' layout (part of every key).
FORMAT = 1
_ARRAYS = ("sel", "gap", "hit_face", "hit_point2", "h1", "h2", "outcome")
_FOLDER: contextvars.ContextVar = contextvars.ContextVar("dea_opt_spring_cache", default=None)
_MEMORY_ENTRIES = 8  # casts kept in memory per process (a sweep has a few geometries and poses)
_casts: dict = {}
_prepared: dict = {}
_meshes: dict = {}
_STATS = {"hits_memory": 0, "hits_disk": 0, "casts": 0, "meshes_read": 0}


def stats() -> dict:
    """This process's counts: casts found in memory, found on disk, computed; mesh files read."""
    return dict(_STATS)


def directory() -> Path | None:
    """The folder of the active cache, or None outside :func:`active`."""
    return _FOLDER.get()


@contextlib.contextmanager
def active(folder):
    """Use the cache in ``folder`` (created when missing) inside the block, in this thread."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    token = _FOLDER.set(folder)
    try:
        yield folder
    finally:
        _FOLDER.reset(token)


def mesh_part(files, scale: float, read):
    """``read(files, scale)`` (a mesh file, or a table ``{label: file}``), once per (files, their
    sizes and modification times, scale) in this process while a cache is active; every call
    otherwise."""
    if directory() is None:
        return read(files, scale)
    paths = list(files.values()) if isinstance(files, dict) else [files]
    stamp = (repr(files), float(scale), tuple((os.stat(p).st_size, os.stat(p).st_mtime_ns) for p in paths))
    if stamp not in _meshes:
        _STATS["meshes_read"] += 1
        _meshes[stamp] = read(files, scale)
    return _meshes[stamp]


# --- keys --------------------------------------------------------------------------------


def _feed(digest, value) -> None:
    """Add ``value`` to ``digest`` unambiguously (type tag, shape, dtype and bytes)."""
    import trimesh

    if value is None or isinstance(value, (bool, int, float, str)):
        digest.update(json.dumps([type(value).__name__, value]).encode())
    elif isinstance(value, trimesh.Trimesh):
        digest.update(b"mesh")
        _feed(digest, np.asarray(value.vertices, dtype=np.float64))
        _feed(digest, np.asarray(value.faces, dtype=np.int64))
    elif isinstance(value, (str, os.PathLike)):
        digest.update(b"file" + Path(value).read_bytes())
    elif isinstance(value, (tuple, list)):
        digest.update(f"seq{len(value)}".encode())
        for item in value:
            _feed(digest, item)
    elif isinstance(value, dict):
        digest.update(f"dict{len(value)}".encode())
        for name in sorted(value):
            _feed(digest, name)
            _feed(digest, value[name])
    else:
        array = np.asarray(value)
        if array.dtype.kind in "OUS":
            array = array.astype(str).astype("U")
        digest.update(f"array{array.shape}{array.dtype.str}".encode())
        digest.update(np.ascontiguousarray(array).tobytes())


def _digest(*values) -> str:
    digest = hashlib.sha256()
    for value in values:
        _feed(digest, value)
    return digest.hexdigest()


def cast_key(mesh1, mesh2, pose, options: dict) -> str:
    """The key of a cast: the meshes' bytes, the options of :func:`~dea_opt.mesh.cast_springs`
    (the engine as it resolves here), the pose (identity for None), the format and dea-opt's version."""
    from .raycast import _engine

    resolved = {**options, "engine": _engine(options.get("engine", "auto"))}
    return _digest(
        FORMAT, __version__, mesh1, mesh2, resolved, np.eye(4) if pose is None else np.asarray(pose, dtype=float)
    )


# --- entries -----------------------------------------------------------------------------


def _read_entry(path: Path, key: str):
    """The arrays and warnings of an entry, or None when it is missing, unreadable or another key's."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            arrays = {name: data[name] for name in _ARRAYS}
            caught = json.loads(str(data["warnings"]))
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
        return None
    return arrays, caught


def _write_entry(path: Path, key: str, springs, caught: list) -> None:
    from ..files.atomic import write_atomic

    layer = springs.layer
    arrays = {
        "sel": layer.source_face,
        "gap": layer.gap,
        "hit_face": springs.hit_face,
        "hit_point2": layer.target_points,
        "h1": springs.thickness1,
        "h2": springs.thickness2,
        "outcome": springs.outcome,
    }

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as handle:
            np.savez(handle, key=np.array(key), warnings=np.array(json.dumps(caught)), **arrays)

    write_atomic(path, write)


def _remember(key: str, springs) -> None:
    if len(_casts) >= _MEMORY_ENTRIES:
        _casts.pop(next(iter(_casts)))
    _casts[key] = springs


def _replay(caught: list) -> None:
    """The warnings the cast gave when it was computed, given again (a case's row lists them)."""
    import builtins

    for category, message in caught:
        kind = getattr(builtins, category, None)
        if not (isinstance(kind, type) and issubclass(kind, Warning)):
            from .. import errors

            kind = getattr(errors, category, UserWarning)
        warnings.warn(message, kind, stacklevel=3)


def cast(mesh1, mesh2, *, pose=None, **options):
    """:func:`dea_opt.mesh.cast_springs`, through the active cache (directly without one)."""
    from .springs import (
        _cast,
        assemble_cast,
        cast_springs,
        check_pose,
        prepare_cast,
    )

    folder = directory()
    if folder is None:
        return cast_springs(mesh1, mesh2, pose=pose, **options)
    T = check_pose(pose)
    T = np.eye(4) if T is None else T
    key = cast_key(mesh1, mesh2, T, options)
    if key in _casts:
        _STATS["hits_memory"] += 1
        return _casts[key]
    inputs = _digest(mesh1, mesh2, options)
    if inputs not in _prepared:
        _prepared.clear()  # one geometry at a time is what sweeps do; keep memory flat
        _prepared[inputs] = prepare_cast(mesh1, mesh2, **options)
    m1, m2, resolved = _prepared[inputs]
    path = folder / f"{key}.npz"
    from ..files.locks import hold

    with hold(folder / f"{key}.lock"):
        entry = _read_entry(path, key)
        if entry is not None:
            _STATS["hits_disk"] += 1
            arrays, caught = entry
            springs = assemble_cast(
                m1,
                m2,
                T,
                resolved,
                arrays["sel"],
                arrays["gap"],
                arrays["hit_face"],
                arrays["hit_point2"],
                arrays["h1"],
                arrays["h2"],
                arrays["outcome"],
            )
            _replay(caught)
        else:
            _STATS["casts"] += 1
            with warnings.catch_warnings(record=True) as recorded:
                warnings.simplefilter("always")
                springs = _cast(m1, m2, T, resolved)
            caught = [[w.category.__name__, str(w.message)] for w in recorded]
            _write_entry(path, key, springs, caught)
            for w in recorded:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    _remember(key, springs)
    return springs
