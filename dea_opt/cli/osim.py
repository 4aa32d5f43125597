"""``dea-opt import-osim``: an OpenSim model (``.osim``) written as a dea-opt scenario."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from .common import ForceOpt, _reported, app


@app.command("import-osim")
@_reported
def import_osim(
    model: Annotated[Path, typer.Argument(help="The OpenSim model file (.osim).", show_default=False)],
    output: Annotated[
        Path | None,
        typer.Option(
            "--output", "-o", help="The scenario to write (default: <model name>.toml here).", show_default=False
        ),
    ] = None,
    mesh: Annotated[
        list[str] | None,
        typer.Option(
            "--mesh",
            help="NAME=PATH: use PATH (in mm) for the contact mesh NAME, e.g. for meshes renamed or converted "
            "(repeatable).",
            show_default=False,
        ),
    ] = None,
    fixed: Annotated[
        list[str] | None,
        typer.Option(
            "--fixed",
            help="BODY: a body held in place (repeatable); each body jointed to it takes that joint's coordinates "
            "as its dofs (e.g. --fixed tibia_r: the femur moves by knee_r's coordinates).",
            show_default=False,
        ),
    ] = None,
    leave_out: Annotated[
        list[str] | None,
        typer.Option(
            "--leave-out",
            help="BODY: leave this body out, with every contact pair and bundle touching it (repeatable; e.g. "
            "--leave-out patella_r when the motion gives no patellar pose).",
            show_default=False,
        ),
    ] = None,
    force: ForceOpt = False,
):
    """Read an OpenSim model without OpenSim and write it as a scenario of the multi-body joint.

    Writes [[bodies]] (each body's pose at the model's default coordinates), [[contacts]]
    (each Smith2018ArticularContactForce: casting mesh as mesh 1, target as mesh 2, the
    proximity window, thicknesses and JAM's law) and [[ligaments]] (each
    Blankevoort1991Ligament as a straight line between its first and last path point), all in
    ground at the default pose in mm, N, MPa; then every part of the model dea-opt does not
    model (wrap objects with each bundle's straight line, via points, muscles and other
    forces, constraints, joint functions) as comments. Meshes are looked for next to the
    model and in its Geometry/ folder. dea-opt run takes the scenario as written (every body
    held); choose the free dofs and add loads or a [load_path]. An existing file is kept
    unless --force.
    """
    from ..opensim import read_model
    from ..opensim.export import write_scenario

    meshes = {}
    for text in mesh or []:
        name, sep, path = text.partition("=")
        if not sep or not name.strip() or not path.strip():
            raise InputError(f"--mesh takes NAME=PATH (a contact mesh of the model and a file), got {text!r}")
        if not Path(path.strip()).is_file():
            raise InputError(f"--mesh {name.strip()}: the file {path.strip()} does not exist")
        meshes[name.strip()] = path.strip()
    target = output if output is not None else Path.cwd() / f"{model.stem}.toml"
    if target.exists() and not force:
        raise InputError(f"{target} exists: choose another file with -o, or pass --force to replace it")
    if target.is_dir():
        raise InputError(f"{target} is a directory: -o names the scenario file to write")
    read = read_model(model)
    written = write_scenario(read, target, meshes, tuple(fixed or ()), tuple(leave_out or ()))
    summary = read.summary()
    typer.echo(
        f"read {model}: {summary['bodies']} bodies, {summary['joints']} joints, {summary['contact_pairs']} contact "
        f"pair(s), {summary['ligaments']} ligament bundle(s)"
    )
    kinds = ", ".join(f"{count} {kind}" for kind, count in summary["not_modelled"].items())
    typer.echo(f"not modelled ({len(read.not_modelled)}, listed at the end of the scenario): {kinds or 'nothing'}")
    left = set(leave_out or ())
    missing = [
        m.name
        for m in read.contact_meshes.values()
        if m.resolved is None and m.name not in meshes and m.body not in left
    ]
    if missing:
        typer.echo(
            f"dea-opt: warning: contact mesh file(s) not found for {', '.join(missing)} (see the scenario's "
            f"comments; --mesh NAME=PATH gives a file)",
            err=True,
        )
    typer.echo(f"wrote {written}")
