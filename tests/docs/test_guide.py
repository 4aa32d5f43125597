"""Every code block of the user guide (``docs/guide/*.md``) is checked: Python blocks run, page by
page in one namespace and in order, with the answers they compute checked here; TOML blocks
parse; shell blocks name real ``dea-opt`` commands and options. A block that cannot run here (a
SLURM cluster) is compiled and its calls bound to the real signatures."""

from __future__ import annotations

import inspect
import re
import shlex
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import KNEE

import dea_opt as d

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "guide"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
needs_knee = pytest.mark.skipif(not all((KNEE / f).is_file() for f in KNEE_FILES), reason="no knee meshes")
#: The knee's reference point the guide's knee blocks leave as ``(x, y, z)``: the midpoint of the
#: plateaus' centroids (mm), as ``examples/knee_from_meshes.py`` and the tests of the re-cast use.
KNEE_REFERENCE = {"x": -69.0242, "y": -5.9006, "z": -18.8433}


def blocks(page: str, language: str) -> list[str]:
    text = (GUIDE / page).read_text(encoding="utf-8")
    return re.findall(rf"^```{language}\n(.*?)^```", text, re.S | re.M)


def run(page: str, namespace: dict, skip=()) -> dict:
    for i, code in enumerate(blocks(page, "python")):
        if i not in skip:
            exec(compile(code, f"{page} block {i}", "exec"), namespace)  # noqa: S102 - the guide's own example
    return namespace


def short_example(namespace: dict) -> dict:
    """The concepts page's first block: the sphere on a bed every later block may build on."""
    exec(compile(blocks("concepts.md", "python")[0], "concepts.md block 0", "exec"), namespace)  # noqa: S102
    return namespace


def test_every_page_with_python_is_covered_here():
    covered = {
        "concepts.md",
        "laws.md",
        "meshes.md",
        "joint.md",
        "opensim.md",
        "finite.md",
        "sensitivities.md",
        "sweeps.md",
    }
    with_python = {p.name for p in GUIDE.glob("*.md") if blocks(p.name, "python")}
    assert with_python == covered, (
        f"a guide page's Python is not run by tests/docs/test_guide.py: {with_python - covered}"
    )


def test_concepts(capsys):
    namespace = run("concepts.md", {})
    solution, problem = namespace["solution"], namespace["problem"]
    # the sphere's springs push it back along their normals with the 10 N: summed here
    push = solution.pressure * problem.layer.areas * problem.layer.normals[:, 2]
    assert solution.success and abs(float(np.sum(push)) - 10.0) < 1e-8
    assert namespace["loose"].valid and namespace["loose"].limits.peak_pressure == 50.0
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("valid (")


def test_laws(capsys):
    from dea_opt import formulations

    namespace: dict = {}
    try:
        run("laws.md", namespace)
        law = namespace["StiffeningLaw"](k=10.0, c=50.0)
        assert law.stress(np.array([-0.5]))[0] == pytest.approx(-10.0 * 0.5 - 50.0 * 0.125)
        solution = namespace["solution"]
        assert solution.success and solution.method == "bfgs"
        layer = namespace["problem"].layer
        assert abs(float(np.sum(solution.pressure * layer.areas * layer.normals[:, 2])) - 10.0) < 1e-6
    finally:
        d.LAWS.unregister("stiffening")
        if "bfgs" in formulations.names():
            formulations.unregister("bfgs")


@pytest.mark.slow
def test_sensitivities():
    namespace = short_example({})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        run("sensitivities.md", namespace)
    sens = namespace["sens"]
    assert sens.unit("peak_pressure", "H") == "MPa/MPa" and sens.u["Fz"].shape == (12,)


def test_joint(capsys):
    from joint_checks import net_wrench, worst_imbalance

    namespace = run("joint.md", {})
    solution = namespace["solution"]
    assert solution.success and solution.certificate.passed and solution.validity.valid
    assert worst_imbalance(solution) < 1e-9  # forces and moments summed in tests/joint_checks.py
    # the plateaus carry the 800 N and the bundles' pull: their vertical parts, summed here
    pull = sum(
        row["force_N"] * (lig.point2[2] - lig.point1[2]) / np.linalg.norm(np.subtract(lig.point2, lig.point1))
        for row, lig in zip(namespace["rows"], solution.joint.ligaments)
    )
    carried = sum(float(np.sum(c.pressure * c.problem.layer.areas)) for c in solution.contacts)
    assert carried == pytest.approx(800.0 + pull, rel=1e-9) and pull > 0
    assert np.allclose(net_wrench(solution)["femur"][0], 0.0, atol=1e-7)
    assert [r["name"] for r in namespace["rows"]] == ["ACL", "PCL", "MCL", "LCL"]
    assert capsys.readouterr().out.startswith("converged True valid")


