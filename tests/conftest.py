"""Shared fixtures: the reference problems of the core tests, with their closed forms."""

from __future__ import annotations

import os
import textwrap
import warnings
from pathlib import Path

import pytest

import dea_opt as d
from dea_opt import formulations
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer


def docs_unavailable(what: str) -> None:
    """A test that needs the ``docs`` extra (or Chromium) and lacks ``what``: it skips in a plain
    ``[dev]`` install (the README's test command) and fails with ``DEA_OPT_REQUIRE_DOCS=1``, which
    ``.ci/run`` sets, so that CI never passes without them."""
    if os.environ.get("DEA_OPT_REQUIRE_DOCS") == "1":
        pytest.fail(f"{what}, and DEA_OPT_REQUIRE_DOCS=1 asks for the site's tests")
    pytest.skip(what)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """A test process of pytest-xdist leaves without the interpreter's teardown once it is done:
    its reports went to the main process before this last hook, its fixtures are torn down, and
    freeing the modules it imported (SciPy, CasADi, cvxpy, matplotlib, Dask...) took 1.5 to 2.4 s
    that the whole run waited for at its end. The command line does the same once it has
    published (``dea_opt.cli._leave``)."""
    if hasattr(config, "workerinput"):
        import sys

        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)


#: The methods every test is parametrized over.
METHODS = ("newton", "qp", "nlp")
#: Tight options so the three formulations can be compared to 1e-6.
TIGHT = {"newton": {}, "qp": {"tol": 1e-12}, "nlp": {}}

SHARED = Path(__file__).resolve().parents[2] / "shared"
KNEE = SHARED / "data" / "knee"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")


def scenario_text(
    *,
    title=None,
    size=None,
    nx: int = 40,
    ny: int = 4,
    law: str | None = "linear",
    H: float = 10.0,
    free=("uz", "rx", "ry"),
    force: float = -500.0,
    point=None,
    formats=None,
) -> str:
    """The TOML of the plate scenario the tests that run scenarios share (``kind = "plate"``):
    ``title`` first when given, the plate's ``size`` (length, width, mm) when given, ``nx`` x
    ``ny`` springs, a law of kind ``law`` (None: the default kind, unwritten) and modulus ``H``
    (MPa), body 2's ``free`` dofs, the force ``force`` (N) along z at ``point`` (mm) when given,
    and ``[output] formats`` when given. One key a line, in that order (tests count the lines)."""
    lines = [f'title = "{title}"'] if title is not None else []
    lines += ["[geometry]", 'kind = "plate"']
    if size is not None:
        lines += [f"length = {size[0]}", f"width = {size[1]}"]
    lines += [f"nx = {nx}", f"ny = {ny}", "[law]"]
    if law is not None:
        lines.append(f'kind = "{law}"')
    listed = ", ".join(f'"{dof}"' for dof in free)
    lines += [f"H = {H}", "[body2]", f"free = [{listed}]", "[load]", f"force = [0.0, 0.0, {force}]"]
    if point is not None:
        lines.append(f"point = [{point[0]}, {point[1]}, {point[2]}]")
    if formats is not None:
        lines += ["[output]", "formats = [" + ", ".join(f'"{f}"' for f in formats) + "]"]
    return "\n".join(lines) + "\n"


def ball_on_bed(layer, reference, moment, free, force=(0.0, 0.0, 0.0), *, H=10.0, radius=25.0):
    """A rigid ball of ``radius`` (mm) touching the bed ``layer`` at the origin (centre
    ``(0, 0, radius)``, its target a sphere), with finite kinematics: body 2's ``free`` dofs about
    ``reference`` under ``force`` (N) and ``moment`` (N mm), linear law of modulus ``H`` (MPa)."""
    from dea_opt.formulations.finite import Targets

    return d.ContactProblem(
        layer,
        d.LinearLaw(H),
        force=force,
        moment=moment,
        reference=reference,
        free=free,
        kinematics="finite",
        targets=Targets.spheres((0.0, 0.0, radius), radius, n=len(layer)),
    )


#: A scenario of the generated knee meshes solved with finite kinematics.
KNEE_SCENARIO = textwrap.dedent("""
    [geometry]
    kind = "generator"
    function = "knee_meshes"
    [law]
    kind = "linear"
    H = 10.0
    [body2]
    free = ["uz", "ry"]
    [load]
    force = [0, 0, -600.0]
    moment = [0, 1500.0, 0]
    [solve]
    kinematics = "finite"
    [output]
    formats = ["json"]
""")

#: :data:`KNEE_SCENARIO` on a coarse generated knee (a second or two a run): CLI tests of finite runs.
COARSE_KNEE_SCENARIO = KNEE_SCENARIO.replace(
    'function = "knee_meshes"', 'function = "knee_meshes"\nparameters = { n_plateau = 12, step = 6.0 }'
)


#: A coarse hip socket with a free head (the scenario tables before its load and outputs).
COARSE_SOCKET = """\
[geometry]
kind = "socket"
radius = 25.0
thickness = 3.0
coverage = 80.0
gap = 0.1
n_rings = 10
n_sectors = 30
[law]
kind = "linear"
H = 10.0
[body2]
free = ["ux", "uy", "uz"]
"""


