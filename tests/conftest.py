"""Shared test set-up: no progress bars, deterministic threads."""

from __future__ import annotations

import os

os.environ.setdefault("CLFD_NO_PROGRESS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
