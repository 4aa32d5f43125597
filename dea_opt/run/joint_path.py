"""A joint's load and motion path: every frame solved in turn, its outputs written as it comes.

Written math: ``formulations/joint.md`` ("A path").

Each frame starts from the previous frame's answer (its free coordinates and, under finite
kinematics, its contacts' springs as they were cast again at that answer's pose: the springs are
carried from frame to frame, not cast anew from the start pose). The outputs, with units in every
column name: ``frames.csv`` (per frame: status, each body's coordinates and the reactions at its
prescribed dofs, each layer's peak pressure, area, force and centre of pressure, and each labelled
compartment's force, share, peak pressure and area), ``ligaments.csv`` (per bundle and frame),
``elastic.csv`` (per spring or bushing and frame, when there are any), per layer a ParaView series
``<layer>.pvd`` of ``<layer>_frames/frame_NNNN.vtu`` (the frames' springs where each answer put
them; a frame without an answer on the start layer, with NaN fields) and ``summary.json``.
"""

from __future__ import annotations

import csv
import io as _io
import math

import numpy as np

from ..kinematics import DOFS
from .outcome import RunOutcome

__all__ = ["JointPathWriter", "run_joint_path", "solve_joint_path"]

_UNITS = {"u": "mm", "r": "rad"}
_REACTION_UNITS = {"u": "N", "r": "Nmm"}


def _stem(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)


def _csv(rows: list[dict], columns) -> str:
    text = _io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    return text.getvalue()


def solve_joint_path(
    joint,
    path,
    method: str = "auto",
    *,
    certificate_tol: float = 1e-6,
    stop_on_error: bool = False,
    on_frame=None,
    keep: bool = True,
):
    """Every frame of ``path`` (:class:`~dea_opt.scenario.joint_path.JointPath`) solved in turn, each
    from the previous frame's answer (its free dofs; under finite kinematics its contacts' springs
    where it left them, :attr:`~dea_opt.joint.JointSolution.states`, and the tangent of its exact
    forces). A frame whose warm start fails its certificate is reached in halves of its motion from
    the previous answer (loads and prescribed dofs interpolated, :meth:`JointPath.between`; at most
    three halvings), else solved once more from the start pose.

    Parameters
    ----------
    on_frame : callable, optional
        ``on_frame(k, frame_joint, solution)`` as each frame is solved (``solution`` None for a frame
        that raised a :class:`~dea_opt.errors.DeaError`): a run writes its outputs there.
    keep : bool
        Return the solutions (else Nones: a long path's answers are not kept in memory).

    Returns
    -------
    list of JointSolution or None
        None for a frame that raised a :class:`~dea_opt.errors.DeaError` (re-raised with
        ``stop_on_error``), or every frame with ``keep=False``.
    """
    from ..errors import DeaError
    from ..joint import solve_joint

    finite = joint.kinematics == "finite"

    def attempt(frame, previous):
        """The frame's answer from ``previous`` (or from the start), None where it raised."""
        warm = previous is not None and previous.joint.free_names == frame.free_names
        options: dict = {}
        if warm:
            options["x0"] = previous.x
        if finite and previous is not None and previous.states:
            options["contact_states"] = previous.states
        if finite and warm and previous.info.get("tangent") is not None:
            options["tangent"] = previous.info["tangent"]
        try:
            return solve_joint(frame, method, certificate_tol=certificate_tol, strict=False, **options)
        except DeaError:
            if stop_on_error:
                raise
            return None

    def reach(k, previous, before: float, depth: int):
        """Frame ``k`` from the answer at fraction ``before`` of the way from frame ``k - 1``: where it
        fails, from an answer halfway first (the motion of one frame in halves, at most 8)."""
        frame = path.frame(joint, k) if before == 0.0 and depth == 0 else None
        s = attempt(frame or path.between(joint, k, 1.0), previous)
        if (s is None or not s.success) and previous is not None and depth < 3:
            middle = before + (1.0 - before) / 2.0
            half = attempt(path.between(joint, k, middle), previous)
            if half is not None and half.success:
                s = reach(k, half, middle, depth + 1)
        return s

    solutions: list = []
    previous = None
    for k in range(len(path)):
        frame = path.frame(joint, k)
        s = reach(k, previous, 0.0, 0) if k > 0 and previous is not None else attempt(frame, previous)
        if (s is None or not s.success) and previous is not None:
            s = attempt(frame, None)  # from the start, once
        if on_frame is not None:
            on_frame(k, frame, s)
        solutions.append(s if keep else None)
        previous = s if s is not None and s.success else previous
    return solutions