def real_knee_scenario(free, moment=(0.0, 0.0, 0.0)) -> str:
    """A scenario of the real knee's meshes (``KNEE``) with finite kinematics: 1000 N along -z and
    ``moment`` (N mm) on the femur, ``free`` its free dofs, json output."""
    return textwrap.dedent(f"""
        [geometry]
        kind = "meshes"
        mesh1 = {{ medial = "{KNEE / "medial_tibial_cartilage.stl"}", lateral = "{KNEE / "lateral_tibial_cartilage.stl"}" }}
        mesh2 = "{KNEE / "femoral_cartilage.stl"}"
        max_gap = 2.0
        [law]
        kind = "linear"
        H = 10.0
        [body2]
        reference = [-69.0242, -5.9006, -18.8433]
        free = {list(free)}
        [load]
        force = [0.0, 0.0, -1000.0]
        moment = {list(map(float, moment))}
        [solve]
        kinematics = "finite"
        [output]
        formats = ["json"]
    """)


_REAL_KNEE: dict = {}


def real_knee() -> dict:
    """The real knee of ``../shared/data/knee`` cast tibia onto femur (labels medial/lateral, max_gap
    2 mm): ``mesh1``, ``mesh2``, ``options``, ``reference`` (the plateaus' mean centroid) and
    ``cast``. Skips the test when the meshes are absent. Read and cast once per test process (the
    cast is a frozen record; each caller gets its own dict of the same objects)."""
    if not all((KNEE / name).is_file() for name in KNEE_FILES):
        pytest.skip(f"the knee meshes are not in {KNEE}")
    if not _REAL_KNEE:
        _REAL_KNEE.update(_read_real_knee())
    return dict(_REAL_KNEE)


def _read_real_knee() -> dict:
    from dea_opt import mesh as M

    femur = M.load_mesh(KNEE / "femoral_cartilage.stl")
    medial = M.load_mesh(KNEE / "medial_tibial_cartilage.stl")
    lateral = M.load_mesh(KNEE / "lateral_tibial_cartilage.stl")
    tibia, labels = M.concatenate_meshes({"medial": medial, "lateral": lateral})
    centre = [(m.area_faces @ m.triangles_center) / m.area for m in (medial, lateral)]
    options = {"labels": labels, "max_gap": 2.0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cast = M.cast_springs(tibia, femur, **options)
    return {
        "mesh1": tibia,
        "mesh2": femur,
        "options": options,
        "reference": 0.5 * (centre[0] + centre[1]),
        "cast": cast,
    }


def applies(method, law) -> bool:
    """Whether ``method`` takes ``law``, as the registry's capabilities say (``auto`` takes any)."""
    return method == "auto" or formulations.takes(method, law)


def method_law_pairs(methods, laws) -> list:
    """``pytest.param(method, law)`` for the pairs the capabilities allow, and only those (no
    run-time skips for pairs that do not apply)."""
    return [
        pytest.param(method, law, id=f"{getattr(law, 'name', type(law).__name__)}-{method}")
        for law in laws
        for method in methods
        if applies(method, law)
    ]


def solve_quietly(problem, method, **options):
    """Solve with the tight options of ``method``, silencing ValidityWarning on purpose."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, method, **{**TIGHT[method], **options})


@pytest.fixture
def finite(tmp_path):
    """:data:`COARSE_KNEE_SCENARIO` (the knee with finite kinematics) as a scenario file."""
    path = tmp_path / "finite.toml"
    path.write_text(COARSE_KNEE_SCENARIO)
    return path


@pytest.fixture(scope="session")
def plate():
    return plate_layer(40.0, 10.0, 400, 10, thickness=2.0)


@pytest.fixture(scope="session")
def socket():
    return socket_layer(radius=25.0, thickness=2.0, coverage=90.0, n_rings=60, n_sectors=120)


@pytest.fixture(scope="session")
def bed():
    return sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=120, n_sectors=64)


def invoke(*args):
    """``dea-opt ARGS`` in this process (Typer's runner), its arguments made strings."""
    from typer.testing import CliRunner

    from dea_opt.cli import app

    return CliRunner().invoke(app, [str(a) for a in args])


def one_paragraph_error(result):
    """The one-paragraph error of a refused command (exit 2, no traceback): its text."""
    assert result.exit_code == 2, (result.stdout, result.stderr)
    text = result.stderr.strip()
    assert text.startswith("dea-opt: error: ")
    assert "\n" not in text and "Traceback" not in text
    return text


@pytest.fixture(autouse=True)
def _pictures_drawn_in_the_test_s_process(request, monkeypatch):
    """A run started in a test's own process draws its load path's pictures there, as a run with
    ``background_pictures=False`` (a sweep's case) does, instead of starting a
    :class:`~dea_opt.run.pictures.PictureWorker`: a second Python process per run, a second of CPU
    to import Matplotlib and warm up, for the same files. The worker itself is tested where it
    is named (tests marked ``picture_worker``, and every command a test runs as a process)."""
    if request.node.get_closest_marker("picture_worker") is not None:
        return
    from dea_opt.run import demo, runner

    original = runner.picture_worker

    def drawn_here(scenario, background=True):
        return original(scenario, False)

    monkeypatch.setattr(runner, "picture_worker", drawn_here)
    monkeypatch.setattr(demo, "picture_worker", drawn_here)
