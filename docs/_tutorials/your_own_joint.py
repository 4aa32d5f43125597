"""
Your own joint
==============

From cartilage meshes of your own to a validated result and a figure: a knee whose tibial
cartilage comes as two labelled files (medial and lateral) and whose femoral cartilage is a
third. On the way, the traps a new user falls into: the units of the meshes, the body-2
reference point, the modulus, where pose rotations are centred, and moving between Python and a
scenario file.

This page is a script (``docs/_tutorials/your_own_joint.py``) that the documentation build runs
and the test suite runs too (``tests/docs/test_tutorial.py``): every number on it was computed when
the page was made. Units: mm, N, MPa.
"""

# %%
# Your files
# ----------
#
# Bring triangle meshes of the articular cartilage (STL, OBJ, PLY, OFF or legacy VTK), one file
# per part you want reported on its own: here ``medial_tibial_cartilage.stl`` and
# ``lateral_tibial_cartilage.stl`` (body 1, held fixed) and ``femoral_cartilage.stl`` (body 2,
# the one the load moves). So that this page runs anywhere, it first writes three such files:
# two 3 mm slabs of tibial cartilage and two 2 mm caps of femoral cartilage, placed about 70 mm
# from the origin as a scanner's coordinates would put them. With your own files, start at the
# next step.

import tempfile
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import trimesh

import dea_opt as dea
from dea_opt.geometry import slab_mesh, spherical_shell_mesh

folder = Path(tempfile.mkdtemp(prefix="your-own-joint-"))
where = np.array([-70.0, -6.0, -19.0])  # the scanner's coordinates of the joint (mm)
parts = {
    "medial_tibial_cartilage": slab_mesh(24.0, 24.0, 3.0, 24, 24, center=(20.0, 0.0)),
    "lateral_tibial_cartilage": slab_mesh(24.0, 24.0, 3.0, 24, 24, center=(-20.0, 0.0)),
    "femoral_cartilage": trimesh.util.concatenate(
        [
            spherical_shell_mesh(r, 2.0, 25.0, center=(x, 0.0, r), axis=(0.0, 0.0, -1.0), step=1.5)
            for x, r in ((20.0, 45.0), (-20.0, 40.0))
        ]
    ),
}
for name, mesh in parts.items():
    mesh.apply_translation(where)
    mesh.export(folder / f"{name}.stl")
print(sorted(p.name for p in folder.iterdir()))

# %%
# Read them, and check their units
# --------------------------------
#
# dea-opt works in millimetres, newtons and megapascals. A mesh file has no units: look at its
# size. Human cartilage layers span 10-100 mm; a plateau 0.06 units wide is in metres. Load such
# a file with ``load_mesh(path, scale=1000)`` (in a scenario: ``[geometry] scale = 1000``).
# In Python a mesh in metres still solves, and every answer's validity report then fails its
# ``extent`` check (the layer's size, 1-1000 mm); ``dea-opt run`` stops such a scenario before
# it solves, naming ``[geometry] scale = 1000`` (:ref:`the check before solving
# <checks-before-solving>`), and ``dea-opt init`` reads the size and writes the scale itself.
#
# Labelled meshes become one mesh 1 whose springs carry their part's label:
# :func:`dea_opt.mesh.concatenate_meshes`.

from dea_opt.mesh import cast_springs, concatenate_meshes, load_mesh

tibia, labels = concatenate_meshes(
    {
        "medial": load_mesh(folder / "medial_tibial_cartilage.stl"),
        "lateral": load_mesh(folder / "lateral_tibial_cartilage.stl"),
    }
)
femur = load_mesh(folder / "femoral_cartilage.stl")
print("tibia spans", tibia.extents.round(1), "mm; femur spans", femur.extents.round(1), "mm")

# %%
# Springs from the meshes
# -----------------------
#
# One spring stands on every face of mesh 1 whose normal ray meets mesh 2 within the proximity
# window (``max_gap`` ahead, ``max_overlap`` behind, within ``max_angle`` of facing). Its
# thickness is measured through both closed cartilage surfaces (pass ``thickness1=`` and
# ``thickness2=`` for open ones, or a bone mesh). :func:`dea_opt.mesh.cast_springs` also keeps
# where each ray met mesh 2, so that the springs can be cast again where the femur ends up.

cast = cast_springs(tibia, femur, labels=labels, max_gap=2.0)
layer = cast.layer
names, counts = np.unique(layer.labels, return_counts=True)
print(
    len(layer),
    "springs:",
    dict(zip(names.tolist(), counts.tolist())),
    f"mean thickness {layer.thickness.mean():.2f} mm",
)

