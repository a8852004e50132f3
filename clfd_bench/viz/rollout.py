"""Rendering one rollout: executing a trajectory and streaming its frames (or only its
closing frame)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from clfd_bench.viz.captions import _caption, outcome_caption
from clfd_bench.viz.framing import (
    _HAND_REACH,
    _PROP_REACH,
    _camera_for,
    _inflate,
    _is_writing,
    _motion_points,
    _prop_box_points,
    see_through_bodies,
)
from clfd_bench.viz.overlay import _BOARD_LIFT, OverlayRenderer
from clfd_bench.viz.style import DEMONSTRATION_RGBA, PREDICTION_RGBA, VideoStyle

__all__ = ["closing_frame", "render_rollout"]


def render_rollout(env: Any, trajectory: Any, demo: int, sinks: Sequence[Callable], *,
                   demonstration: Any | None = None, caption: str = "",
                   style: VideoStyle | None = None, trace: bool = False,
                   settle_s: float | None = None, camera: Any | None = None):
    """Executes ``trajectory`` from demo ``demo``'s start and streams rendered frames, with
    the paths drawn in, to every sink (e.g. ``VideoWriter.append``).

    Args:
        env: a clfd-bench env (no render mode needed; e.g. ``env_pool.get_env(id)``).
        trajectory: what ``clfd_bench.execution.execute.execute`` takes (data units).
        demo: the demo to reset to.
        sinks: callables taking one frame ``[H, W, 3]`` uint8.
        demonstration: the demonstration in the same form, drawn in green (optional).
        caption: text drawn top-left; the outcome is added on the held closing frames
            (:func:`outcome_caption`).
        style: a :class:`VideoStyle`.
        trace: keep the rollout's step-by-step trace (for rerun logging).
        settle_s: seconds of settling after the trajectory (default: the rollout's).
        camera: a ``CameraSpec`` (default: writing, one framing the letter; otherwise one
            framing the tool's path, the hand and the props wherever this rollout takes them,
            found by a first rollout without rendering: :mod:`clfd_bench.viz.framing`).

    Returns:
        ``(ExecResult, frames written per sink)``; the frame count is
        ``style.frames_for(result.steps)``.
    """
    from clfd_bench.execution.execute import execute
    from clfd_bench.execution.trace import FrameHook, tool_path

    style = style or VideoStyle()
    base = env.unwrapped
    target = tool_path(base, trajectory)
    static = [(target, PREDICTION_RGBA)]
    if demonstration is not None:
        static.insert(0, (tool_path(base, demonstration), DEMONSTRATION_RGBA))
    if camera is None:  # the writing camera frames the letters only
        moving = ([] if _is_writing(base)
                  else [_motion_points(env, trajectory, demo, settle_s, style.every)])
        extra = np.concatenate([np.zeros((0, 3)), *moving, *(s for s, _ in static[:-1])])
        camera = _camera_for(base, target, extra, style.width / style.height)
    overlay = OverlayRenderer(base.model, style, camera, see_through_bodies(base))
    last: list[np.ndarray] = []
    count = [0]

    def sink(frame: np.ndarray) -> None:
        last[:] = [frame]
        count[0] += 1
        for s in sinks:
            s(frame)

    try:
        overlay.start(static, expected_steps=len(target) + 60, caption=caption,
                      lift=_BOARD_LIFT if _is_writing(base) else 0.0)
        result = execute(env, trajectory, demo, trace=trace, settle_s=settle_s,
                         frame_hook=FrameHook(overlay, sink, style.every))
        if style.hold_frames and last:
            text, border = outcome_caption(caption, result)
            if not style.caption_reason:
                text = text.split("\n", 1)[0]
            held = _caption(last[0], text if style.caption else None, border=border)
            for _ in range(style.hold_frames):
                for s in sinks:
                    s(held)
            count[0] += style.hold_frames
    finally:
        overlay.close()
    return result, count[0]


def closing_frame(env: Any, trajectory: Any, demo: int, *, demonstration: Any | None = None,
                  style: VideoStyle | None = None, settle_s: float | None = None):
    """Executes ``trajectory`` from demo ``demo``'s start to its horizon and renders only its
    closing frame: the final state, with the demonstration (green), the prediction (orange)
    and the tool's whole path (blue; writing: the ink) drawn in, from the camera a video of
    the rollout would use (writing: the letter; otherwise the path, the hand and the props
    wherever they went).

    Args:
        env: a clfd-bench env (no render mode needed; e.g. ``env_pool.get_env(id)``).
        trajectory: what ``clfd_bench.execution.execute.execute`` takes (data units).
        demo: the demo to reset to.
        demonstration: the demonstration in the same form (optional).
        style: size and look (its caption and hold settings are not used).
        settle_s: seconds of settling after the trajectory (default: the rollout's).

    Returns:
        ``(ExecResult with its trace, frame [H, W, 3] uint8)``.
    """
    import types

    from clfd_bench.execution.execute import execute
    from clfd_bench.execution.trace import tool_path

    style = style or VideoStyle()
    base = env.unwrapped
    result = execute(env, trajectory, demo, trace=True, settle_s=settle_s)
    tr = result.trace
    target = tool_path(base, trajectory)
    static = [(target, PREDICTION_RGBA)]
    if demonstration is not None:
        static.insert(0, (tool_path(base, demonstration), DEMONSTRATION_RGBA))
    moving = [] if _is_writing(base) else [
        _inflate(tr.hand_pos[::style.every], _HAND_REACH), _prop_box_points(base),
        *(_inflate(pose[::style.every, :3], _PROP_REACH) for pose in tr.objects.values())]
    extra = np.concatenate([np.zeros((0, 3)), *moving, *(p for p, _ in static[:-1])])
    camera = _camera_for(base, target, extra, style.width / style.height)
    overlay = OverlayRenderer(base.model, dataclasses.replace(style, caption=False), camera,
                              see_through_bodies(base))
    try:
        overlay.start(static, expected_steps=len(tr.time),
                      lift=_BOARD_LIFT if _is_writing(base) else 0.0)
        flags = [None] * len(tr.time) if tr.tool_down is None else [bool(f) for f in
                                                                    tr.tool_down]
        recorded = types.SimpleNamespace(tool_positions=list(tr.tool_pos),
                                         tool_down_flags=flags)
        frame = overlay(base, recorded)
    finally:
        overlay.close()
    return result, frame
