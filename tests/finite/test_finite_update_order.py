"""The order of a finite solve's updates of the springs (``_bring_up_to_date`` in
``dea_opt/finite/driver.py``), driven by a scripted tracker: which update comes when, and when
none is needed. The meshes' side of each update is tested against fresh casts in
``test_finite_meshes.py``; here only the driver's choices, which the knee meets too rarely to pin.

* a partial update that changes nothing is followed by a complete one at the same pose (the
  window's far edge, where springs come into range, is looked at only then);
* right after a complete update that changed the springs, a pose whose hits moved less than
  ``_SETTLED`` (1e-6 mm) keeps them: nothing an update there could change carries a force above
  rounding;
* a pose that moved more is updated again, completely.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dea_opt.finite import driver


class _Tracker:
    """The tracker's side the driver asks: what its updates return, in order, and how far the hits
    moved since the last one (mm)."""

    def __init__(self, answers, complete: bool, moved: float):
        self.answers, self.complete, self.moved = list(answers), complete, moved
        self.asked: list[bool] = []  # ``complete`` of each update asked for
        self.crushed_through = 0

    def short_step(self, pose) -> bool:
        return False

    def moved_from_update(self, pose) -> float:
        return self.moved

    def update(self, system, state, complete: bool):
        self.asked.append(complete)
        return self.answers.pop(0)


def _bring_up_to_date(tracker):
    system = SimpleNamespace(transform=lambda y: np.eye(4))
    inner = SimpleNamespace(success=True, state=SimpleNamespace(y=np.zeros(6)), message="")
    tightened = []

    def tighten(system, inner):
        tightened.append(True)
        return inner

    out = driver._bring_up_to_date(tracker, system, inner, "finite", {"max_recasts": 10}, [0], tighten)
    return out, tightened


def test_a_partial_update_that_changes_nothing_is_followed_by_a_complete_one_at_the_same_pose():
    tracker = _Tracker([None, None], complete=False, moved=0.0)
    (_, _, resolve, stable), tightened = _bring_up_to_date(tracker)
    assert tracker.asked == [False, True]
    assert tightened == [True]  # the pose the complete update checks is solved to the tolerance first
    assert resolve is False and stable is True and tracker.complete is True


@pytest.mark.parametrize("moved", [0.0, 0.5 * driver._SETTLED, driver._SETTLED])
def test_right_after_a_complete_update_a_pose_that_moved_less_than_settled_keeps_its_springs(moved):
    tracker = _Tracker([], complete=True, moved=moved)
    (_, _, resolve, stable), tightened = _bring_up_to_date(tracker)
    assert tracker.asked == [] and tightened == [True]
    assert resolve is False and stable is True


@pytest.mark.parametrize("moved", [2.0 * driver._SETTLED, 1e-3])
def test_a_pose_that_moved_more_since_a_complete_update_is_updated_again_completely(moved):
    tracker = _Tracker([None], complete=True, moved=moved)
    (_, _, resolve, stable), _ = _bring_up_to_date(tracker)
    assert tracker.asked == [True]
    assert resolve is False and stable is True
