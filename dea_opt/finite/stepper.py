"""The frames of a load path with finite kinematics: each warm-started from the previous pose.

Written math: ``formulations/finite.md``. Every frame is a :func:`dea_opt.finite.solve`
started from the previous frame's free coordinates and its re-cast springs; with prescribed poses
(the gait set-up: flexion from the kinematics, the rest found) each frame's pose of body 2's mesh
is the zero of its free coordinates.
"""

from __future__ import annotations

import time

import numpy as np

from ..problem import ContactProblem
from ..solution import Solution

__all__ = ["FiniteStepper"]


class FiniteStepper:
    """Solves frame after frame with finite kinematics, carrying the pose and the re-cast springs.

    Set :attr:`pose` (4x4) before a frame to prescribe body 2's mesh pose at zero displacement.
    """

    def __init__(self, method: str, options: dict, certificate_tol: float):
        self.method = method  # checked by the finite solve
        self.options = dict(options)  # checked by the finite solve (dea_opt.finite.plan)
        self.certificate_tol = certificate_tol
        self.x: np.ndarray | None = None
        self.tracker: object = None
        self.pose: np.ndarray | None = None

    def solve(self, problem: ContactProblem, new_geometry: bool, setup: float = 0.0) -> Solution:
        from ..finite import solve as solve_finite
        from ..loadcheck import check_unresisted

        start = time.perf_counter()
        solution = solve_finite(
            problem,
            self.method,
            certificate_tol=self.certificate_tol,
            strict=False,
            frame=self.pose,
            tracker=self.tracker,
            unresisted=check_unresisted,
            x0=self.x,
            **self.options,
        )
        if not solution.success and self.x is not None and self.method != "auto":
            # The previous frame's pose may be a poor start (a jump in the load): start cold (auto
            # tried the cold starts already, dea_opt/finite/means.py).
            warm = solution
            solution = solve_finite(
                problem,
                self.method,
                certificate_tol=self.certificate_tol,
                strict=False,
                frame=self.pose,
                unresisted=check_unresisted,
                **self.options,
            )
            if not solution.success:  # what the start nearer the path found says as much
                said = f"from the previous frame's pose, status '{warm.status.value}': {warm.message}"
                object.__setattr__(solution, "message", f"{solution.message}; {said}")
                solution.info["warm_start"] = {"status": warm.status.value, "message": warm.message}
        object.__setattr__(solution, "build_time", solution.build_time + setup)
        if solution.success:
            self.x = solution.u[problem.free_indices]
            self.tracker = solution.tracker
        solution.info["frame_time"] = time.perf_counter() - start
        return solution

    def reset(self) -> None:
        """Forget the warm start and the re-cast springs (after a failed frame)."""
        self.x = None
        self.tracker = None


def moves(problem: ContactProblem, poses) -> bool:
    """Whether the springs change from frame to frame: prescribed poses, or re-casting from meshes."""
    from ..mesh.springs import SpringCast

    return poses is not None or isinstance(problem.targets, SpringCast)


def frame_layer(frame: ContactProblem, solution) -> object:
    """The springs a frame's results belong to: the solution's (re-cast) ones when it has them."""
    if solution is not None and getattr(solution, "tracker", None) is not None:
        return solution.problem.layer
    return frame.layer


def check_finite_poses(problem: ContactProblem, poses, n: int):
    """Poses of a finite-kinematics path: (T, 4, 4), one per frame; the springs are re-cast from the
    problem's SpringCast (``targets=``), not by a ``layer_for_pose``."""
    from .._checks.inputs import as_numeric
    from ..errors import InputError
    from ..mesh.springs import SpringCast, check_pose

    if poses is None:
        return None
    poses = as_numeric("poses", poses)
    if poses.shape != (n, 4, 4):
        raise InputError(f"poses must have shape ({n}, 4, 4), one per frame, got {poses.shape}")
    if not isinstance(problem.targets, SpringCast):
        raise InputError(
            "poses move body 2's mesh, so with kinematics='finite' the springs are re-cast from their "
            "SpringCast: give ContactProblem(cast.layer, ..., kinematics='finite', targets=cast)"
        )
    for k, pose in enumerate(poses):
        check_pose(pose, f"poses[{k}]")
    return poses
