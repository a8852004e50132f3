"""Shared helpers for the issue-15 analysis scripts (RoboTasks9 new tasks).

The scripts import this module as `common`: Python puts a script's own directory first on
sys.path, so `python docs/design/robotasks9/scripts/NAME.py` finds it from any directory.
"""
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
import numpy as np
from scipy.spatial.transform import Rotation as R

from clfd_bench.data.loaders import load_dataset

GRASP_OFFSET = 0.1034
HZ = 60.0
NEW = ["matfolding", "obstaclerotate", "pan2stove", "scoop", "wineglass"]


def out_dir():
    """Where scripts write files: $RT9_OUT, else <repo>/results/robotasks9 (git-ignored)."""
    default = Path(__file__).resolve().parents[4] / "results" / "robotasks9"
    d = Path(os.environ.get("RT9_OUT") or default)
    d.mkdir(parents=True, exist_ok=True)
    return d


def tasks():
    ds = load_dataset("robotasks9")
    return {n: ds.tasks[ds.task_names.index(n)] for n in ds.task_names}


def rot(quat_wxyz):
    q = np.asarray(quat_wxyz)
    return R.from_quat(q[..., [1, 2, 3, 0]].reshape(-1, 4))


def mats(quat_wxyz):
    q = np.asarray(quat_wxyz)
    return rot(q).as_matrix().reshape(q.shape[:-1] + (3, 3))


def grasp(pos, quat):
    """grasp point = hand origin + 0.1034 m along the hand's z axis."""
    m = mats(quat)
    return pos + GRASP_OFFSET * m[..., :, 2]
