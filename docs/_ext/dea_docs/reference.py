"""Reference pages made from the code at build time, so that they cannot drift.

- ``{dea-cli}``: every command of ``dea-opt`` and its options, from the Typer app itself;
- ``{dea-scenario-keys}``: every table and key of a scenario file, from its pydantic models
  (type, unit, default, allowed values, meaning) and the law registry;
- ``{dea-formulation-options}`` and ``{dea-formulation-capabilities}``: the formulations'
  options and what each can do, from the registry;
- ``{dea-frame-columns}``: the columns of a load path's ``frames.csv`` with their units;
- ``{dea-moduli}``: the table of moduli with their sources (the tutorial *Your own joint*).

Each directive writes reStructuredText and parses it in place; a Markdown page calls it inside
``{eval-rst}``.
"""

from __future__ import annotations

import re
import types
import typing

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

#: Units a description states in parentheses, as the schema writes them.
_UNIT = re.compile(r"\((mm|N|N mm|MPa|degrees|s|mm, rad|N, N mm|rad|1/s)\)")


def _cell(text) -> str:
    """Text for a list-table cell: one line, literal markup kept, no stray roles."""
    return " ".join(str(text).split()) or " "


def _literal(text) -> str:
    text = str(text)
    return f"``{text}``" if text else " "


def _table(header: list[str], rows: list[list[str]], widths: str | None = None) -> list[str]:
    lines = [".. list-table::", "   :header-rows: 1", "   :class: dea-reference-table"]
    if widths:
        lines.append(f"   :widths: {widths}")
    lines.append("")
    for row in [header, *rows]:
        lines.append(f"   * - {_cell(row[0])}")
        lines += [f"     - {_cell(cell)}" for cell in row[1:]]
    return [*lines, ""]


class _Generated(SphinxDirective):
    has_content = False

    def lines(self) -> list[str]:  # pragma: no cover - each directive has its own
        raise NotImplementedError

    def run(self) -> list[nodes.Node]:
        # reStructuredText, sections included: the pages call these directives through
        # ``{eval-rst}`` so that the state parsing them is docutils', not MyST's
        container = nodes.container()
        nested_parse_with_titles(self.state, StringList(self.lines(), source="generated"), container)
        return container.children


# --- the command line ---------------------------------------------------------------------------


def _param_type(param) -> str:
    """The type a command-line value takes (Typer keeps the annotation; click a type object)."""
    descriptor = getattr(param, "type_descriptor", None)
    if descriptor is not None:
        return _type_name(descriptor.annotation)
    return getattr(getattr(param, "type", None), "name", "text")


def _param_row(param) -> list[str]:
    if param.param_type_name == "argument":
        name = _literal(param.name.upper())
        kind = "argument, required" if param.required else "argument"
    else:
        flags = [*param.opts, *param.secondary_opts]
        name = ", ".join(_literal(f) for f in flags)
        kind = "flag" if getattr(param, "is_flag", False) else f"value ({_param_type(param)})"
        if param.required:
            kind += ", required"
        if param.multiple:
            kind += ", repeatable"
    default = param.default
    shown = " " if default is None or param.required else _literal(default)
    return [name, kind, shown, getattr(param, "help", None) or " "]


class CliDirective(_Generated):
    """Every command of ``dea-opt``, its usage, its help and its options."""

    def lines(self) -> list[str]:
        import typer.main

        from dea_opt.cli import app

        group = typer.main.get_command(app)
        out = [_cell(group.help), "", "Options of ``dea-opt`` itself:", ""]
        out += _table(["option", "kind", "default", "meaning"], [_param_row(p) for p in group.params])
        for name, command in group.commands.items():
            out += [f".. _cli-{name}:", "", f"``dea-opt {name}``", "-" * (len(name) + 13), ""]
            arguments = " ".join(p.name.upper() for p in command.params if p.param_type_name == "argument")
            out += ["::", "", f"    dea-opt {name} [OPTIONS] {arguments}".rstrip(), ""]
            for paragraph in (command.help or "").split("\n\n"):
                out += [_cell(paragraph).replace("*", r"\*"), ""]
            params = [p for p in command.params if p.name != "help"]
            if params:
                out += _table(["option", "kind", "default", "meaning"], [_param_row(p) for p in params])
        return out


# --- the scenario file --------------------------------------------------------------------------


