"""``dea-opt init``: a commented scenario written from cartilage meshes (:mod:`dea_opt.run.init`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..laws.moduli import DEFAULT_MATERIAL, MODULI
from .common import QuietOpt, _reported, app


def _points(values, option: str) -> dict | None:
    """``["medial=1,2,3", ...]`` -> ``{"medial": [1.0, 2.0, 3.0], ...}``."""
    from ..errors import InputError

    if not values:
        return None
    points = {}
    for text in values:
        name, sep, numbers = text.partition("=")
        try:
            point = [float(v) for v in numbers.split(",")]
        except ValueError:
            point = []
        if not sep or not name.strip() or len(point) != 3:
            raise InputError(f"{option} must look like NAME=X,Y,Z (e.g. medial=-40.5,2.1,18.0), got {text!r}")
        points[name.strip()] = point
    return points


@app.command()
@_reported
def init(
    body1: Annotated[
        list[str],
        typer.Option(
            "--body1",
            help="Mesh file of body 1 (held fixed; it carries the springs), or LABEL=FILE once per labelled file "
            "(the labels become compartments, e.g. --body1 medial=med.stl --body1 lateral=lat.stl).",
            show_default=False,
        ),
    ],
    body2: Annotated[
        list[str],
        typer.Option(
            "--body2", help="Mesh file of body 2 (the one loaded), or LABEL=FILE per file.", show_default=False
        ),
    ],
    load: Annotated[
        str,
        typer.Option(
            "--load",
            help="A force in N pressing body 2 onto body 1 along the contact's normal, or a load file for a path: "
            "a CSV (time,Fx,Fy,Fz[,Mx,My,Mz], N and N mm) or an OpenSim .sto/.mot (its columns, sign and units "
            "sniffed).",
            show_default=False,
        ),
    ],
    output: Annotated[
        Path, typer.Option("--output", "-o", help="The scenario file to write (.toml).", show_default=False)
    ],
    scale: Annotated[
        float | None,
        typer.Option(
            help="The meshes' factor to mm (1000 for metres); default: sniffed from their size.", show_default=False
        ),
    ] = None,
    material: Annotated[
        str | None,
        typer.Option(
            help="A row of dea-opt's table of moduli for H (the tutorial's 'Which modulus'): "
            + ", ".join(f"{row.key} ({row.H:g} MPa)" for row in MODULI)
            + f"; default {DEFAULT_MATERIAL}.",
            show_default=False,
        ),
    ] = None,
    modulus: Annotated[
        float | None, typer.Option(help="H in MPa, instead of the table's.", show_default=False, min=0.0)
    ] = None,
    landmark: Annotated[
        list[str] | None,
        typer.Option(
            "--landmark",
            help="NAME=X,Y,Z: three landmarks of the anatomical frame in the mesh files' coordinates, named by "
            "the direction they mark (medial, lateral, proximal, ...); with --side.",
            show_default=False,
        ),
    ] = None,
    axis: Annotated[
        list[str] | None,
        typer.Option(
            "--axis",
            help="NAME=X,Y,Z: two or three directions of the anatomical frame (medial, anterior, proximal); "
            "with --side.",
            show_default=False,
        ),
    ] = None,
    side: Annotated[str | None, typer.Option(help="right or left (the limb).", show_default=False)] = None,
    max_gap: Annotated[
        float | None,
        typer.Option(help="The proximity window's largest gap (mm; default 2).", show_default=False, min=0.0),
    ] = None,
    title: Annotated[str | None, typer.Option(help="The scenario's title.", show_default=False)] = None,
    sto_prefix: Annotated[
        str | None,
        typer.Option(help="A .sto with several joints' columns: the prefix of the one to read.", show_default=False),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace the scenario file if it exists.")] = False,
    quiet: QuietOpt = False,
):
    """Write a commented scenario from cartilage meshes that runs as it stands (dea-opt run FILE).

    Reads the meshes, sniffs their units (or stops, saying why: --scale), casts the springs,
    puts the reference point at the contact's centre (reference = "contact"), frees the dofs
    the springs resist, points the load to press body 2 onto body 1 (a load file: its sign,
    columns and units checked), takes H with its source from dea-opt's table of moduli, and
    names the compartments, the anatomical frame and the outputs. Every choice is a comment in
    the file. Exit 0 written, 2 bad input.
    """
    from ..progress import showing
    from ..run.init import init_scenario, parse_part

    with showing(not quiet):
        result = init_scenario(
            parse_part(body1, "--body1"),
            parse_part(body2, "--body2"),
            load,
            output,
            scale=scale,
            material=material,
            modulus=modulus,
            landmarks=_points(landmark, "--landmark"),
            axes=_points(axis, "--axis"),
            side=side,
            max_gap=max_gap,
            title=title,
            sto_prefix=sto_prefix,
            force=force,
        )
    for line in result.suspicions:
        typer.echo(f"dea-opt: warning: suspicious input: {line}", err=True)
    typer.echo(f"wrote {result.path}:")
    for note in result.notes:
        typer.echo(f"  {note}")
    typer.echo(f"run it: dea-opt run {result.path}")
