"""Reading scenario files: TOML in, a validated :class:`~dea_opt.scenario.schema.Scenario` out.

Errors name the file, the key path (``law.H``) and, when it can be found, the TOML line;
``--set`` overrides (:func:`parse_set`, :func:`apply_overrides`) are applied before
validation and named as such in the errors.
"""

from __future__ import annotations

import copy
import hashlib
import os
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from ..errors import ScenarioError
from ..laws import LAWS
from .schema import GEOMETRY_KINDS, Scenario

__all__ = ["MAX_DEPTH", "apply_overrides", "load_scenario", "parse_scenario", "parse_set"]

#: Deepest nesting of tables and arrays a scenario may have (a real one needs 3).
MAX_DEPTH = 16


def load_scenario(path, overrides: dict | None = None) -> Scenario:
    """Read and validate a scenario file.

    Parameters
    ----------
    path : str or Path
        The TOML file.
    overrides : dict, optional
        ``{"law.H": 0.45, ...}`` applied to the file's values before validation
        (see :func:`parse_set`).

    Raises
    ------
    ScenarioError
        Naming the file, the key path and (when known) the line.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ScenarioError(f"the scenario must be a file path, got {type(path).__name__}")
    if "\0" in os.fspath(path):
        raise ScenarioError(f"the scenario path contains a NUL byte, which no file system allows: {os.fspath(path)!r}")
    path = Path(path).expanduser()
    if not path.is_file():
        raise ScenarioError(f"scenario file not found: {path}")
    return parse_scenario(
        decode(path.read_bytes(), path), name=str(path), base_dir=path.resolve().parent, overrides=overrides
    )


def decode(data: bytes, name) -> str:
    """The UTF-8 text of a scenario file's bytes (TOML is UTF-8), or a ScenarioError naming the place."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise ScenarioError(
            f"{name} is not UTF-8 text (TOML files are UTF-8): byte {data[exc.start]:#04x} at line "
            f"{line}, column {column}; save the file as UTF-8"
        ) from None


def parse_scenario(
    text: str, *, name: str = "<scenario>", base_dir=None, overrides: dict | None = None, swept=()
) -> Scenario:
    """Validate scenario TOML ``text``; relative paths resolve against ``base_dir``.

    ``swept`` names the override keys a sweep gives several values: where ``solve.kinematics``
    is one, ``solve.max_recasts`` is dropped (with a note) from its small-kinematics cases.
    """
    if not isinstance(text, str):
        raise ScenarioError(f"scenario text must be a str, got {type(text).__name__}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{name} is not valid TOML: {exc}") from None
    except RecursionError:
        raise ScenarioError(
            f"{name} nests tables or arrays too deeply to read (a scenario needs 3 levels, at "
            f"most {MAX_DEPTH} are read)"
        ) from None
    _check_depth(data, name)
    overrides = dict(overrides or {})
    if overrides:
        data = apply_overrides(data, overrides)
        _check_depth(data, f"{name} with the --set values")
    notes = _fit_law_to_kind(data, overrides) + _fit_solve_to_kinematics(data, swept)
    base_dir = Path.cwd() if base_dir is None else Path(base_dir)
    try:
        # [[bodies]]: a whole joint (dea_opt/scenario/joint_schema.py); else the two-body form
        model = _joint_model() if isinstance(data, dict) and "bodies" in data else Scenario
        scenario = model.model_validate(data, context={"base_dir": base_dir})
    except ValidationError as exc:
        raise ScenarioError(_describe_errors(exc, name, text, data, overrides)) from None
    if name != "<scenario>":
        scenario._source = str(Path(base_dir) / Path(name).name)
    scenario._text_sha256 = hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()
    scenario._overrides = overrides
    scenario._notes = notes
    return scenario


def _joint_model():
    from .joint_schema import JointScenario

    return JointScenario


