"""The anatomical frame: directions by the ISB convention, landmarks, and maps that are never mirrored."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dea_opt as d
from dea_opt import io
from dea_opt.anatomy import AnatomicalFrame
from dea_opt.anatomy.regions import label_by_axis
from dea_opt.geometry import plate_layer
from dea_opt.io.mapframe import map_frame

X, Y, Z = np.eye(3)


def random_rotation(rng):
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


@pytest.mark.parametrize("side", ["right", "left"])
def test_two_directions_and_the_side_give_the_third_by_the_isb_convention(side):
    rng = np.random.default_rng(5)
    for _ in range(20):
        R = random_rotation(rng)
        anterior, proximal, right = R[:, 0], R[:, 1], R[:, 2]  # ISB: X anterior, Y proximal, Z right
        medial = -right if side == "right" else right
        for given in (
            {"medial": medial, "proximal": proximal},
            {"medial": medial, "anterior": anterior},
            {"anterior": anterior, "proximal": proximal},
        ):
            frame = AnatomicalFrame.from_directions(**given, side=side)
            np.testing.assert_allclose(frame.medial, medial, atol=1e-12)
            np.testing.assert_allclose(frame.anterior, anterior, atol=1e-12)
            np.testing.assert_allclose(frame.proximal, proximal, atol=1e-12)
            assert frame.side == side
            # anterior x proximal is the subject's right
            np.testing.assert_allclose(np.cross(frame.anterior, frame.proximal), right, atol=1e-12)


def test_two_directions_off_perpendicular_keep_proximal():
    tilted = np.array([1.0, 0.0, 0.12])  # 6.8 degrees off the plateau, as real landmarks are
    frame = AnatomicalFrame.from_directions(medial=tilted, proximal=Z, side="right")
    np.testing.assert_array_equal(frame.proximal, Z)
    np.testing.assert_allclose(frame.medial, X, atol=1e-15)
    with pytest.raises(d.InputError, match="far from parallel"):
        AnatomicalFrame.from_directions(medial=(0.1, 0, 1), proximal=Z, side="right")


def test_landmarks():
    # a right knee in a frame of its own: epicondyles on x, the hip 400 mm up
    medial_epicondyle, lateral_epicondyle = np.array([45.0, 3.0, 2.0]), np.array([-35.0, 3.0, 2.0])
    hip = np.array([10.0, 20.0, 410.0])
    frame = AnatomicalFrame.from_landmarks(
        {"medial": medial_epicondyle, "lateral": lateral_epicondyle, "proximal": hip}, side="right", origin="midpoint"
    )
    np.testing.assert_allclose(frame.medial, X, atol=1e-15)  # the pair's axis is kept exactly
    up = hip - 0.5 * (medial_epicondyle + lateral_epicondyle)
    up -= (up @ X) * X
    np.testing.assert_allclose(frame.proximal, up / np.linalg.norm(up), atol=1e-15)
    np.testing.assert_allclose(frame.anterior, np.cross(frame.medial, frame.proximal), atol=1e-15)
    np.testing.assert_array_equal(frame.origin, [5.0, 3.0, 2.0])
    assert frame.origin_name == "medial-lateral midpoint"
    # the distal end named instead of the proximal one gives the same frame
    other = AnatomicalFrame.from_landmarks(
        {"lateral": lateral_epicondyle, "medial": medial_epicondyle, "distal": 2 * np.array([5.0, 3.0, 2.0]) - hip},
        side="right",
    )
    np.testing.assert_allclose(other.proximal, frame.proximal, atol=1e-12)


@pytest.mark.parametrize(
    "spec, match",
    [
        ({"medial": X}, "two of medial, anterior and proximal"),
        ({"medial": X, "proximal": Z}, "side"),
        ({"medial": X, "proximal": Z, "side": "up"}, "side must be 'right' or 'left'"),
        ({"medial": X, "proximal": Z, "side": "right", "colour": 1}, "unknown key colour"),
        ({"medial": X, "anterior": X + Z, "proximal": Z, "side": "right"}, "must be perpendicular"),
        ({"medial": X, "anterior": -Y, "proximal": Z, "side": "left"}, "make a right limb"),
        ({"medial": (0, 0, 0), "proximal": Z, "side": "right"}, "nonzero direction"),
        ({"medial": X, "proximal": Z, "side": "right", "origin": "knee"}, "origin must be 'centroid'"),
        ({"landmarks": {"medial": X, "lateral": -X}, "side": "right"}, "three named points"),
        ({"landmarks": {"medial": X, "lateral": -X, "elbow": Z}, "side": "right"}, "not a direction"),
        ({"landmarks": {"medial": X, "anterior": Y, "proximal": Z}, "side": "right"}, "one pair of opposite"),
        ({"landmarks": {"medial": X, "lateral": -X, "proximal": Z}, "medial": X}, "not both"),
    ],
)
def test_bad_frames_are_named_errors(spec, match):
    with pytest.raises(d.InputError, match=match):
        AnatomicalFrame.from_dict(spec)


def tibial_plateau(side):
    """Two compartments on a plate, proximal +z; the medial one at -x for a right knee."""
    layer = plate_layer(60.0, 30.0, 30, 15, thickness=3.0)
    medial = (-1.0, 0.0, 0.0) if side == "right" else (1.0, 0.0, 0.0)
    anatomy = {"medial": medial, "proximal": (0.0, 0.0, 1.0), "side": side}
    return dataclasses.replace(layer, labels=label_by_axis(layer, "medial", anatomy=anatomy)), anatomy


@pytest.mark.parametrize("side", ["right", "left"])
def test_maps_are_anatomical_views_never_mirrored(side):
    layer, anatomy = tibial_plateau(side)
    frame = map_frame(layer.points, layer.areas, layer.normals, anatomy)
    assert np.isclose(np.linalg.det(frame.axes), 1.0)  # right, up, toward the viewer: right-handed
    np.testing.assert_allclose(frame.axes[2], (0, 0, 1))  # seen from proximal, body 2's side
    assert "superior view" in frame.note and side in frame.note
    # Looking down on a right knee with anterior up, its medial side is on the left.
    medial_x = frame.project(layer.points[layer.labels == "medial"])[:, 0]
    assert (medial_x < 0).all() if side == "right" else (medial_x > 0).all()
    expected = ("Medial", "Lateral") if side == "right" else ("Lateral", "Medial")
    assert (frame.sides["left"], frame.sides["right"]) == expected
    assert (frame.sides["top"], frame.sides["bottom"]) == ("Anterior", "Posterior")
    assert frame.ylabel == "anterior (mm)"
    np.testing.assert_allclose(frame.origin, layer.areas @ layer.points / layer.areas.sum())


def test_without_anatomy_the_axes_are_named_not_printed_as_vectors():
    rng = np.random.default_rng(2)
    for tilt in (0.0, 0.07, 0.5):
        points = rng.uniform(-10, 10, (300, 3)) * (1, 1, 0)
        points[:, 2] = tilt * points[:, 0]
        frame = map_frame(points, normals=np.tile((0, 0, 1.0), (300, 1)))
        for label in (frame.xlabel, frame.ylabel):
            assert "(" not in label.replace("(mm)", "") and label.endswith("(mm)")
        assert "no anatomical frame" in frame.note and not frame.sides
    assert map_frame(points * (1, 1, 0)).xlabel == "x (mm)"


def test_summary_gives_centres_of_pressure_in_the_anatomical_frame(tmp_path):
    layer, anatomy = tibial_plateau("right")
    problem = d.ContactProblem(
        layer, d.LinearLaw(10.0), force=(0, 0, -900), moment=(-1500, 3000, 0), free=("uz", "rx", "ry")
    )
    solution = d.solve(problem, "newton")
    summary = io.summary_dict(solution, anatomy=anatomy)
    origin = layer.areas @ layer.points / layer.areas.sum()
    cop = solution.center_of_pressure - origin
    assert abs(cop[1]) > 0.5  # the moment about x moves it off the axis
    assert summary["center_of_pressure_anatomical"] == pytest.approx(
        {"medial_mm": -cop[0], "anterior_mm": cop[1], "proximal_mm": cop[2]}, abs=1e-12
    )
    for name in ("medial", "lateral"):
        mask = layer.labels == name
        weight = solution.pressure[mask] * layer.areas[mask]
        region_cop = weight @ layer.points[mask] / weight.sum() - origin
        assert summary["regions"][name]["center_of_pressure_anatomical"]["medial_mm"] == pytest.approx(-region_cop[0])
    paths = io.write_results(solution, tmp_path, anatomy=anatomy)
    assert paths["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert io.read_json(paths["json"])["anatomy"]["side"] == "right"


def test_the_guide_examples_of_compartments_and_the_anatomical_frame_run(tmp_path, monkeypatch):
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[2] / "docs" / "guide" / "meshes.md").read_text()
    blocks = [
        re.search(r"```python\n(.*?)```", page.split(title, 1)[1], re.DOTALL).group(1)
        for title in ("## Compartments", "## The anatomical frame")
    ]
    layer = plate_layer(60.0, 30.0, 30, 15, thickness=3.0)
    namespace = {
        "layer": layer,
        "epicondyle_m": np.array([40.0, 0.0, 10.0]),
        "epicondyle_l": np.array([-40.0, 0.0, 10.0]),
        "hip_centre": np.array([0.0, 10.0, 420.0]),
    }
    exec(compile(blocks[0], "meshes.md", "exec"), namespace)
    labelled = namespace["layer"]
    np.testing.assert_array_equal(labelled.labels, np.where(layer.points[:, 0] < 0, "lateral", "medial"))
    problem = d.ContactProblem(labelled, d.LinearLaw(10.0), force=(0, 0, -900), free=("uz",))
    namespace["solution"] = d.solve(problem, "newton")
    monkeypatch.chdir(tmp_path)
    exec(compile(blocks[1], "meshes.md", "exec"), namespace)
    assert (tmp_path / "knee.png").read_bytes()[:4] == b"\x89PNG"
