"""Regional statistics: labels, half-spaces and axis splits add up to the whole contact; a region's
force is the resultant of its springs (its share: that resultant along the contact force), and the
sum of their force magnitudes is kept under that name, never as a force."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dea_opt as d
from dea_opt.anatomy.regions import RegionStats, region_statistics, regional_statistics, split_by_axis
from dea_opt.errors import InputError
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer


@pytest.fixture(scope="module")
def tilted():
    """A sphere on a bed pushed off-centre by a moment: the load is uneven in x."""
    layer = sphere_on_bed_layer(n_rings=24, n_sectors=32)
    labels = np.where(layer.points[:, 0] < -2.0, "medial", np.where(layer.points[:, 0] < 2.0, "centre", "lateral"))
    layer = dataclasses.replace(layer, labels=labels)
    problem = d.ContactProblem(
        layer, d.LinearLaw(10.0), force=(0, 0, -30), moment=(0, 20, 0), reference=(0, 0, 25), free=("uz", "ry")
    )
    solution = d.solve(problem, "newton")
    assert 0 < solution.in_contact.sum() < len(layer)
    return solution


@pytest.fixture(scope="module")
def plate():
    """A bonded plate with integer labels (left half 1, right half 2)."""
    layer = plate_layer(nx=40, ny=4)
    layer = dataclasses.replace(layer, labels=np.where(layer.points[:, 0] < 0, 1, 2))
    problem = d.ContactProblem(layer, d.LinearLaw(10.0), force=(0, 0, -400), moment=(0, 1000, 0), free=("uz", "ry"))
    return d.solve(problem, "newton")


def brute_force(solution, mask):
    """The region's numbers summed here, spring by spring."""
    layer = solution.problem.layer
    p, a, n = solution.pressure[mask], layer.areas[mask], layer.normals[mask]
    vector = np.zeros(3)
    for pressure, area, normal in zip(p, a, n):
        vector += pressure * area * normal  # the force of one spring on body 2
    everything = np.zeros(3)
    for pressure, area, normal in zip(solution.pressure, layer.areas, layer.normals):
        everything += pressure * area * normal
    magnitudes = float(p @ a)
    contact = solution.in_contact[mask]
    return {
        "force_vector": vector,
        "resultant": np.sqrt(vector @ vector),
        "share": (vector @ everything) / (everything @ everything),
        "force_magnitude_sum": magnitudes,
        "peak_pressure": p.max(initial=0.0),
        "contact_area": a[contact].sum(),
        "mean_pressure": magnitudes / a[contact].sum(),
        "center_of_pressure": (p * a) @ layer.points[mask] / magnitudes,
        "area": a.sum(),
        "n_springs": int(mask.sum()),
    }


def assert_partition(stats, solution):
    layer = solution.problem.layer
    magnitudes = float(solution.pressure @ layer.areas)
    assert sum(s.force_magnitude_sum for s in stats.values()) == pytest.approx(magnitudes, rel=1e-12)
    assert sum(s.share for s in stats.values()) == pytest.approx(1.0, rel=1e-12)
    assert sum(s.n_springs for s in stats.values()) == len(layer)
    assert sum(s.contact_area for s in stats.values()) == pytest.approx(solution.contact_area, rel=1e-12)
    resultant = sum(s.force_vector for s in stats.values())
    np.testing.assert_allclose(resultant, solution.contact_force, rtol=1e-12, atol=1e-12)
    weighted = sum(s.force_magnitude_sum * s.center_of_pressure for s in stats.values() if s.force_magnitude_sum > 0)
    np.testing.assert_allclose(weighted / magnitudes, solution.center_of_pressure, rtol=1e-10, atol=1e-12)


def test_label_regions(tilted):
    stats = regional_statistics(tilted)
    assert list(stats) == ["centre", "lateral", "medial"]
    assert_partition(stats, tilted)
    labels = tilted.problem.layer.labels
    for name, region in stats.items():
        assert isinstance(region, RegionStats) and region.name == name
        want = brute_force(tilted, labels == name)
        for key, value in want.items():
            np.testing.assert_allclose(getattr(region, key), value, rtol=1e-12, err_msg=f"{name}.{key}")
    assert stats["lateral"].share > stats["medial"].share  # the moment pushes toward +x
    via_method = tilted.regions()
    assert {k: v.share for k, v in via_method.items()} == {k: v.share for k, v in stats.items()}


def test_integer_labels_and_explicit_labels(plate):
    stats = plate.regions()
    assert list(stats) == ["1", "2"]
    assert_partition(stats, plate)
    assert stats["2"].share > 0.5
    mine = regional_statistics(plate, labels=np.where(plate.problem.layer.points[:, 1] < 0, "south", "north"))
    assert list(mine) == ["north", "south"]
    assert_partition(mine, plate)
    assert mine["north"].share == pytest.approx(0.5, rel=1e-9)  # symmetric in y


def test_half_spaces(tilted):
    planes = {"right": ((0.01, 0, 0), (2.0, 0, 0)), "left": ((0.01, 0, 0), (-1, 0, 0))}
    stats = regional_statistics(tilted, planes=planes)
    assert list(stats) == ["right", "left"]
    assert_partition(stats, tilted)
    x = tilted.problem.layer.points[:, 0]
    np.testing.assert_allclose(stats["right"].force_vector, brute_force(tilted, x >= 0.01)["force_vector"], rtol=1e-12)
    both = regional_statistics(tilted, labels=tilted.problem.layer.labels, planes=planes)
    assert list(both) == ["centre", "lateral", "medial", "right", "left"]


