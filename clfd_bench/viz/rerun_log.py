"""Interactive logs of rollouts with rerun-sdk (``.rrd`` files, open with ``rerun FILE.rrd``).

One :class:`RolloutLogger` writes one recording. Every rollout goes under its own entity path
(e.g. ``after_task_3/e/demo_0``) with, in the world frame (metres, z up):

* ``prediction``, ``demonstration``: the commanded and the demonstrated tool path (static
  lines; the tool is the pen tip for writing, the grasp point between the fingertips for
  RoboTasks, see :func:`clfd_bench.execution.trace.tool_path`);
* ``tool_path``: where the tool went (static line) and ``tool``: the tool point over time;
* ``ink``: the pen-down segments (writing envs);
* ``hand``: the tracked hand frame's pose over time (with axes);
* ``objects/<body>``: pose over time (axes and a marker) of every movable body that is not
  the robot (the lid, bottle, plate, blocks, cup, beans);
* ``tracking_error``: the hand's position error (m) over time;
* ``events``: the outcome (success, or failure with its reason) at the rollout's end.

Time is the ``sim_time`` timeline (seconds since the rollout's reset). The file is written to
a temporary sibling and renamed into place by :meth:`RolloutLogger.close`, so a killed process
never leaves half a file under the final name.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["RolloutLogger", "rrd_entity_paths"]

PREDICTION_RGB = (255, 140, 0)
DEMONSTRATION_RGB = (40, 170, 60)
PATH_RGB = (30, 90, 230)
INK_RGB = (20, 20, 120)
OBJECT_RGB = (200, 120, 40)
_MAX_LABELLED_OBJECTS = 6
_LINE_RADIUS = 0.002


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    """MuJoCo quaternions (w, x, y, z) [..., 4] -> rerun's (x, y, z, w)."""
    q = np.asarray(wxyz, dtype=np.float64)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def _segments(points: np.ndarray, keep: np.ndarray) -> list[np.ndarray]:
    """Runs of consecutive points [K, 3] where ``keep`` [K] is True (each >= 2 points)."""
    out, start = [], None
    for k, flag in enumerate(np.append(keep, False)):
        if flag and start is None:
            start = k
        elif not flag and start is not None:
            if k - start >= 2:
                out.append(points[start:k])
            start = None
    return out


