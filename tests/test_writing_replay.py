"""Writing envs decide success by the ink, as an observer would: demos and good-but-imperfect
variants succeed, wrong trajectories fail (a small subset of
`clfd-bench replay --env writing --perturb all`), and the text env lifts the pen between
letters."""

from __future__ import annotations

import argparse
import json

import gymnasium as gym
import numpy as np
import pytest

import clfd_bench  # noqa: F401
from clfd_bench.cli import replay as replay_cli
from clfd_bench.envs.writing import ink_strokes
from clfd_bench.execution.replay import replay
from clfd_bench.execution.rollout import rollout

LETTERS = ("clfd/HelloWorld-l-v3", "clfd/HelloWorld-h-v3")


@pytest.fixture(scope="module", params=LETTERS)
def letter_env(request):
    env = gym.make(request.param)
    yield request.param, env
    env.close()


def test_demo_succeeds_with_every_check_passing(letter_env):
    env_id, env = letter_env
    (rec,) = replay(env_id, [3], "demo", env=env)
    assert rec.success and rec.info["failed"] == [], rec.info
    tol = rec.info["tolerances"]
    assert rec.info["hausdorff"] < 0.2 * tol["hausdorff"]
    assert rec.info["coverage"] == 1.0
    assert rec.info["dwell"] <= tol["max_dwell"]
    assert rec.max_tracking_error_m < 1e-3
    checks = rec.info["checks"]
    assert [c["name"] for c in checks] == ["ink_fraction", "dtw", "hausdorff", "coverage",
                                           "goal", "dwell"]
    assert all(c["passed"] for c in checks)
    (goal,) = [c for c in checks if c["name"] == "goal"]
    assert goal["value"] == pytest.approx(rec.info["goal_distance"])  # letters: m = data units
    assert goal["bound"] == pytest.approx(tol["goal_tolerance"]) and goal["unit"] == "m"


@pytest.mark.parametrize("family,demo,end_m", [("drift", 2, 0.0223), ("overrun", 0, 0.0235)])
def test_the_end_check_alone_fails_drift_and_overrun_on_w(family, demo, end_m):
    # 'w' (14.8 cm): a drift of 2.2 cm stays within its 2.6 cm Hausdorff tolerance, and the
    # overrun draws the demo's own 'w' before it runs on 2.35 cm; both end beyond the 1.48 cm
    # end bound, and only the end check sees it. HN `full` seed 1's 'w' (2.0 cm past,
    # docs/execution.md "Running on past the end") is the overrun's case: a rule that forgave
    # running on would pass this must-fail family too.
    env = gym.make("clfd/HelloWorld-w-v3")
    (rec,) = replay("clfd/HelloWorld-w-v3", [demo], family, env=env)
    env.close()
    assert rec.info["failed"] == ["goal"], rec.info["failed"]
    (goal,) = [c for c in rec.info["checks"] if c["name"] == "goal"]
    assert goal["value"] == pytest.approx(end_m, abs=5e-4) and goal["value"] > 1.4 * goal["bound"]


def test_a_pen_that_runs_on_past_the_end_fails_the_end_check(letter_env):
    # `overrun`: the demo itself, then 15 % of the letter's size (>= 2 cm) on past its end.
    # The end point is where the pen stops: past the end fails as short of it does.
    env_id, env = letter_env
    (rec,) = replay(env_id, [3], "overrun", env=env)
    assert not rec.success and "goal" in rec.info["failed"], rec.info
    (goal,) = [c for c in rec.info["checks"] if c["name"] == "goal"]
    assert goal["value"] > 1.2 * goal["bound"]


@pytest.mark.parametrize("family", ["shortcut", "rush-wait", "mirror"])
def test_wrong_shapes_fail_on_their_shape(letter_env, family):
    # Before v1, a straight stroke passed 'l' on 3/8 demos and rushing to the end and waiting
    # passed 'l' on 3/8 and 'h' on 1/8 (the summed DTW is lenient).
    env_id, env = letter_env
    (rec,) = replay(env_id, [3], family, env=env)
    assert not rec.success, rec.info
    if rec.info.get("failure") is None:  # judged on the ink (not stopped by a reflex)
        assert "hausdorff" in rec.info["failed"], rec.info


def test_slower_noisy_and_offset_letters_succeed():
    env = gym.make("clfd/HelloWorld-l-v3")
    for family in ("slower", "noise", "start-offset"):
        (rec,) = replay("clfd/HelloWorld-l-v3", [5], family, env=env)
        assert rec.success, (family, rec.info)
    env.close()