class JointPathWriter:
    """The rows and files of a joint's path, frame by frame (:func:`solve_joint_path`'s ``on_frame``).

    Parameters
    ----------
    joint : Joint
        The path's joint (its bodies, contacts, bundles and elastic elements name the columns).
    times : array_like (T,)
    out : Path or None
        Where each layer's series goes (``<layer>_frames/``); None writes none.
    """

    def __init__(self, joint, times, out=None):
        from ..loadpath.series import FrameSeries

        self.joint, self.times = joint, np.asarray(times, dtype=float)
        self.frames: list[dict] = []
        self.bundles: list[dict] = []
        self.elastic: list[dict] = []
        self.good: list[int] = []
        self.peaks: dict = {}
        #: ``(frame, time_s, solution, force_N)`` of the certified frame with the largest contact force: what
        #: the run's report shows in 3-D (one solution kept, whatever the path's length)
        self.shown: tuple | None = None
        self.series = (
            {c.name: FrameSeries(out / f"{_stem(c.name)}_frames", len(self.times)) for c in joint.contacts}
            if out is not None
            else {}
        )

    def __call__(self, k: int, frame, s) -> None:
        t = float(self.times[k])
        row: dict = {"frame": k, "time_s": t}
        row["status"] = "load_not_supported" if s is None else str(s.status)
        row["success"] = s is not None and s.success
        row["valid"] = s is not None and s.validity.valid
        row["iterations"] = 0 if s is None else int(s.iterations)
        for name, body in frame.bodies.items():
            u = s.bodies[name].u if s is not None else np.full(6, math.nan)
            for j, dof in enumerate(DOFS):
                row[f"{name}.{dof}_{_UNITS[dof[0]]}"] = float(u[j])
            for dof in sorted(body.prescribed, key=DOFS.index):
                value = s.bodies[name].reactions.get(dof, math.nan) if s is not None else math.nan
                row[f"{name}.reaction_{dof}_{_REACTION_UNITS[dof[0]]}"] = float(value)
        for i, contact in enumerate(self.joint.contacts):
            self._layer(row, k, t, contact, None if s is None else s.contacts[i])
        self.frames.append(row)
        if s is not None and s.success:
            force = sum(float(np.linalg.norm(c.contact_force)) for c in s.contacts)
            if self.shown is None or force > self.shown[3]:
                self.shown = (k, t, s, force)
        for i, lig in enumerate(self.joint.ligaments):
            r = s.ligaments[i] if s is not None else None
            self.bundles.append(
                {
                    "frame": k,
                    "time_s": t,
                    "name": lig.name or f"ligament {i}",
                    "body1": lig.body1,
                    "body2": lig.body2,
                    "force_N": r["force_N"] if r else math.nan,
                    "strain": r["strain"] if r else math.nan,
                    "length_mm": r["length_mm"] if r else math.nan,
                }
            )
        for item in s.elastic if s is not None else []:
            self.elastic.append({"frame": k, "time_s": t, **item})
        if s is not None and s.success:
            self.good.append(k)

    def _layer(self, row, k, t, contact, layer) -> None:
        name = contact.name
        ok = layer is not None and layer.success
        row[f"{name}.peak_pressure_MPa"] = layer.peak_pressure if layer else math.nan
        row[f"{name}.contact_area_mm2"] = layer.contact_area if layer else math.nan
        force = layer.contact_force if layer else np.full(3, math.nan)
        row[f"{name}.force_N"] = float(np.linalg.norm(force))
        for a, v in zip("xyz", force):
            row[f"{name}.force_{a}_N"] = float(v)
        cop = layer.center_of_pressure if layer else np.full(3, math.nan)
        for a, v in zip("xyz", cop):
            row[f"{name}.center_of_pressure_{a}_mm"] = float(v)
        labels = contact.layer.labels
        if labels is not None:
            stats = layer.regions() if layer is not None and layer.problem.layer.labels is not None else {}
            for label in sorted(set(np.asarray(labels).astype(str))):
                r = stats.get(label)
                row[f"{name}.{label}.force_N"] = float(r.resultant) if r else math.nan
                row[f"{name}.{label}.share"] = float(r.share) if r else math.nan
                row[f"{name}.{label}.peak_pressure_MPa"] = float(r.peak_pressure) if r else math.nan
                row[f"{name}.{label}.contact_area_mm2"] = float(r.contact_area) if r else math.nan
        if ok and (name not in self.peaks or layer.peak_pressure > self.peaks[name][0]):
            self.peaks[name] = (float(layer.peak_pressure), k, t)
        series = self.series.get(name)
        if series is not None:
            if layer is not None:
                series.write(k, t, layer.problem.layer, layer if ok else None)
            else:
                series.write(k, t, contact.layer, None)

    def write(self, out) -> dict:
        """Write the tables, the series' ``.pvd`` and nothing else; returns ``{name: Path}``."""
        from ..files.atomic import write_data

        files = {"frames": write_data(out / "frames.csv", _csv(self.frames, list(self.frames[0])))}
        if self.bundles:
            files["ligaments"] = write_data(out / "ligaments.csv", _csv(self.bundles, list(self.bundles[0])))
        if self.elastic:
            columns: dict = {}
            for r in self.elastic:
                columns.update(dict.fromkeys(r))
            files["elastic"] = write_data(out / "elastic.csv", _csv(self.elastic, list(columns)))
        for name, series in self.series.items():
            files[f"{_stem(name)}.pvd"] = series.write_pvd(out / f"{_stem(name)}.pvd")
        return files

    def compartments(self) -> dict:
        """``{layer: {label: {largest_force_N, frame, time_s, mean_share}}}`` over the certified frames."""
        out: dict = {}
        good = [self.frames[k] for k in self.good]
        for contact in self.joint.contacts:
            if contact.layer.labels is None:
                continue
            per: dict = {}
            for label in sorted(set(np.asarray(contact.layer.labels).astype(str))):
                forces = [r[f"{contact.name}.{label}.force_N"] for r in good]
                shares = [r[f"{contact.name}.{label}.share"] for r in good]
                if not forces:
                    per[label] = {
                        "largest_force_N": math.nan,
                        "frame": None,
                        "time_s": math.nan,
                        "mean_share": math.nan,
                    }
                    continue
                i = int(np.nanargmax(forces)) if np.isfinite(forces).any() else 0
                per[label] = {
                    "largest_force_N": float(forces[i]),
                    "frame": int(good[i]["frame"]),
                    "time_s": float(good[i]["time_s"]),
                    "mean_share": float(np.nanmean(shares)) if np.isfinite(shares).any() else math.nan,
                }
            out[contact.name] = per
        return out

    def summary(self) -> dict:
        failures: dict = {}
        for row in self.frames:
            if not row["success"]:
                failures[row["status"]] = failures.get(row["status"], 0) + 1
        good = set(self.good)
        largest: dict = {}
        for r in self.bundles:
            if r["frame"] in good:
                largest[r["name"]] = max(largest.get(r["name"], 0.0), float(r["force_N"]))
        return {
            "frames": len(self.frames),
            "certified": len(self.good),
            "valid": sum(1 for k in self.good if self.frames[k]["valid"]),
            "failures": failures,
            "peak_pressure_MPa": {
                c.name: {
                    "value": self.peaks[c.name][0],
                    "frame": self.peaks[c.name][1],
                    "time_s": self.peaks[c.name][2],
                }
                if c.name in self.peaks
                else {"value": math.nan, "frame": None, "time_s": math.nan}
                for c in self.joint.contacts
            },
            "compartments": self.compartments(),
            "largest_ligament_force_N": {
                (lig.name or f"ligament {i}"): largest.get(lig.name or f"ligament {i}", math.nan)
                for i, lig in enumerate(self.joint.ligaments)
            },
        }