def _check_depth(data, name: str) -> None:
    """A ScenarioError when ``data`` nests deeper than :data:`MAX_DEPTH` (checked without recursion)."""
    stack = [(data, 1, "")]
    while stack:
        node, depth, where = stack.pop()
        if depth > MAX_DEPTH:
            raise ScenarioError(
                f"{name} nests tables or arrays more than {MAX_DEPTH} levels deep (at "
                f"{where or 'the top level'}); a scenario needs 3"
            )
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        for key, value in items:
            if isinstance(value, (dict, list)):
                step = f"{where}[{key}]" if isinstance(key, int) else (f"{where}.{key}" if where else str(key))
                stack.append((value, depth + 1, step))


def _fit_law_to_kind(data: dict, overrides: dict) -> list[str]:
    """Drop the ``[law]`` parameters its kind does not take when the kind or the parameter came
    from ``--set`` (a sweep over law kinds shares one table of parameters); returns the notes.

    A parameter the file itself gives to a kind that does not take it stays an error.
    """
    law = data.get("law")
    if not isinstance(law, dict) or not any(k == "law" or k.startswith("law.") for k in overrides):
        return []
    kind = law.get("kind", "linear")
    if not isinstance(kind, str) or kind not in LAWS:
        return []
    taken = {p.name for p in LAWS[kind].parameters} | {"kind"}
    # Only what another kind takes is dropped: a key no law takes is a misspelling, an error.
    known = {p.name for k in LAWS.values() for p in k.parameters}
    kind_overridden = "law.kind" in overrides or "law" in overrides
    dropped = [k for k in law if k not in taken and k in known and (kind_overridden or f"law.{k}" in overrides)]
    for key in dropped:
        del law[key]
    if not dropped:
        return []
    names = ", ".join(f"law.{k}" for k in dropped)
    return [f"law kind {kind!r} takes no {', '.join(dropped)}: dropped {names} for this case"]


def _fit_solve_to_kinematics(data: dict, swept) -> list[str]:
    """Drop ``[solve] max_recasts`` from the small-kinematics cases of a sweep over
    ``solve.kinematics`` (its cases share one ``[solve]`` table, as those of a sweep over law kinds
    share ``[law]``: :func:`_fit_law_to_kind`); returns the notes.

    Anywhere else (the file, or one ``--set`` value of a run) ``max_recasts`` with small kinematics
    stays an error, naming where each of the two came from.
    """
    solve = data.get("solve")
    if not isinstance(solve, dict) or "solve.kinematics" not in swept or "max_recasts" not in solve:
        return []
    if solve.get("kinematics", "small") != "small":
        return []
    del solve["max_recasts"]
    return ["kinematics 'small' takes no max_recasts: dropped solve.max_recasts for this case"]


def _origin(key: str, loc: tuple, text: str, overrides: dict, missing: bool = False) -> str:
    """Where the value at ``key`` came from: ``from --set``, ``line N``, ``with --set k`` (a table
    some of whose keys came from ``--set``), or "" when unknown."""
    if any(key == k or key.startswith((k + ".", k + "[")) for k in overrides):
        return "from --set"
    line = None if missing else _find_line(text, loc)
    inside = [k for k in overrides if key and k.startswith(key + ".")]
    if inside:  # an error of a whole table, whose keys came from the file and from --set
        return (f"line {line}, " if line else "") + f"with --set {', '.join(inside)}"
    return f"line {line}" if line else ""


def _describe_errors(exc: ValidationError, name: str, text: str, data: dict, overrides: dict) -> str:
    parts = []
    # A misspelt key first: the missing key it was meant to be is its consequence, not its cause.
    for error in sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden"):
        loc = _clean_loc(error["loc"])
        if error["type"] in ("union_tag_invalid", "union_tag_not_found"):
            loc = (*loc, "kind")
        key = _key_path(loc)
        origin = _origin(key, loc, text, overrides, missing=error["type"] == "missing")
        where = f"{key} ({origin})" if origin else (key or "top level")
        message = _message(error, loc, data)
        related = (error.get("ctx") or {}).get("related")
        if related and loc:  # the message names another key of the table: say where that one came from
            other = (*loc[:-1], related)
            other_origin = _origin(_key_path(other), other, text, overrides)
            message += f" ({other_origin})" if other_origin else ""
        parts.append(f"{where}: {message}")
    plural = "s" if len(parts) > 1 else ""
    return f"{name} has {len(parts)} error{plural}: " + "; ".join(parts)


