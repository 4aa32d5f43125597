"""The scenario's field types: paths that must exist, mesh tables, dof lists, the anatomy table,
method names read from the formulation registry, and the strict base of every section.

:mod:`dea_opt.scenario.schema` builds the sections from them.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, ValidationInfo

from ..kinematics import DOFS

__all__ = ["check_method_name", "method_names"]


def method_names() -> tuple:
    """The methods a scenario names: ``auto`` and every registered formulation
    (:func:`dea_opt.formulations.names`), read when a scenario is checked, so a formulation
    registered after import is accepted."""
    from .. import formulations

    return ("auto", *formulations.names())


def check_method_name(method, what: str = "method", auto: bool = True) -> str:
    """``method`` if it is one of :func:`method_names` (without ``auto`` unless ``auto``);
    an :class:`~dea_opt.errors.InputError` (a ``ValueError``) naming ``what`` otherwise."""
    from ..errors import InputError

    names = method_names() if auto else method_names()[1:]
    if not isinstance(method, str) or method not in names:
        raise InputError(f"{what} must be one of {', '.join(names)}, got {method!r}")
    return method


# --- field types ------------------------------------------------------------------------


def _no_nul(value: str) -> str:
    if "\0" in value:
        raise ValueError(f"a path cannot contain a NUL byte, got {value!r}")
    return value


def _existing_file(value: str, info: ValidationInfo) -> str:
    """Resolve ``value`` against the scenario's folder and insist that the file exists."""
    _no_nul(value)
    base = (info.context or {}).get("base_dir")
    path = Path(value).expanduser()
    if not path.is_absolute() and base is not None:
        path = Path(base) / path
    if not path.is_file():
        raise ValueError(f"file not found: {path}{_nearby(path)}")
    return str(path.resolve())


def _nearby(path: Path) -> str:
    """``; did you mean femur.stl?`` (a file of the same folder with a close name), or where the
    path stops existing, or ""."""
    import difflib

    folder = path.parent
    if not folder.is_dir():
        existing = next((p for p in path.parents if p.is_dir()), None)
        return f" (the folder {folder} does not exist{f'; {existing} does' if existing is not None else ''})"
    try:
        names = sorted(p.name for p in folder.iterdir() if p.is_file())
    except OSError:
        return ""
    close = difflib.get_close_matches(path.name, names, n=1, cutoff=0.6)
    return f"; did you mean {close[0]}?" if close else ""


def _anatomy(value):
    """A table :meth:`dea_opt.anatomy.AnatomicalFrame.from_dict` accepts, kept as the plain table;
    its errors name ``output.anatomy.<key>``."""
    if value is None:
        return None
    from ..anatomy import AnatomicalFrame
    from ..errors import InputError

    try:
        AnatomicalFrame.from_dict(value)
    except InputError as exc:
        message = str(exc)
        if not message.startswith("anatomy"):
            message = f"anatomy: {message}"
        raise ValueError(re.sub(r"(?<![\w.])anatomy(?=[.:\s])", "output.anatomy", message)) from None
    return value


def _dof_list(value):
    # "all" / "none" are accepted as shorthands for the list of every dof / no dof.
    if value == "all":
        return list(DOFS)
    if value == "none":
        return []
    return value


def _mesh_files(value, info: ValidationInfo):
    """One mesh file, or a non-empty table ``{label = file}`` of labelled meshes, each existing."""
    if isinstance(value, str):
        return _existing_file(value, info)
    if not isinstance(value, dict) or not value:
        raise ValueError(
            f'expected a path or a table of labelled paths {{medial = "medial.stl", ...}}, got '
            f"{value!r}" + (" (a number)" if isinstance(value, (int, float)) else "")
        )
    files = {}
    for label, path in value.items():
        if not isinstance(path, str):
            # pydantic turns a ValueError (not a TypeError) into a validation error naming the key
            raise ValueError(f"the mesh labelled {label!r} must be a path (a string), got {path!r}")  # noqa: TRY004
        try:
            files[label] = _existing_file(path, info)
        except ValueError as exc:
            raise ValueError(f"the mesh labelled {label!r}: {exc}") from None
    return files


File = Annotated[str, AfterValidator(_existing_file)]
#: One mesh, or a table of labelled meshes ``{medial = "medial.stl", lateral = "lateral.stl"}``.
_MESH_FILES_SCHEMA = {"anyOf": [{"type": "string"}, {"type": "object", "additionalProperties": {"type": "string"}}]}
MeshFiles = Annotated[Any, AfterValidator(_mesh_files), Field(json_schema_extra=_MESH_FILES_SCHEMA)]
Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Count = Annotated[int, Field(ge=1)]
Dof = Literal["ux", "uy", "uz", "rx", "ry", "rz"]
DofList = Annotated[list[Dof], BeforeValidator(_dof_list)]
#: A method name (:func:`method_names`); the JSON schema lists the names registered when it is made.
Method = Annotated[
    str,
    AfterValidator(lambda name: check_method_name(name, "the method")),
    Field(json_schema_extra=lambda schema: schema.update(enum=list(method_names()))),
]
#: A formulation compared by ``dea-opt compare`` (a method name other than ``auto``).
ComparedMethod = Annotated[
    str,
    AfterValidator(lambda name: check_method_name(name, "a compared method", auto=False)),
    Field(json_schema_extra=lambda schema: schema.update(enum=list(method_names()[1:]))),
]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)  # a NaN or inf is named at its key