TKA = KNEE.parent / "tka"


@pytest.mark.skipif(not (TKA / "DM.osim").is_file(), reason="no TKA model")
def test_opensim_models(capsys, monkeypatch):
    monkeypatch.chdir(ROOT)  # the page reads ../shared/data/tka from the repository's folder
    namespace = run("opensim.md", {})
    model, state, gait = namespace["model"], namespace["state"], namespace["gait"]
    assert model.name == "DM" and len(state.force) == 149 and len(gait) == 101
    assert namespace["law"].H == pytest.approx(0.54 * 46.3 / (1.46 * 0.08), rel=1e-12)  # (1-nu)E/((1+nu)(1-2nu))
    assert namespace["pair"].thickness == 10.0
    assert {"femur_r", "tibia_r", "patella_r"} <= set(namespace["poses"])
    assert capsys.readouterr().out.startswith("145 things of DM.osim that dea-opt does not model")


@needs_knee
def test_meshes_and_finite_on_the_real_knee(tmp_path, monkeypatch):
    for name in KNEE_FILES:
        (tmp_path / name).symlink_to(KNEE / name)
    monkeypatch.chdir(tmp_path)
    namespace = {
        **KNEE_REFERENCE,
        "epicondyle_m": np.array([-30.0, -5.0, 10.0]),
        "epicondyle_l": np.array([-110.0, -5.0, 10.0]),
        "hip_centre": np.array([-69.0, -5.0, 420.0]),
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        run("meshes.md", namespace)
        solution = namespace["solution"]
        assert solution.success and (tmp_path / "knee.png").read_bytes()[:4] == b"\x89PNG"
        layer = solution.problem.layer
        push = solution.pressure[:, None] * layer.areas[:, None] * layer.normals  # N, on the femur
        assert float(np.sum(push[:, 2])) == pytest.approx(1000.0, rel=1e-8)  # uz is free: its balance
        assert namespace["again"].dropped == 0 and solution.validity["dropped_springs"].value == 0
        run("finite.md", namespace)
    finite = namespace["solution"]
    assert finite.success and finite.pose.shape == (4, 4)


def test_the_cluster_block_calls_run_sweep_as_it_is_defined():
    """The SLURM block needs a cluster: it compiles, and its call binds to ``run_sweep``."""
    from dea_opt.sweep import run_sweep

    (code,) = blocks("sweeps.md", "python")
    compile(code, "sweeps.md", "exec")
    call = re.search(r"run_sweep\((.*?)\)\n", code, re.S).group(1)
    args = eval(f"(lambda *a, **k: (a, k))({call})", {"cluster": type("C", (), {"scheduler_address": "tcp://x:1"})})  # noqa: S307
    inspect.signature(run_sweep).bind(*args[0], **args[1])


@pytest.mark.parametrize("page", sorted(p.name for p in GUIDE.glob("*.md")))
def test_toml_blocks_parse(page):
    for code in blocks(page, "toml"):
        assert tomllib.loads(code) is not None


def _commands() -> dict[str, set[str]]:
    import typer.main

    from dea_opt.cli import app

    group = typer.main.get_command(app)
    out = {"": {o for p in group.params for o in (*p.opts, *p.secondary_opts)}}
    for name, command in group.commands.items():
        out[name] = {o for p in command.params for o in (*p.opts, *p.secondary_opts)} | {"--help"}
    return out


@pytest.mark.parametrize("page", sorted(p.name for p in GUIDE.glob("*.md")))
def test_shell_blocks_name_real_commands_and_options(page):
    commands = _commands()
    for code in blocks(page, "bash"):
        for line in code.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            while "dea-opt" in words or ".venv/bin/dea-opt" in words:
                start = next(i for i, w in enumerate(words) if w.endswith("dea-opt"))
                words = words[start + 1 :]
                end = next((i for i, w in enumerate(words) if w in ("&&", "&", ";", "|")), len(words))
                call, words = words[:end], words[end:]
                name = call[0] if call and not call[0].startswith("-") else ""
                assert name in commands, f"{page}: dea-opt {name} is no command"
                for word in call:
                    if word.startswith("--"):
                        assert word.split("=")[0] in commands[name], f"{page}: dea-opt {name} has no option {word}"