def _clean_loc(loc: tuple) -> tuple:
    # pydantic puts the union tag (e.g. "socket") into the location of [geometry] errors.
    if len(loc) >= 2 and loc[0] == "geometry" and loc[1] in GEOMETRY_KINDS:
        loc = loc[:1] + loc[2:]
    return tuple(p for p in loc if not (isinstance(p, str) and p.startswith(("function-", "literal["))))


def _key_path(loc: tuple) -> str:
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _message(error: Mapping[str, Any], loc: tuple, data: dict) -> str:
    kind = error["type"]
    given = error.get("input")
    law = _law_kind(loc, data)
    if kind == "extra_forbidden" and law is not None:
        if any(p.name == loc[-1] for k in LAWS.values() for p in k.parameters):
            return f"law kind {law.name!r} takes no {loc[-1]} (it takes {_names(law)})"
        others = sorted({p.name for k in LAWS.values() for p in k.parameters} - {p.name for p in law.parameters})
        also = f" (other kinds take {', '.join(others)})" if others else ""
        meant = _did_you_mean(loc[-1], ["kind", *(p.name for p in law.parameters)])
        return f"unknown key {loc[-1]!r}{meant}; law kind {law.name!r} takes kind, {_names(law)}{also}"
    if kind == "extra_forbidden":
        allowed = _allowed_keys(loc[:-1], data)
        hint = f"; allowed here: {', '.join(allowed)}" if allowed else ""
        return f"unknown key {loc[-1]!r}{_did_you_mean(loc[-1], allowed)}{hint}"
    if kind == "missing" and law is not None:
        parameter = law.parameter(loc[-1])
        return f"law kind {law.name!r} needs {loc[-1]}" + (f" ({parameter.describe()})" if parameter else "")
    if kind == "missing":
        return (
            "required table is missing"
            if len(loc) == 1 and loc[0] in Scenario.model_fields
            else "required key is missing"
        )
    if kind == "union_tag_invalid":
        return f"unknown kind {error['ctx']['tag']!r}; expected one of {error['ctx']['expected_tags']}"
    if kind == "union_tag_not_found":
        return f"required key is missing; expected one of {', '.join(repr(k) for k in GEOMETRY_KINDS)}"
    bounds = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}
    if kind in bounds:
        limit = next(iter(error.get("ctx", {}).values()), None)
        shown = f"{limit:g}" if isinstance(limit, (int, float)) else repr(limit)
        return f"must be {bounds[kind]} {shown}, got {_short(given)}"
    message = error["msg"]
    message = message.removeprefix("Value error, ")
    if kind in (
        "float_type",
        "int_type",
        "string_type",
        "bool_type",
        "list_type",
        "dict_type",
        "literal_error",
        "int_from_float",
        "float_parsing",
        "finite_number",
    ):
        message += f", got {_short(given)}" + (" (a string)" if isinstance(given, str) else "")
    return message


def _did_you_mean(key, allowed) -> str:
    """``: did you mean 'free'?`` for the allowed key nearest a misspelt one (case aside), or ""."""
    import difflib

    if not isinstance(key, str):
        return ""
    lower = {name.lower(): name for name in allowed}
    close = difflib.get_close_matches(key.lower(), list(lower), n=1, cutoff=0.6)
    return f": did you mean {lower[close[0]]!r}?" if close else ""


def _law_kind(loc: tuple, data: dict):
    """The registered kind of ``[law]`` when the error ``loc`` is inside it, else None."""
    law = data.get("law") if isinstance(data, dict) else None
    if len(loc) != 2 or loc[0] != "law" or not isinstance(law, dict):
        return None
    kind = law.get("kind", "linear")
    return LAWS[kind] if isinstance(kind, str) and kind in LAWS else None


def _names(kind) -> str:
    return ", ".join(p.name for p in kind.parameters) or "no parameters"


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 50 else text[:47] + "..."