# %%
# The body-2 reference point
# --------------------------
#
# Body 2's rotations are centred on its **reference point**, and its moments are taken about
# it; a force given without a ``point`` acts *at* the reference point. The default is the
# origin of your coordinates, here 70 mm from the joint. With the femur free to sink (``uz``) and
# to tilt in varus-valgus (``ry``), 1000 N straight down through the origin is a load whose
# moment no spring of the knee can balance:

problem = dea.ContactProblem(layer, dea.LinearLaw(10.0), force=(0.0, 0.0, -1000.0), free=("uz", "ry"))
try:
    dea.solve(problem)
except dea.LoadNotSupportedError as error:
    print(type(error).__name__ + ":", error)

# %%
# The message starts with the likely cause: the reference point, ``(0, 0, 0) mm``, lies about 70 mm
# from the centre of the contact, so the 1000 N acting there has a moment about the contact that
# no spring of the knee can balance. Put the reference point at the centre of the joint: the
# springs' area-weighted centroid (in a scenario, ``reference = "contact"`` takes exactly this
# point), or the point where your load acts (the knee's centre of your gait model); give a force
# acting elsewhere with ``dea.Load(force, point=...)``.

centre = (layer.points * layer.areas[:, None]).sum(axis=0) / layer.areas.sum()
problem = dea.ContactProblem(layer, dea.LinearLaw(10.0), force=(0.0, 0.0, -1000.0), reference=centre, free=("uz", "ry"))
print("reference point", centre.round(2), "mm")

# %%
# .. _which-modulus:
#
# Which modulus
# -------------
#
# ``H`` is the spring's stress per unit strain (MPa): the modulus of the cartilage layer in
# confined compression. The paper quotes 0.3-0.6 MPa: that is cartilage's **equilibrium**
# (drained) modulus, the stiffness left after minutes of steady load once the fluid has flowed
# out. Under walking, loads come and go in a fraction of a second, the interstitial fluid carries
# much of the load, and the layer responds at its **instantaneous** modulus, one to two orders of
# magnitude higher: hip and knee DEA use about 5-20 MPa, and every knee example here uses 10.
# With the equilibrium modulus body weight crushes a knee's cartilage:

with warnings.catch_warnings():
    warnings.simplefilter("ignore", dea.ValidityWarning)
    soft = dea.solve(problem.with_law(dea.AteshianLaw(0.45, 0.3)))
print("H = 0.45 MPa:", soft.validity.summary())

# %%
# Values from the literature and the models it publishes. A study gives either a Young's
# modulus ``E`` with a Poisson's ratio ``nu`` (an elastic-foundation model then uses the
# confined modulus ``H = (1 - nu) E / ((1 + nu)(1 - 2 nu))``, as OpenSim-JAM's lumped model of Bei
# & Fregly does) or the spring's modulus itself (then ``H = E``): check which before you copy a
# number. The table is dea-opt's own (:mod:`dea_opt.laws.moduli`): ``dea-opt init --material``
# writes a row's ``H`` with its source into the scenario it makes, and the check before solving
# takes its range as the range of plausible moduli.
#
# .. dea-moduli::
#
# Whatever you choose, the validity report says whether the answer stays inside the model
# (strain below the law's range, 30 % for the linear law), and
# :doc:`/guide/sensitivities` fits ``H`` to a pressure film when you have one.

# %%
# Solve, and read the verdict
# ---------------------------
#
# ``dea.solve`` runs Newton's method and certifies the answer. The certificate says it solves
# the equations; the validity says whether they still describe cartilage there. Two checks are
# evaluated only when asked: the springs the proximity window dropped at the solved pose (a
# fresh cast there, as ``dea-opt run`` does for meshes) and the stability of an equilibrium
# (finite kinematics).

from dea_opt.mesh import recast_at_solution

solution = dea.solve(problem)
again = recast_at_solution(solution, cast)
solution = solution.with_validity(dropped=again.dropped)
print("certificate:", solution.certificate)
print("validity:", solution.validity.summary())
print(f"peak {solution.peak_pressure:.2f} MPa, contact area {solution.contact_area:.0f} mm^2")
for name, region in solution.regions().items():
    print(
        f"  {name}: {region.share:.1%} of the contact force, peak {region.peak_pressure:.2f} MPa, area {region.contact_area:.0f} mm^2"
    )

# %%
# ``valid`` is the verdict to publish: every evaluated check passed. A check that fails names
# its value, its limit and what to do (the guide's :ref:`Validity <validity-verdict>` lists them all).
# The figure: the pressure map in the anatomical frame (x runs medial-lateral with the medial
# plateau at larger x, z from the tibia to the femur, a right knee), seen from above.