class RolloutLogger:
    """Writes rollouts to a rerun recording saved as ``path`` (``.rrd``).

    Args:
        path: the ``.rrd`` file to write (parent folders are created).
        recording_name: shown in the viewer.
        application_id: rerun application id.
    """

    def __init__(self, path: str | os.PathLike[str], recording_name: str = "clfd-bench",
                 application_id: str = "clfd-bench"):
        import rerun as rr

        self.path = Path(path)
        if self.path.suffix != ".rrd":
            raise ValueError(f"rerun files end in .rrd, got {self.path.name!r}; e.g. "
                             "--rerun rollouts.rrd")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(f".{self.path.stem}.{uuid.uuid4().hex[:8]}.rrd.tmp")
        self._rr = rr
        self.rec = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
        self.rec.set_log_time_enabled(False)
        self.rec.set_log_tick_enabled(False)
        self.rec.save(self._tmp)
        self.rec.send_recording_name(recording_name)
        self.rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self.num_rollouts = 0
        self._closed = False

    def log_rollout(self, entity: str, base: Any, result: Any, prediction: Any,
                    demonstration: Any | None = None) -> None:
        """Logs one executed rollout.

        Args:
            entity: entity path prefix, e.g. ``"after_task_3/e/demo_0"``.
            base: the unwrapped env it ran in (maps data units to the world).
            result: its :class:`~clfd_bench.execution.execute.ExecResult`, executed with
                ``trace=True``.
            prediction: the executed trajectory in data units (what ``execute`` got).
            demonstration: the demonstration of the same demo, data units (optional).
        """
        from clfd_bench.execution.trace import tool_path

        rr, rec = self._rr, self.rec
        trace = result.trace
        if trace is None:
            raise ValueError("log_rollout needs the rollout's trace: execute with trace=True")
        entity = entity.strip("/")
        rec.log(f"{entity}/prediction",
                rr.LineStrips3D([tool_path(base, prediction)], radii=_LINE_RADIUS,
                                colors=[PREDICTION_RGB], labels=["prediction"]), static=True)
        if demonstration is not None:
            rec.log(f"{entity}/demonstration",
                    rr.LineStrips3D([tool_path(base, demonstration)], radii=_LINE_RADIUS,
                                    colors=[DEMONSTRATION_RGB], labels=["demonstration"]),
                    static=True)
        rec.log(f"{entity}/tool_path",
                rr.LineStrips3D([trace.tool_pos], radii=_LINE_RADIUS * 0.6, colors=[PATH_RGB]),
                static=True)
        if trace.tool_down is not None:
            strokes = _segments(trace.tool_pos, trace.tool_down)
            if strokes:
                rec.log(f"{entity}/ink", rr.LineStrips3D(strokes, radii=_LINE_RADIUS * 1.2,
                                                         colors=[INK_RGB] * len(strokes)),
                        static=True)
        times = [rr.TimeColumn("sim_time", duration=trace.time)]
        rec.send_columns(f"{entity}/tool", indexes=times,
                         columns=rr.Points3D.columns(positions=trace.tool_pos))
        rec.log(f"{entity}/tool", rr.Points3D.from_fields(radii=0.006, colors=[PATH_RGB]),
                static=True)
        rec.send_columns(f"{entity}/hand", indexes=times,
                         columns=rr.Transform3D.columns(translation=trace.hand_pos,
                                                        quaternion=_xyzw(trace.hand_quat)))
        rec.log(f"{entity}/hand", rr.TransformAxes3D(0.08), static=True)
        labelled = len(trace.objects) <= _MAX_LABELLED_OBJECTS  # not every coffee bean
        for name, poses in trace.objects.items():
            path = f"{entity}/objects/{rr.escape_entity_path_part(name)}"
            rec.send_columns(path, indexes=times,
                             columns=rr.Transform3D.columns(translation=poses[:, :3],
                                                            quaternion=_xyzw(poses[:, 3:])))
            rec.log(path, rr.TransformAxes3D(0.04), static=True)
            rec.log(f"{path}/marker", rr.Points3D([[0.0, 0.0, 0.0]], radii=0.012,
                                                   colors=[OBJECT_RGB],
                                                   labels=[name] if labelled else None),
                    static=True)
        ok = np.isfinite(trace.tracking_error)
        if ok.any():
            rec.send_columns(
                f"{entity}/tracking_error",
                indexes=[rr.TimeColumn("sim_time", duration=trace.time[ok])],
                columns=rr.Scalars.columns(scalars=trace.tracking_error[ok]))
        rec.set_time("sim_time", duration=float(trace.time[-1]))
        text = (f"{entity}: success" if result.success
                else f"{entity}: failure: {result.failure_reason}")
        rec.log(f"{entity}/events", rr.TextLog(text, level="INFO" if result.success else "WARN"))
        rec.log("events", rr.TextLog(text, level="INFO" if result.success else "WARN"))
        rec.reset_time()
        self.num_rollouts += 1

    def close(self) -> Path:
        """Finishes the file and moves it to ``path``; returns ``path``."""
        if not self._closed:
            self.rec.flush()
            self.rec.disconnect()
            os.replace(self._tmp, self.path)
            self._closed = True
        return self.path

    def __enter__(self) -> RolloutLogger:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:  # keep no half-written recording
            self.rec.disconnect()
            self._tmp.unlink(missing_ok=True)
            self._closed = True


def rrd_entity_paths(path: str | os.PathLike[str]) -> dict[str, int]:
    """Entity paths in an ``.rrd`` file and their row counts (reads it back with rerun's own
    reader; raises if rerun cannot open it)."""
    from rerun.chunk import RrdReader

    counts: dict[str, int] = {}
    for chunk in RrdReader(Path(path)).stream().to_chunks():
        counts[str(chunk.entity_path)] = counts.get(str(chunk.entity_path), 0) + chunk.num_rows
    return counts
