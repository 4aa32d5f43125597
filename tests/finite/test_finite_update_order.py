"""The order of a finite solve's updates of the springs (``_bring_up_to_date`` in
``dea_opt/finite/driver.py``), driven by a scripted tracker: which update comes when, and when
none is needed. The meshes' side of each update is tested against fresh casts in
``test_finite_meshes.py``; here only the driver's choices, which the knee meets too rarely to pin.

* a partial update that changes nothing is followed by a complete one at the same pose (the
  window's far edge, where springs come into range, is looked at only then);
* right after a complete update that changed the springs, a pose whose hits moved less than
  ``_SETTLED`` (1e-6 mm) keeps them: nothing an update there could change carries a force above
  rounding;
* a pose that moved more is updated again, completely;
* the pose a complete update checks is solved to the tolerance only where that update changed
  nothing that carries load (else a solve follows anyway); where that solve moved the hits more
  than ``_SETTLED``, the springs are updated again there.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from dea_opt.finite import driver


class _Tracker:
    """The tracker's side the driver asks: what its updates return, in order, and how far the hits
    moved since the last one (mm)."""

    def __init__(self, answers, complete: bool, moved: float, moved_after=(0.0,)):
        self.answers, self.complete, self.moved = list(answers), complete, moved
        # how far the hits moved since each update, once it was made (an update is at the pose)
        self.moved_after = list(moved_after)
        self.asked: list[bool] = []  # ``complete`` of each update asked for
        self.crushed_through = 0

    def short_step(self, pose) -> bool:
        return False

    def moved_from_update(self, pose) -> float:
        return self.moved

    def update(self, system, state, complete: bool):
        self.asked.append(complete)
        self.moved = self.moved_after.pop(0) if len(self.moved_after) > 1 else self.moved_after[0]
        return self.answers.pop(0)


def _bring_up_to_date(tracker, moves=()):
    """The driver's choices with ``tracker``; ``moves``: how far (mm) each solve to the tolerance
    moves the hits (0 after the last one given)."""
    system = SimpleNamespace(transform=lambda y: np.eye(4))
    inner = SimpleNamespace(success=True, state=SimpleNamespace(y=np.zeros(6)), message="")
    tightened = []
    moves = list(moves)

    def tighten(system, inner):
        tightened.append(True)
        tracker.moved += moves.pop(0) if moves else 0.0
        return inner

    out = driver._bring_up_to_date(tracker, system, inner, "finite", {"max_recasts": 10}, [0], tighten)
    return out, tightened


def test_a_partial_update_that_changes_nothing_is_followed_by_a_complete_one_at_the_same_pose():
    tracker = _Tracker([None, None], complete=False, moved=0.0)
    (_, _, resolve, stable), tightened = _bring_up_to_date(tracker)
    assert tracker.asked == [False, True]
    assert tightened == [True]  # the pose where the complete update changed nothing, solved to the tolerance
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


def test_a_complete_update_that_changes_a_loaded_spring_checks_the_pose_as_solved():
    """A solve follows it anyway: the pose it checked is not solved to the tolerance first."""
    changed = SimpleNamespace(none_left=None, system="new", state="at the pose", resolve=True)
    tracker = _Tracker([None, changed], complete=False, moved=0.0)
    (system, _, resolve, stable), tightened = _bring_up_to_date(tracker)
    assert tracker.asked == [False, True] and tightened == []
    assert system == "new" and resolve is True and stable is True


def test_where_solving_to_the_tolerance_moved_the_hits_the_springs_are_updated_again_there():
    tracker = _Tracker([None, None], complete=True, moved=1e-3)
    (_, _, resolve, stable), tightened = _bring_up_to_date(tracker, moves=[3.0 * driver._SETTLED])
    assert tracker.asked == [True, True] and tightened == [True, True]
    assert resolve is False and stable is True