anatomy = {"medial": (1.0, 0.0, 0.0), "proximal": (0.0, 0.0, 1.0), "side": "right"}
picture = solution.plot_pressure(folder / "knee.png", anatomy=anatomy)
fig, ax = plt.subplots(figsize=(8, 5))
ax.imshow(plt.imread(picture))
ax.set_axis_off()
fig.tight_layout()

# %%
# Where pose rotations are centred
# --------------------------------
#
# Two kinds of motion turn body 2, about two different points:
#
# - the free (or prescribed) rotations ``rx, ry, rz`` of the answer turn body 2 about its
#   **reference point**;
# - a **pose** of mesh 2 (``pose=`` of ``cast_springs``, ``springs_from_meshes``, or a load
#   path's ``pose_rx..pose_rz`` columns in degrees) is a 4x4 rigid transform applied to mesh 2's
#   coordinates: its rotation turns about the **origin of the mesh file**.
#
# A varus-valgus tilt of 5 degrees (about the y axis) written as a pose about the origin swings
# a femur 70 mm away from the origin through about 6 mm, into the tibia; centred on the joint
# (translation ``t = c - R c``) it tilts the femur in place:

from scipy.spatial.transform import Rotation

R = Rotation.from_euler("y", 5.0, degrees=True).as_matrix()
about_origin = np.eye(4)
about_origin[:3, :3] = R
about_joint = about_origin.copy()
about_joint[:3, 3] = centre - R @ centre
for name, pose in (("about the origin", about_origin), ("about the joint", about_joint)):
    moved = femur.copy()
    moved.apply_transform(pose)
    shift = np.linalg.norm(moved.centroid - femur.centroid)
    try:
        springs = len(cast_springs(tibia, femur, labels=labels, max_gap=2.0, pose=pose).layer)
    except dea.InputError as error:
        springs = f"none ({error})"
    print(f"5 deg {name}: the femur's centroid moves {shift:.2f} mm; springs cast there: {springs}")

# %%
# From a scenario to Python, and back
# -----------------------------------
#
# The same study as a scenario file runs from the command line (``dea-opt run knee.toml``) and
# sweeps, and its pieces are Python objects: :func:`dea_opt.scenario.load_scenario` reads and
# checks a file, :func:`dea_opt.scenario.build_problem` builds its ``ContactProblem``, and
# :func:`dea_opt.run.run_scenario` does what ``dea-opt run`` does. Going back, every argument
# above is a key of the file (:doc:`/reference/scenario` lists them all); the reference point
# is ``reference = "contact"``, the same centroid as above. ``dea-opt init`` writes such a file
# from the meshes alone, every choice a comment (:doc:`/guide/scenarios`):
#
# .. code-block:: bash
#
#    dea-opt init --body1 medial=medial_tibial_cartilage.stl --body1 lateral=lateral_tibial_cartilage.stl \
#        --body2 femoral_cartilage.stl --load 1000 -o knee.toml
#    dea-opt run knee.toml

from dea_opt.run import run_scenario
from dea_opt.scenario import build_problem, load_scenario

(folder / "knee.toml").write_text("""
title = "my knee, 1000 N"

[geometry]
kind = "meshes"
mesh1 = { medial = "medial_tibial_cartilage.stl", lateral = "lateral_tibial_cartilage.stl" }
mesh2 = "femoral_cartilage.stl"
max_gap = 2.0

[law]
kind = "linear"
H = 10.0

[body2]
reference = "contact"
free = ["uz", "ry"]

[load]
force = [0.0, 0.0, -1000.0]

[output]
directory = "knee-out"
anatomy = { medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "right" }
""")
scenario = load_scenario(folder / "knee.toml")
built = build_problem(scenario)
print('reference = "contact":', np.round(built.body2.reference, 2), "mm")
from_file = dea.solve(built)
print(f"from the file: peak {from_file.peak_pressure:.4f} MPa (in Python: {solution.peak_pressure:.4f} MPa)")
outcome = run_scenario(scenario, background_pictures=False)
print(
    f"dea-opt run: {outcome.status.value} (exit code {outcome.exit_code}),",
    sorted(Path(p).name for p in outcome.files.values()),
)

# %%
# ``status`` is the run's verdict, the one ``dea-opt run`` turns into its exit code (0 for
# ``ok``: certified and valid). Next: a gait from an OpenSim file in
# :doc:`/guide/loadpaths`, a sweep of ``H`` on a cluster in :doc:`/guide/sweeps`, and finite
# rotations in :doc:`/guide/finite`.
