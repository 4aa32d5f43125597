"""The documented scenario schema: :func:`schema_text`, commented TOML made from the models of
:mod:`~dea_opt.scenario.schema` and the law registry, so it cannot drift (``dea-opt schema``)."""

from __future__ import annotations

import textwrap
from typing import get_args

from pydantic import BaseModel

from ..laws import LAWS
from .schema import (
    BodySection,
    GeneratorGeometry,
    LoadPathSection,
    LoadSection,
    MeshGeometry,
    OutputSection,
    PlateGeometry,
    RegionsSection,
    SocketGeometry,
    SolveSection,
    SphereOnBedGeometry,
    SpringsGeometry,
    law_model,
    method_names,
)

__all__ = ["method_choices", "schema_sections", "schema_text", "toml_value"]

_SECTIONS: tuple[tuple[str, tuple[type[BaseModel], ...] | None], ...] = (
    (
        "geometry",
        (PlateGeometry, SphereOnBedGeometry, SocketGeometry, MeshGeometry, SpringsGeometry, GeneratorGeometry),
    ),
    ("law", None),  # one model per registered kind, made when the schema is printed
    ("body1", (BodySection,)),
    ("body2", (BodySection,)),
    ("load", (LoadSection,)),
    ("load_path", (LoadPathSection,)),
    ("regions", (RegionsSection,)),
    ("solve", (SolveSection,)),
    ("output", (OutputSection,)),
)


def schema_sections() -> list[tuple[str, tuple[type[BaseModel], ...]]]:
    """Every table of a scenario file with the models of its kinds, in the file's order (the
    ``[law]`` table: one model per kind registered now). The documentation site's scenario
    reference is made from these, as :func:`schema_text` is."""
    return [
        (table, tuple(law_model(kind) for kind in LAWS) if models is None else models) for table, models in _SECTIONS
    ]


#: Units as the schema's descriptions write them, by their name in :data:`dea_opt.units.SUFFIXES`.
_DESCRIBED_UNITS = {"mm": "mm", "N": "N", "N mm": "N mm", "MPa": "MPa", "s": "s", "degrees": "deg", "mm^2": "mm^2"}


def key_unit(key: str) -> str:
    """The unit of a scenario key (``"law.H"`` -> ``"MPa"``, ``"geometry.thickness"`` -> ``"mm"``), as
    its description in the schema states it; ``""`` for a key without one (a count, a factor, a
    name) or one the schema does not know."""
    import re

    table, _, name = key.partition(".")
    for section, models in schema_sections():
        if section != table:
            continue
        for model in models:
            field = model.model_fields.get(name)
            for found in re.findall(r"\(([^()]*)\)", (field.description or "") if field is not None else ""):
                if found.strip() in _DESCRIBED_UNITS:
                    return _DESCRIBED_UNITS[found.strip()]
    return ""


def schema_text() -> str:
    """The scenario schema as commented TOML: every table, key, type, default and meaning."""
    lines = [
        "# dea-opt scenario file (TOML). Units: mm, N, N mm, MPa, s.",
        "# Relative paths resolve against the scenario file's folder. Unknown keys are errors.",
        "# Give exactly one of [load] and [load_path].",
        "",
        'title = ""  # string, optional: a name for reports',
    ]
    for table, models in schema_sections():
        lines.append("")
        lines.append(f"[{table}]")
        if len(models) > 1:
            kinds = " | ".join(_kind(m) for m in models)
            lines.append(f"# Choose one kind ({kinds}); each kind takes the keys listed under it.")
        for model in models:
            doc = " ".join((model.__doc__ or "").replace("``", "").split())
            if len(models) > 1:
                kind = _kind(model)
                lines.append("")
                lines.extend(textwrap.wrap(f"--- {doc}", 96, initial_indent="# ", subsequent_indent="#     "))
                lines.append(f'kind = "{kind}"')
            else:
                lines.extend(textwrap.wrap(doc, 96, initial_indent="# ", subsequent_indent="# "))
            for name, field in model.model_fields.items():
                if name == "kind" and len(models) > 1:
                    continue
                lines.append(_field_line(name, field, method_choices(model, name)))
    return "\n".join(lines + _joint_lines()) + "\n"


def _joint_lines() -> list[str]:
    """The joint form (``[[bodies]]``: :mod:`~dea_opt.scenario.joint_schema`), after the two-body form."""
    from .joint_schema import (
        JointBodySection,
        JointContactSection,
        JointLigamentSection,
        JointLoadPathSection,
        JointScenario,
        JointSolveSection,
    )

    lines = ["", "# ==== A whole joint: a scenario with [[bodies]] instead of [geometry], [law], [body1], [body2] ===="]
    lines.extend(
        textwrap.wrap(" ".join((JointScenario.__doc__ or "").split()), 96, initial_indent="# ", subsequent_indent="# ")
    )
    for table, model in (
        ("[[bodies]]", JointBodySection),
        ("[[contacts]]", JointContactSection),
        ("[[ligaments]]", JointLigamentSection),
        ("[load_path]", JointLoadPathSection),
        ("[solve]", JointSolveSection),
    ):
        lines.append("")
        lines.append(f"# {table}")
        doc = " ".join((model.__doc__ or "").replace("``", "").split())
        lines.extend(textwrap.wrap(doc, 96, initial_indent="# ", subsequent_indent="# "))
        for name, field in model.model_fields.items():
            if model is JointContactSection and name in ("geometry", "law", "regions"):
                lines.append(f"# {name} = {{ ... }}  # a [{name}] table of the two-body form (above)")
                continue
            lines.append("# " + _field_line(name, field))
    return lines


def _kind(model: type[BaseModel]) -> str:
    """The ``kind`` a model of a table with several kinds stands for (its ``Literal``)."""
    return get_args(model.model_fields["kind"].annotation)[0]


def method_choices(model, name: str) -> str:
    """The method names registered now, for the keys that name methods (else "")."""
    if model is SolveSection and name in ("method", "methods"):
        return " | ".join(method_names()[0 if name == "method" else 1 :])
    return ""


def _field_line(name: str, field, choices: str = "") -> str:
    from pydantic_core import PydanticUndefined

    description = (field.description or "") + (f": {choices}" if choices else "")
    if field.default is PydanticUndefined and field.default_factory is None:
        return f"{name} = ...  # required; {description}"
    default = field.default_factory() if field.default_factory is not None else field.default
    if default is None:
        return f"# {name} = ...  # optional; {description}"
    return f"{name} = {toml_value(default)}  # {description}"


def toml_value(value) -> str:
    """``value`` written as TOML (a default of the schema)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    return repr(value)
