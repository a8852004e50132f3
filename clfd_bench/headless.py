"""Offscreen rendering on a machine without a display: MuJoCo's OpenGL backend by default.

MuJoCo chooses its OpenGL platform from ``MUJOCO_GL`` when it is first imported and falls back
to GLFW, which needs an X or Wayland display. On a headless Linux machine (a server, CI, a
container) every video then fails with "an OpenGL platform library has not been loaded", and
the main job learns that only after its training (2026-12-07: 15 minutes in). ``import
clfd_bench`` calls :func:`default_gl_backend` before anything imports MuJoCo, which picks EGL
there (offscreen, GPU or Mesa's software driver). A ``MUJOCO_GL`` the user set always wins, as
does a display; nothing changes once MuJoCo is imported (its choice is made).
"""

from __future__ import annotations

import os
import sys

__all__ = ["HEADLESS_GL", "default_gl_backend"]

#: The backend chosen on a headless Linux machine.
HEADLESS_GL = "egl"


def default_gl_backend() -> str | None:
    """Sets ``MUJOCO_GL`` to :data:`HEADLESS_GL` on Linux when it is unset, no display is
    (``DISPLAY``, ``WAYLAND_DISPLAY``) and MuJoCo is not imported yet. Returns the value of
    ``MUJOCO_GL`` afterwards (None: unset, MuJoCo's own default)."""
    if (sys.platform.startswith("linux") and not os.environ.get("MUJOCO_GL")
            and not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY")
            and "mujoco" not in sys.modules):
        os.environ["MUJOCO_GL"] = HEADLESS_GL
    return os.environ.get("MUJOCO_GL") or None
