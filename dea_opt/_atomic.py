"""Text files written atomically, through :func:`dea_opt.io.write_atomic` (temporary file, fsync,
``os.replace``): an interrupted run leaves the old file or the new one, never half of one."""

from __future__ import annotations

from pathlib import Path

from .io import write_atomic


def write_text_atomic(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; missing folders are created."""
    return write_atomic(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