def _status(value: str):
    from ..status import Status

    try:
        return Status(value)
    except ValueError:
        return Status.SOLVER_ERROR


def run_joint_path(scenario, joint, path, method, out, stop_on_error) -> RunOutcome:
    """Solve ``path`` and write its outputs into ``out`` (a run's staging folder)."""
    from ..io.summary import write_json

    vtk = "vtk" in scenario.output.formats
    writer = JointPathWriter(joint, path.time, out if vtk else None)
    solve_joint_path(
        joint,
        path,
        method,
        certificate_tol=scenario.solve.certificate_tol,
        stop_on_error=stop_on_error,
        on_frame=writer,
        keep=False,
    )
    files = writer.write(out)
    summary = writer.summary()
    summary["title"] = scenario.title
    files["summary"] = write_json(summary, out / "summary.json")
    n, certified = summary["frames"], summary["certified"]
    success = certified == n
    valid = (summary["valid"] == certified) if certified else None
    message = f"{certified} of {n} frames certified" + ("" if success else f" ({summary['failures']})")
    regions = []
    for layer, per in summary["compartments"].items():
        for label, c in per.items():
            if c["frame"] is not None:
                regions.append(
                    f"{layer} {label}: largest force {c['largest_force_N']:.4g} N at frame {c['frame']} "
                    f"(time {c['time_s']:.4g}), mean share {c['mean_share']:.3f}"
                )
    outside = [f"frame {r['frame']}" for r in writer.frames if r["success"] and not r["valid"]]
    headline = {"frames": n, "certified": certified}
    for layer, peak in summary["peak_pressure_MPa"].items():
        headline[f"{layer}.peak_pressure_MPa"] = peak["value"]
    return RunOutcome(
        "path",
        success,
        message,
        files,
        headline,
        {"frames": writer.frames, "shown": writer.shown},
        valid=valid,
        validity=[f"validity: {summary['valid']} of {certified} certified frames valid"],
        reasons=outside,
        regions=regions,
        failures={_status(k): v for k, v in summary["failures"].items()},
    )