def _similar(demo: np.ndarray, shift: float, scale: float, degrees: float) -> np.ndarray:
    """Demo [T, 2] shifted along x, scaled about its start and turned about its centroid, after a
    0.5 s min-jerk move from the demo's start to the variant's (as `start-offset` leaves it)."""
    from clfd_bench.execution.perturb import min_jerk

    a = np.radians(degrees)
    turn = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    out = demo[0] + (demo - demo[0]) * scale
    out = out.mean(axis=0) + (out - out.mean(axis=0)) @ turn.T + [shift, 0.0]
    move = demo[0] + min_jerk(30)[:, None] * (out[0] - demo[0])
    return np.concatenate([move, out[1:]])


@pytest.mark.parametrize("shift,scale,degrees", [(0.005, 1.0, 0.0), (0.0, 1.07, 0.0),
                                                 (0.0, 0.93, 0.0), (0.0, 1.0, 3.0)],
                         ids=["5mm-aside", "7pc-larger", "7pc-smaller", "turned-3deg"])
def test_the_same_letter_written_a_little_aside_larger_or_turned_succeeds(letter_env, shift,
                                                                           scale, degrees):
    # Variants no replay family makes (2026-12-07: all 56 demos of the 7 letters succeed for
    # each, docs/execution.md): a reader sees the same letter, so the criterion must too.
    env_id, env = letter_env
    demo = np.asarray(env.unwrapped.demos[3], float)
    result = rollout(env, _similar(demo, shift, scale, degrees), demo=3)
    assert result.success, result.info.get("failed")


def test_lasa_demo_succeeds_and_its_mirror_fails():
    env = gym.make("clfd/LASA-Sine-v3")
    (ok,) = replay("clfd/LASA-Sine-v3", [0], "demo", env=env)
    assert ok.success, ok.info
    (bad,) = replay("clfd/LASA-Sine-v3", [0], "mirror", env=env)
    assert not bad.success and "hausdorff" in bad.info["failed"], bad.info
    env.close()


def test_text_env_lifts_the_pen_between_letters():
    env = gym.make("clfd/HelloWorld-v3", text="he")
    base = env.unwrapped
    result = rollout(env, base.demo_trajectory(1), demo=1)
    info = result.info
    assert result.success and info["strokes"] == 2, info
    names = [c["name"] for c in info["checks"]]
    assert names[:3] == ["strokes", "ink_fraction", "stray_ink"]
    assert names[3:] == [f"letter {k} ({c}): {n}" for k, c in enumerate("he")
                         for n in ("dtw", "hausdorff", "coverage", "goal", "dwell")]
    assert all(c["passed"] for c in info["checks"])
    (goal_e,) = [c for c in info["checks"] if c["name"] == "letter 1 (e): goal"]
    # letter units (m before the text's 0.3 scale) -> m on the board
    assert goal_e["value"] == pytest.approx(0.3 * info["letter_goal_distance"][1])
    assert goal_e["bound"] == pytest.approx(0.3 * base.tolerances["e"].goal_tolerance)
    assert max(info["letter_dtw"]) < 1.0
    # No connecting ink: the ink drawn while the pen is commanded up is at most a dot where
    # it leaves / meets the board, and the two ink strokes are the two letters.
    flags = np.array(base._ink_flags)
    down = np.array(base._commanded_down[: len(flags)])
    xy = base.pen_path()
    assert info["stray_ink"] < 1e-3
    strokes = ink_strokes(flags)
    assert len(strokes) == 2
    a, b = strokes[0][1], strokes[1][0]  # the gap between the letters
    assert not down[a:b].any() and np.linalg.norm(xy[b] - xy[a - 1]) > 0.02
    (rev,) = replay("clfd/HelloWorld-v3", [1], "reverse", env=env)
    assert not rev.success
    env.close()


def test_replay_cli_json(capsys, tmp_path):
    out = tmp_path / "t.json"
    args = argparse.Namespace(env=["clfd/HelloWorld-l-v3"], demos="1", perturb="stop-early",
                              settle=0.5, json=str(out), verbose=False)
    assert replay_cli._run(args) == 0
    doc = json.loads(out.read_text())
    (row,) = doc["results"]
    assert row["demo"] == 1 and row["family"] == "stop-early" and row["success"] is False
    assert "goal" in row["info"]["failed"]  # 'l' cut at half: only the end check sees it
    (goal,) = [c for c in row["info"]["checks"] if c["name"] == "goal"]
    assert goal["value"] > 2 * goal["bound"]  # 4.9 cm against 1.76 cm


def test_replay_rejects_bad_demo_index():
    with pytest.raises(ValueError, match="has demos 0..7"):
        replay("clfd/HelloWorld-h-v3", [8])