def _type_name(annotation) -> str:
    """A short, readable name of a field's type (``number``, ``list of 3 numbers``, ...)."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        return _type_name(args[0])
    if origin is typing.Literal:
        return "one of " + ", ".join(f'"{a}"' if isinstance(a, str) else str(a) for a in args)
    if origin in (typing.Union, types.UnionType):
        names = [_type_name(a) for a in args if a is not type(None)]
        return " or ".join(dict.fromkeys(names))
    if origin in (list, tuple, set, frozenset):
        inner = [a for a in args if a is not Ellipsis]
        if origin is tuple and inner and len(inner) == len(args) and len(set(map(str, inner))) == 1:
            return f"list of {len(inner)} {_type_name(inner[0])}s"
        return "list of " + (_type_name(inner[0]) + "s" if inner else "values")
    if origin is dict:
        return "table" + (f" of {_type_name(args[1])}s" if len(args) == 2 else "")
    names = {float: "number", int: "integer", str: "string", bool: "true or false", dict: "table"}
    if annotation in names:
        return names[annotation]
    name = getattr(annotation, "__name__", str(annotation))
    return {"Path": "path", "PathLike": "path"}.get(name, name)


def _default(field) -> str:
    from pydantic_core import PydanticUndefined

    from dea_opt.scenario.docs import toml_value

    if field.default is PydanticUndefined and field.default_factory is None:
        return "required"
    value = field.default_factory() if field.default_factory is not None else field.default
    return "(none)" if value is None else _literal(toml_value(value))


class ScenarioKeysDirective(_Generated):
    """Every table of a scenario file and every key of each, from the models."""

    def lines(self) -> list[str]:
        from dea_opt.scenario.docs import schema_sections

        out = []
        for table, models in schema_sections():
            out += [f".. _scenario-{table}:", "", f"``[{table}]``", "-" * (len(table) + 6), ""]
            for model in models:
                doc = _cell((model.__doc__ or "").replace("``", "`"))
                kind = model.model_fields.get("kind")
                if len(models) > 1 and kind is not None:
                    (value,) = typing.get_args(kind.annotation)
                    out += [f'``kind = "{value}"``: {doc}', ""]
                else:
                    out += [doc, ""]
                rows = []
                for name, field in model.model_fields.items():
                    if name == "kind" and len(models) > 1:
                        continue
                    description = field.description or ""
                    unit = _UNIT.search(description)
                    choices = schema_choices(model, name)
                    rows.append(
                        [
                            _literal(f"{table}.{name}"),
                            _type_name(field.annotation) + (f": {choices}" if choices else ""),
                            unit.group(1) if unit else " ",
                            _default(field),
                            description.replace("*", r"\*"),
                        ]
                    )
                out += _table(["key", "type and allowed values", "unit", "default", "meaning"], rows, "18 22 8 12 40")
        return out


def schema_choices(model, name: str) -> str:
    """The registered method names for the keys that name methods (as ``dea-opt schema``)."""
    from dea_opt.scenario.docs import method_choices

    return method_choices(model, name)


# --- the formulations' registry and the statuses ------------------------------------------------


class FormulationOptionsDirective(_Generated):
    def lines(self) -> list[str]:
        from dea_opt import formulations

        rows = []
        for name in formulations.names():
            for o in formulations.options(name):
                rows.append(
                    [
                        _literal(name),
                        _literal(o.name),
                        o.kind(),
                        _literal(repr(o.default)),
                        "yes" if o.tolerance else " ",
                        o.doc,
                    ]
                )
        return _table(["method", "option", "takes", "default", "tol", "meaning"], rows, "10 14 16 10 5 45")


class FormulationCapabilitiesDirective(_Generated):
    def lines(self) -> list[str]:
        from dea_opt import formulations

        rows = []
        for name in formulations.names():
            c = formulations.capabilities(name)
            rows.append(
                [
                    _literal(name),
                    str(c.laws),
                    "yes" if c.warm_start else "no",
                    ", ".join(c.kinematics),
                    "yes" if c.duals else "no",
                    "before" if c.checks_load_first else "after a failure",
                ]
            )
        return _table(["method", "laws", "warm start", "kinematics", "spring forces from duals", "cone test"], rows)


class FrameColumnsDirective(_Generated):
    """The columns of a load path's table (``frames.csv``), in order, with units."""

    def lines(self) -> list[str]:
        import numpy as np

        import dea_opt
        from dea_opt.geometry import plate_layer
        from dea_opt.loadpath.table import MOTION_UNITS, REGION_COLUMNS, TABLE_COLUMNS
        from dea_opt.units import SUFFIXES, unit_name
        from dea_opt.validity import assess

        def unit(name: str) -> str:
            return unit_name(name) or "–"

        rows = [[_literal(name), unit(name), what] for name, what in TABLE_COLUMNS.items()]
        for dof, dof_unit in MOTION_UNITS.items():
            column = f"body<b>_{dof}_{SUFFIXES[dof_unit]}"
            rows.append([_literal(column), dof_unit, "the motion found along a free dof (``Solution.u``)"])
        problem = dea_opt.ContactProblem(plate_layer(nx=4, ny=4), dea_opt.LinearLaw(1.0), force=(0, 0, -1.0))
        for check in assess(problem, np.zeros(12)).checks:
            what = f"the value of the validity check {check.name} ({check.unit or 'a strain'})"
            rows.append([_literal(check.column), unit(check.column), what])
            for key, _ in check.details:
                detail = f"{check.column}_{SUFFIXES.get(key, key)}"
                rows.append([_literal(detail), unit(detail), f"the same check in {key}"])
        for name, what in REGION_COLUMNS.items():
            rows.append([_literal(f"<region>_{name}"), unit(name), f"per labelled region: {what}"])
        return _table(["column", "unit", "meaning"], rows, "30 10 60")


class ModuliDirective(_Generated):
    """dea-opt's table of moduli (:data:`dea_opt.laws.moduli.MODULI`): the tutorial's "Which
    modulus", the rows ``dea-opt init --material`` names and the check before solving's range."""

    def lines(self) -> list[str]:
        from dea_opt.laws.moduli import MODULI

        rows = [
            [row.material, row.source, row.gives, f"{row.advice} (``--material {row.key}``: H = {row.H:g} MPa)"]
            for row in MODULI
        ]
        return _table(["joint, material", "source", "what it gives", "``H`` for dea-opt"], rows, "14 38 24 24")


def setup(app) -> None:
    app.add_directive("dea-moduli", ModuliDirective)
    app.add_directive("dea-frame-columns", FrameColumnsDirective)
    app.add_directive("dea-cli", CliDirective)
    app.add_directive("dea-scenario-keys", ScenarioKeysDirective)
    app.add_directive("dea-formulation-options", FormulationOptionsDirective)
    app.add_directive("dea-formulation-capabilities", FormulationCapabilitiesDirective)
