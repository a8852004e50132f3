"""Captions: the text drawn into a video's frames (the run, the task, the outcome) and the
outcome's border."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from clfd_bench.viz.style import FAILURE_RGB, SUCCESS_RGB

__all__ = ["method_label", "outcome_caption", "outcome_text", "run_caption"]


@functools.lru_cache(maxsize=4)
def _font(size: int):
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def _wrap(draw: Any, line: str, font: Any, width: int) -> list[str]:
    """``line`` broken at spaces (a word longer than ``width`` at a character) into lines of
    at most ``width`` pixels in ``font``: nothing is cut off."""
    out: list[str] = []
    current = ""
    for word in line.split(" "):
        trial = f"{current} {word}" if current else word
        if draw.textlength(trial, font=font) <= width:
            current = trial
            continue
        if current:
            out.append(current)
        current = word
        while draw.textlength(current, font=font) > width and len(current) > 1:
            cut = len(current) - 1
            while cut > 1 and draw.textlength(current[:cut], font=font) > width:
                cut -= 1
            out.append(current[:cut])
            current = current[cut:]
    out.append(current)
    return out


def _caption(frame: np.ndarray, text: str | None,
             border: tuple[int, int, int] | None = None) -> np.ndarray:
    """``frame`` with ``text`` (if any; one line per ``\\n``, each wrapped at the frame's
    width, never cut) in its top-left corner on a dark veil, and an optional coloured
    border."""
    from PIL import Image, ImageDraw

    out = frame.copy()
    if text:
        img = Image.fromarray(frame)
        draw = ImageDraw.Draw(img)
        font = _font(max(10, frame.shape[0] // 24))
        pad = max(3, frame.shape[0] // 60) + 3  # clear of the border
        lines = [part for line in text.split("\n")
                 for part in _wrap(draw, line, font, frame.shape[1] - 2 * pad - 6)]
        fitted = "\n".join(lines)
        x0, y0, x1, y1 = draw.multiline_textbbox((pad, pad), fitted, font=font)
        # a dark veil, not an opaque box: a long reason wrapped over a small tile leaves the
        # scene visible under it
        box = np.s_[max(0, y0 - 2):y1 + 3, max(0, x0 - 3):x1 + 4]
        veiled = out.copy()
        veiled[box] = (veiled[box].astype(np.float32) * 0.35).astype(np.uint8)
        img = Image.fromarray(veiled)
        ImageDraw.Draw(img).multiline_text((pad, pad), fitted, fill=(255, 255, 255), font=font)
        out = np.asarray(img).copy()
    if border is not None:
        w = max(3, frame.shape[0] // 60)
        out[:w], out[-w:], out[:, :w], out[:, -w:] = border, border, border, border
    return out


def method_label(method: str) -> str:
    """How a video names a run's method (its ``config.method``): the registry name upper-cased
    ("hn" -> "HN"); a plugin named by an import spec (``pkg.mod:MyMethod``) by its class."""
    return method.rsplit(":", 1)[-1] if ":" in method else method.upper()


def outcome_text(result: Any) -> tuple[str, str]:
    """``(short, reason)`` of an :class:`~clfd_bench.execution.execute.ExecResult`:
    ``("success", "")``, or ``("failed (<kind>)", <the env's reason>)`` with the kind of
    :data:`~clfd_bench.execution.execute.FAILURE_KINDS` (reflex, tracking, task, ...)."""
    if result.success:
        return "success", ""
    return f"failed ({result.failure_kind or 'unknown'})", str(result.failure_reason or "")


def outcome_caption(caption: str, result: Any) -> tuple[str, tuple[int, int, int]]:
    """The text and border colour of a rollout's held closing frames: ``caption · success``
    (green), or ``caption · failed (<kind>)`` and on a second line the env's reason (red)."""
    short, reason = outcome_text(result)
    text = f"{caption} · {short}" if caption else short
    if reason:
        text += f"\n{reason}"
    return text, SUCCESS_RGB if result.success else FAILURE_RGB


def run_caption(run: Any, what: str, demo: int) -> str:
    """``HN · task 3 'l' · demo 0``: the run's method (its config), what is executed, the
    demo; ``· after task i`` when the run has not learned all its tasks yet."""
    parts = [_run_label(run), what, f"demo {demo}"]
    if not run.complete:
        parts.append(f"after task {run.num_learned - 1} of {len(run.task_names)}")
    return " · ".join(parts)


def _run_label(run: Any) -> str:
    """A run in a caption: its method (:func:`method_label`), or its folder's name when the
    run records none."""
    return method_label(run.method) if run.method else run.path.name