def _allowed_keys(loc: tuple, data: dict) -> list[str]:
    """The keys the table at ``loc`` accepts (for 'unknown key' messages)."""
    model = Scenario
    node = data
    for part in loc:
        if not isinstance(part, str) or model is None:
            return []
        node = node.get(part, {}) if isinstance(node, dict) else {}
        field = model.model_fields.get(part)
        if field is None:
            return []
        model = _section_model(field.annotation, node)
    if model is None:
        return []
    return list(model.model_fields)


def _section_model(annotation, node):
    """The model class behind a field annotation (picking the geometry variant by ``kind``)."""
    from typing import get_args

    candidates = [a for a in _flatten(annotation) if isinstance(a, type) and issubclass(a, BaseModel)]
    if len(candidates) > 1 and isinstance(node, dict):
        for model in candidates:
            kind = model.model_fields.get("kind")
            if kind is not None and node.get("kind") in get_args(kind.annotation):
                return model
        return None
    return candidates[0] if candidates else None


def _flatten(annotation):
    from typing import get_args

    args = get_args(annotation)
    if not args:
        return [annotation]
    return [x for a in args for x in _flatten(a)]


def _find_line(text: str, loc: tuple) -> int | None:
    """The 1-based line of the key ``loc`` in the TOML ``text`` (best effort, else None).

    Falls back to the enclosing key's line (an inline table or a list element).
    """
    keys = [p for p in loc if isinstance(p, str)]
    while keys:
        line = _find_key_line(text, keys)
        if line is not None:
            return line
        keys = keys[:-1]
    return None


def _find_key_line(text: str, keys: list) -> int | None:
    table, key = keys[:-1], keys[-1]
    header = re.compile(r"^\s*\[\s*([A-Za-z0-9_.\s]+?)\s*\]\s*(#.*)?$")
    assignment = re.compile(rf"^\s*{re.escape(key)}\s*=")
    current: list[str] = []
    table_line = None
    for number, line in enumerate(text.splitlines(), start=1):
        match = header.match(line)
        if match:
            current = [p.strip() for p in match.group(1).split(".")]
            if current == keys and table_line is None:
                table_line = number
            continue
        if current == table and assignment.match(line):
            return number
    return table_line


# --- --set overrides --------------------------------------------------------------------


def parse_set(text: str) -> tuple[str, list]:
    """Split ``"law.H=0.3,0.45,0.6"`` into ``("law.H", [0.3, 0.45, 0.6])``.

    Values are read as TOML values (numbers, booleans, ``[1, 2, 3]``, quoted strings);
    anything else is kept as a string. Commas inside brackets or quotes do not split.
    """
    key, sep, values = text.partition("=")
    key = key.strip()
    if not sep or not key or not re.fullmatch(r"[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)*", key):
        raise ScenarioError(f"--set must look like KEY.PATH=VALUE[,VALUE...], e.g. law.H=0.3,0.45, got {text!r}")
    items = _split_values(values)
    if not items or any(item == "" for item in items):
        raise ScenarioError(f"--set {key} has an empty value in {text!r}")
    return key, [_parse_value(item) for item in items]


def _split_values(text: str) -> list[str]:
    items, depth, quote, current = [], 0, None, ""
    for char in text:
        if quote:
            quote = None if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        elif char == "," and depth == 0:
            items.append(current.strip())
            current = ""
            continue
        current += char
    items.append(current.strip())
    return items


def _parse_value(text: str):
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_overrides(data: dict, overrides: dict) -> dict:
    """A deep copy of the TOML ``data`` with ``{"table.key": value}`` set (tables created).

    ``law = "ateshian"`` (a string for the table ``law``) sets ``law.kind``.
    """
    data = copy.deepcopy(data)
    for key, value in overrides.items():
        if key == "law" and isinstance(value, str):
            key = "law.kind"
        node = data
        parts = key.split(".")
        for depth, part in enumerate(parts[:-1]):
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ScenarioError(f"--set {key}: {'.'.join(parts[: depth + 1])} is a value, not a table")
        node[parts[-1]] = value
    return data