def test_split_by_axis(tilted):
    layer = tilted.problem.layer
    x = layer.points[:, 0]
    at_cop = split_by_axis(tilted, "x")
    assert list(at_cop) == ["medial", "lateral"]
    assert_partition(at_cop, tilted)
    cut = tilted.center_of_pressure[0]
    assert at_cop["medial"].n_springs == int((x < cut).sum())
    given = split_by_axis(tilted, "x", at=1.5, names=("a", "b"))
    assert given["a"].resultant == pytest.approx(brute_force(tilted, x < 1.5)["resultant"], rel=1e-12)
    assert_partition(given, tilted)
    flipped = split_by_axis(tilted, "-x", at=-1.5, names=("b", "a"))
    assert flipped["a"].n_springs == given["a"].n_springs
    vector = split_by_axis(tilted, (3.0, 0, 0), at=1.5, names=("a", "b"))
    assert vector["b"].share == given["b"].share
    centroid = split_by_axis(tilted, "y", at="centroid")
    assert centroid["medial"].share == pytest.approx(0.5, abs=1e-9)  # symmetric in y


def test_region_without_contact(tilted):
    x = tilted.problem.layer.points[:, 0]
    far = region_statistics(tilted, x > 7.5, "far")
    assert far.resultant == 0 and far.force_magnitude_sum == 0 and far.share == 0
    assert far.contact_area == 0 and far.mean_pressure == 0 and far.peak_pressure == 0
    assert np.isnan(far.center_of_pressure).all()
    empty = region_statistics(tilted, np.zeros(len(x), bool), "empty")
    assert empty.n_springs == 0 and empty.area == 0
    np.testing.assert_array_equal(empty.force_vector, 0.0)
    idle = dataclasses.replace(tilted, pressure=np.zeros_like(tilted.pressure), strain=np.ones_like(tilted.strain))
    halves = split_by_axis(idle, "x")  # no centre of pressure: cut at the area centroid
    assert all(np.isnan(s.share) for s in halves.values())
    assert np.isnan(halves["medial"].as_dict()["center_of_pressure_mm"]).all()
    assert halves["medial"].n_springs + halves["lateral"].n_springs == len(x)


def test_regions_of_a_socket_carry_the_load_by_their_resultants():
    """A ball pushed into a socket: the springs push along the radii, so the sum of their force
    magnitudes is far more than the load; the regions' resultants add up to the load, and their
    shares (the resultants along the load) to 1, their parts in N to the load's size."""
    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=12, n_sectors=36, gap=0.1)
    layer = dataclasses.replace(layer, labels=np.where(layer.points[:, 0] < 0.0, "medial", "lateral"))
    load = np.array([300.0, 0.0, -1500.0])
    solution = d.solve(d.ContactProblem(layer, d.LinearLaw(10.0), force=tuple(load), free=("ux", "uy", "uz")))
    stats = solution.regions()
    for name, region in stats.items():
        want = brute_force(solution, layer.labels == name)
        for key, value in want.items():
            np.testing.assert_allclose(getattr(region, key), value, rtol=1e-10, atol=1e-9, err_msg=f"{name}.{key}")
    size = np.sqrt(load @ load)
    np.testing.assert_allclose(sum(s.force_vector for s in stats.values()), -load, rtol=0, atol=1e-6 * size)
    assert sum(s.share * size for s in stats.values()) == pytest.approx(size, rel=1e-6)  # N of the load
    assert sum(s.resultant for s in stats.values()) > size  # two resultants at an angle
    assert sum(s.force_magnitude_sum for s in stats.values()) > 1.05 * sum(s.resultant for s in stats.values())
    assert stats["lateral"].share > stats["medial"].share > 0  # the load leans toward +x
    assert set(stats["medial"].as_dict()) >= {"force_vector_N", "resultant_N", "share", "force_magnitude_sum_N"}
    assert "force_N" not in stats["medial"].as_dict()  # no number called a force that is none


def test_bad_input(tilted):
    layer = tilted.problem.layer
    bare = dataclasses.replace(tilted, problem=tilted.problem.with_layer(dataclasses.replace(layer, labels=None)))
    with pytest.raises(InputError, match="the layer has no labels"):
        regional_statistics(bare)
    with pytest.raises(InputError, match=r"labels must have shape \(768,\)"):
        regional_statistics(tilted, labels=[1, 2])
    with pytest.raises(InputError, match="planes must be a mapping"):
        regional_statistics(tilted, planes=[((0, 0, 0), (1, 0, 0))])
    with pytest.raises(InputError, match=r"planes\['a'\] must be a pair"):
        regional_statistics(tilted, planes={"a": (0, 0, 0)})
    with pytest.raises(InputError, match=r"planes\['a'\] normal must be a nonzero vector"):
        regional_statistics(tilted, planes={"a": ((0, 0, 0), (0, 0, 0))})
    with pytest.raises(InputError, match="planes uses the name 'medial'"):
        regional_statistics(tilted, labels=layer.labels, planes={"medial": ((0, 0, 0), (1, 0, 0))})
    with pytest.raises(InputError, match="axis must be 'x', 'y', 'z'"):
        split_by_axis(tilted, "w")
    with pytest.raises(InputError, match="axis must be a nonzero vector"):
        split_by_axis(tilted, (0, 0, 0))
    with pytest.raises(InputError, match="at must be a number"):
        split_by_axis(tilted, "x", at="middle")
    with pytest.raises(InputError, match="at must be finite"):
        split_by_axis(tilted, "x", at=float("nan"))
    with pytest.raises(InputError, match="names must be two different strings"):
        split_by_axis(tilted, "x", names=("a", "a"))
    with pytest.raises(InputError, match="names must be a pair"):
        split_by_axis(tilted, "x", names=("a", "b", "c"))
    with pytest.raises(InputError, match="mask must be booleans"):
        region_statistics(tilted, np.ones(3, bool))
