"""What a mesh file holds, told from its first bytes, so that a bad file gets a plain error.

Before a reader parses a file, :func:`check_content` compares what the file's bytes look like
(ASCII or binary STL, OBJ, PLY, OFF, legacy VTK, VTK XML, other text or binary data) with
what its extension promises; a mismatch or unreadable content is an
:class:`~dea_opt.errors.InputError` naming the file, the format expected and what was found
(a garbage ``.stl`` used to surface as a parser's ``No module named 'charset_normalizer'``).
"""

from __future__ import annotations

import struct
from pathlib import Path

from ..errors import InputError

__all__ = ["EXPECTED", "check_content", "check_path", "sniff"]

#: What each extension's file must hold, as told in error messages.
EXPECTED = {
    ".stl": "an STL surface (ASCII text starting with 'solid' and holding 'facet' records, or a binary "
    "STL of 84 + 50 n bytes for its n triangles)",
    ".obj": "an OBJ surface (text with 'v x y z' vertex and 'f i j k' face lines)",
    ".ply": "a PLY surface (a header starting with the line 'ply')",
    ".off": "an OFF surface (text starting with 'OFF')",
    ".vtk": "a legacy VTK file (first line '# vtk DataFile Version x.x')",
    ".vtp": "a VTK XML PolyData file (text starting with '<?xml' or '<VTKFile')",
}
#: The content kinds :func:`sniff` tells apart: description and the extension they belong to.
KINDS = {
    "stl-binary": ("a binary STL", ".stl"),
    "stl-ascii": ("ASCII STL text (it starts with 'solid')", ".stl"),
    "obj": ("OBJ text ('v' and 'f' lines)", ".obj"),
    "ply": ("a PLY file (it starts with 'ply')", ".ply"),
    "off": ("OFF text (it starts with 'OFF')", ".off"),
    "vtk": ("a legacy VTK file", ".vtk"),
    "vtk-xml": ("a VTK XML file", ".vtp"),
}
_OBJ_KEYS = {"v", "vn", "vt", "vp", "f", "l", "o", "g", "s", "mtllib", "usemtl"}
_HEAD = 4096


def check_path(path) -> Path:
    """``path`` as a Path to an existing regular file, or an InputError saying what it is."""
    if isinstance(path, bytes):
        raise InputError(f"mesh file path must be a str or path-like, got bytes {path[:60]!r}")
    try:
        path = Path(path)
    except TypeError:
        raise InputError(f"mesh file path must be a str or path-like, got {type(path).__name__}") from None
    suffix = path.suffix.lower()
    expected = EXPECTED.get(suffix, "a triangle surface")
    if "\0" in str(path):
        raise InputError(
            f"mesh file path {str(path)!r} contains a NUL byte, which no file name can hold; "
            f"expected the path of {expected}"
        )
    try:
        if path.is_dir():
            raise InputError(f"mesh file {path} is a directory, not a file; expected {expected}")
        size = path.stat().st_size
    except FileNotFoundError:
        raise InputError(f"mesh file {path} does not exist (expected a {suffix or 'mesh'} triangle surface)") from None
    except OSError as exc:
        raise InputError(f"mesh file {path} could not be opened ({exc.strerror or exc}); expected {expected}") from None
    if not path.is_file():
        raise InputError(f"mesh file {path} is not a regular file (a device, socket or pipe?); expected {expected}")
    if size == 0:
        raise InputError(f"mesh file {path} is empty (0 bytes); expected a {suffix} triangle surface")
    return path


def sniff(path: Path, suffix: str = "") -> tuple[str, str]:
    """``(kind, detail)``: what the file holds (a key of :data:`KINDS`, ``"text"`` or
    ``"binary"``) and, for the last two, what it looks like."""
    size = path.stat().st_size
    with open(path, "rb") as stream:
        head = stream.read(_HEAD)
    if size >= 84:
        (count,) = struct.unpack("<I", head[80:84])
        if size == 84 + 50 * count:
            return "stl-binary", ""
    start = head.lstrip()
    for prefix, kind in ((b"# vtk DataFile", "vtk"), (b"<?xml", "vtk-xml"), (b"<VTKFile", "vtk-xml"), (b"ply", "ply")):
        if start.startswith(prefix):  # text headers of formats whose data may be binary
            return kind, ""
    text = _as_text(head)
    if text is None:
        detail = f"binary data ({size} bytes"
        if size >= 84 and suffix == ".stl":
            (count,) = struct.unpack("<I", head[80:84])
            detail += (
                f"; read as a binary STL, its header declares {count} triangles, which take "
                f"{84 + 50 * count} bytes: truncated, or not an STL"
            )
        return "binary", detail + ")"
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    content = [line for line in lines if not line.startswith("#")]  # comments do not say the format
    key = content[0].split()[0] if content else ""
    if key.upper() in {"OFF", "COFF", "NOFF", "CNOFF", "STOFF", "4OFF"}:
        return "off", ""
    if key.lower() == "solid":
        return "stl-ascii", ""
    words = [line.split()[0].lower() for line in content]
    if "v" in words and all(word in _OBJ_KEYS for word in words[:5]):
        return "obj", ""
    if not lines:
        return "text", "only blank lines"
    first = lines[0] if len(lines[0]) <= 60 else lines[0][:57] + "..."
    return "text", f"text whose first line is {first!r}"


def _as_text(head: bytes) -> str | None:
    """The head decoded as text, or None for binary data (NUL or other control bytes)."""
    if b"\0" in head:
        return None
    control = sum(1 for b in head if b < 32 and b not in (9, 10, 12, 13))
    if control > 0.01 * len(head):
        return None
    try:
        return head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start >= len(head) - 4:  # a character cut by the end of the head
            return head[: exc.start].decode("utf-8")
        return head.decode("latin-1") if control == 0 else None


def check_content(path: Path) -> str:
    """The kind of ``path``'s content when it matches its extension, else an InputError."""
    suffix = path.suffix.lower()
    kind, detail = sniff(path, suffix)
    if kind in KINDS:
        found, belongs = KINDS[kind]
        if belongs == suffix or (kind == "vtk-xml" and suffix == ".vtp"):
            return kind
        raise InputError(
            f"mesh file {path} holds {found}, but its extension {path.suffix} says it is "
            f"{EXPECTED[suffix]}: rename it to {belongs}"
        )
    raise InputError(f"mesh file {path} is not {EXPECTED[suffix]}: it holds {detail}")
