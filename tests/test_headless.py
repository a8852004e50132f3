"""On a Linux machine without a display, `import clfd_bench` makes MuJoCo render offscreen
(EGL) when MUJOCO_GL is unset, and leaves a user's choice or a display alone."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux only")

_RENDER = """
import os, clfd_bench, mujoco
print("MUJOCO_GL", os.environ.get("MUJOCO_GL"))
model = mujoco.MjModel.from_xml_string(
    "<mujoco><worldbody><light pos='0 0 1'/><geom size='0.1'/></worldbody></mujoco>")
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
with mujoco.Renderer(model, 32, 32) as renderer:
    renderer.update_scene(data)
    print("lit pixels", int((renderer.render() > 0).any(axis=2).sum()))
"""


def _run(code: str, **env: str | None) -> subprocess.CompletedProcess:
    full = {k: v for k, v in os.environ.items()
            if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY")}
    full.update({k: v for k, v in env.items() if v is not None})
    return subprocess.run([sys.executable, "-c", code], env=full, capture_output=True,
                          text=True, timeout=120)


def test_a_headless_machine_renders_without_mujoco_gl():
    # Without the default, MuJoCo falls back to GLFW, which needs a display: the first
    # Renderer raises "an OpenGL platform library has not been loaded" (checked on this
    # machine, 2026-12-07: the main job's video, after its training).
    out = _run(_RENDER)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "MUJOCO_GL egl" in out.stdout
    lit = int(out.stdout.split("lit pixels")[1])
    assert lit > 0  # a real picture, not an empty buffer


def test_the_default_without_it_fails_here():
    """The negative control: the same script with MuJoCo imported first (so the default comes
    too late) cannot render on this display-less machine."""
    out = _run("import mujoco\n" + _RENDER)
    assert "MUJOCO_GL None" in out.stdout
    assert out.returncode != 0 and "OpenGL" in out.stderr


@pytest.mark.parametrize("env,expected", [({"MUJOCO_GL": "osmesa"}, "osmesa"),
                                          ({"DISPLAY": ":0"}, "None"),
                                          ({"WAYLAND_DISPLAY": "wayland-0"}, "None")])
def test_a_users_choice_or_a_display_is_left_alone(env, expected):
    out = _run("import os, clfd_bench; print(os.environ.get('MUJOCO_GL'))", **env)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == expected
