"""Start-position study: starts are uniform in the ball's volume and reproducible, end Δ and
"Large" on hand-made predictions, diverged predictions fail without raising, and an end-to-end
smoke study (one RoboTasks task, 3 starts) writes its files, reproduces the prediction from the
demo's start at start Δ = 0 and skips finished work when run again."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from clfd_bench.studies import start_robustness as sr

R = 0.2


def test_sample_ball_is_uniform_in_volume_and_seeded():
    pts = sr.sample_ball(np.random.default_rng(0), 40_000, R, centre=np.array([1.0, 2.0, 3.0]))
    r = np.linalg.norm(pts - [1.0, 2.0, 3.0], axis=1)
    assert r.max() <= R
    # Uniform in volume: P(r <= s) = (s/R)^3, mean radius 3/4 R (on a sphere's surface it would
    # be R, uniform in radius R/2).
    assert abs(r.mean() - 0.75 * R) < 0.005 * R
    assert abs(np.mean(r <= R / 2) - 1 / 8) < 0.01
    assert np.all(np.abs(pts.mean(axis=0) - [1.0, 2.0, 3.0]) < 0.01 * R)  # no direction bias
    again = sr.sample_ball(np.random.default_rng(0), 40_000, R, centre=np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(pts, again)


def test_draw_starts_reproducible_and_prefix_stable():
    c = np.array([0.4, -0.2, 0.3])
    a = sr.draw_starts(0, "openbox", c, 50, R)
    np.testing.assert_array_equal(a, sr.draw_starts(0, "openbox", c, 50, R))
    np.testing.assert_array_equal(a[:10], sr.draw_starts(0, "openbox", c, 10, R))
    assert np.linalg.norm(a - c, axis=1).max() <= R
    assert not np.allclose(a, sr.draw_starts(1, "openbox", c, 50, R))
    assert not np.allclose(a, sr.draw_starts(0, "pouring", c, 50, R))
    assert sr.choose_demo(0, "openbox", 9) == sr.choose_demo(0, "openbox", 9)


def test_end_deltas_and_large_on_hand_made_predictions():
    goal = np.array([0.5, 0.0, 0.2, 1.0, 0.0, 0.0, 0.0])
    preds = np.zeros((4, 3, 7))
    preds[:, :, 3] = 1.0
    preds[0, -1, :3] = goal[:3] + [0.3, 0.4, 0.0]      # 0.5 m
    preds[1, -1, :3] = goal[:3]                         # 0
    preds[2, -1, :3] = goal[:3] + [0.0, 0.0, 1.5]      # 1.5 m: Large
    preds[3, 1:, :3] = np.nan                           # diverged
    d = sr.end_deltas(preds, goal)
    np.testing.assert_allclose(d[:3], [0.5, 0.0, 1.5])
    assert math.isinf(d[3])
    assert list(d > sr.LARGE_M) == [False, False, True, True]
    assert not sr.diverged(preds[0])
    assert sr.diverged(preds[3])
    far = preds[0].copy()
    far[1, 0] = 1e3
    assert sr.diverged(far)


def test_diverged_prediction_fails_without_executing():
    pred = np.full((5, 7), np.nan)
    res = sr.execute(None, 0, np.zeros(7), pred, 0.1)  # env is never touched
    assert (res["success"], res["approach_steps"]) == (False, 0) and "diverged" in res["failure"]


def test_approach_path_moves_smoothly_at_bounded_speed():
    q = np.array([0.0, 1.0, 0.0, 0.0])
    a = np.concatenate([[0.3, 0.0, 0.4], q])
    b = np.concatenate([[0.3, 0.2, 0.4], q])
    path = sr.approach_path(a, b, speed=0.1)
    assert len(path) == 120  # 0.2 m at a mean 0.1 m/s, 60 Hz
    np.testing.assert_allclose(path[0], a)
    steps = np.linalg.norm(np.diff(np.vstack([path[:, :3], b[:3]]), axis=0), axis=1)
    assert steps.max() * 60 < 0.1 * np.pi / 2 + 1e-9  # cosine profile: peak = pi/2 x mean
    assert len(sr.approach_path(a, a + [5e-5, 0, 0, 0, 0, 0, 0], speed=0.1)) == 0


@pytest.fixture(scope="module")
def smoke_study(tmp_path_factory):
    from clfd_bench.cli.main import main

    out = tmp_path_factory.mktemp("start")
    argv = ["study", "start", "--methods", "sg", "--profile", "smoke", "--seed", "0",
            "--tasks", "1", "--starts", "3", "--out", str(out)]
    assert main(argv) == 0
    return out, argv


def test_smoke_study_outputs_and_reference(smoke_study):
    from clfd_bench.data import load_dataset
    from clfd_bench.harness.protocol import load_learner
    from clfd_bench.leaderboard.grid import RunSpec

    out, _ = smoke_study
    for name in ("records.csv", "records.json", "summary.md", "summary.csv", "summary.json",
                 "start_robustness.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    records = json.loads((out / "records.json").read_text())
    assert [r["start_index"] for r in records] == [sr.REFERENCE, 0, 1, 2]
    assert {r["method"] for r in records} == {"sg"} and {r["task"] for r in records} == {"openbox"}
    assert all(isinstance(r["success"], bool) for r in records)
    ref = records[0]
    assert ref["start_delta_m"] == 0.0 and ref["approach_steps"] == 0
    assert all(0 < r["start_delta_m"] <= R for r in records[1:])
    assert all(r["approach_steps"] > 0 for r in records[1:])
    # The openbox outcome reports the lid angle; a failed start names its reason.
    assert all("lid_angle_deg" in r["outcome"] for r in records)
    assert all(r["success"] or r["failure"] for r in records)
    # Start Δ = 0 is the prediction from the demo's own start, as the harness makes it.
    task = load_dataset("robotasks").tasks[0]
    run_dir = RunSpec("robotasks", "sg", "smoke", 0, tasks=1, sim=False).run_dir(out)
    learner, _ = load_learner(run_dir)
    demo = ref["demo"]
    assert demo == sr.choose_demo(0, "openbox", task.demos.shape[0])
    goals = learner.demo_goals(task)[demo:demo + 1]
    pred = learner.predict(0, task.demos[demo, :1], task.times, goals)
    expected = float(np.linalg.norm(pred[0, -1, :3] - task.goal[:3]))
    assert ref["end_delta_m"] == pytest.approx(expected, rel=1e-6)
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary) == 1 and summary[0]["n"] == 3
    assert summary[0]["ref_end_cm"] == pytest.approx(100 * expected, rel=1e-6)


def test_smoke_study_rerun_uses_the_cache(smoke_study, monkeypatch):
    from clfd_bench.cli.main import main

    out, argv = smoke_study
    before = (out / "records.json").read_text()

    def no_rollouts(*args, **kwargs):
        raise AssertionError("a finished start was executed again")

    monkeypatch.setattr(sr, "execute", no_rollouts)
    assert main(argv) == 0
    assert (out / "records.json").read_text() == before


def test_missing_run_dir_says_what_to_run(tmp_path, capsys):
    from clfd_bench.cli.main import main

    assert main(["study", "start", "--run", str(tmp_path / "nope"), "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "not a trained run" in err and "clfd-bench train" in err
    assert "--dataset robotasks|lasa" in err  # either study dataset, not only RoboTasks
    assert main(["study", "start", "--methods", "nosuch", "--out", str(tmp_path / "o")]) == 2


# --------------------------------------------------------------------------- LASA
def test_sample_disc_is_uniform_in_area():
    pts = sr.sample_ball(np.random.default_rng(0), 40_000, R, centre=np.array([1.0, 2.0]))
    r = np.linalg.norm(pts - [1.0, 2.0], axis=1)
    assert pts.shape == (40_000, 2) and r.max() <= R
    # Uniform in area: P(r <= s) = (s/R)^2, mean radius 2/3 R.
    assert abs(r.mean() - 2 / 3 * R) < 0.005 * R
    assert abs(np.mean(r <= R / 2) - 1 / 4) < 0.01
    # The 3-D default draws the same starts as before the dimension became a parameter.
    np.testing.assert_array_equal(
        sr.sample_ball(np.random.default_rng(3), 5, R, centre=np.zeros(3)),
        sr.sample_ball(np.random.default_rng(3), 5, R))


def test_planar_end_deltas_in_metres_and_horizon_times():
    scale = 0.003  # m per LASA unit
    preds = np.zeros((2, 4, 2))
    preds[0, -1] = [3.0, 4.0]          # 5 units = 1.5 cm from the goal (0, 0)
    preds[1, 2:] = np.inf
    d = sr.end_deltas(preds, np.zeros(2), pos_dim=2, scale=scale)
    assert d[0] == pytest.approx(0.015) and math.isinf(d[1])
    assert sr.diverged(preds[1], 2, scale) and not sr.diverged(preds[0], 2, scale)
    far = preds[0].copy()
    far[1] = [4000.0, 0.0]             # 12 m on the table
    assert sr.diverged(far, 2, scale)
    t = np.arange(5) * 0.25
    np.testing.assert_allclose(sr.horizon_times(t, 3.0), np.arange(13) * 0.25)
    assert sr.horizon_times(t, 1.0) is not None and len(sr.horizon_times(t, 1.0)) == 5
    with pytest.raises(ValueError, match="horizon"):
        sr.StudyConfig(horizon=0.5)


def test_settle_times_on_hand_made_predictions():
    """Settled = within SETTLE_M of the goal from that sample on, in multiples of the demo's
    duration; a prediction that leaves the ball again has not settled until it is back for
    good; the last sample outside (or NaN) means it did not settle."""
    scale = 0.01  # m per unit: the 1 cm ball is 1 unit
    times = np.arange(6) * 0.5             # 0 .. 2.5 s
    preds = np.zeros((5, 6, 2))
    preds[0, :, 0] = [5, 3, 0.5, 0.2, 0, 0]   # in from sample 2: 1.0 s
    preds[1, :, 0] = [5, 0.5, 2, 0.9, 0.1, 0]  # in at 1, out at 2, in for good from 3: 1.5 s
    preds[2, :, 0] = [5, 4, 3, 2, 1.5, 1.2]    # never within: inf
    preds[3, :, 1] = [0.3, 0.3, 0.3, 0.3, 0.3, 0.3]  # always within: 0
    preds[4, :, 0] = [5, 0.5, 0.5, 0.5, 0.5, np.nan]  # NaN at the end: inf
    t = sr.settle_times(preds, np.zeros(2), times, duration=0.5, pos_dim=2, scale=scale)
    np.testing.assert_allclose(t[:2], [2.0, 3.0])  # 1.0 s and 1.5 s over a 0.5 s demo
    assert math.isinf(t[2]) and t[3] == 0.0 and math.isinf(t[4])
    with pytest.raises(ValueError, match="samples"):
        sr.settle_times(preds, np.zeros(2), times[:4], duration=0.5, pos_dim=2)
    rec = sr.StartRecord("m", "t", 0, 0, 0.1, 0.2, False, settle_time=math.inf)
    assert rec.to_json()["settle_time"] is None
    assert math.isinf(sr.StartRecord.from_json(rec.to_json()).settle_time)


def test_lasa_study_with_nodes_and_horizon(tmp_path, capsys, monkeypatch):
    """Two runs on LASA's first shape, NODE^T and sNODE, labelled apart; end Δ in metres on
    the table from starts in the disc; the horizon lengthens the prediction; execution is
    refused on LASA with what to do."""
    from clfd_bench.cli.main import main
    from clfd_bench.data import load_dataset
    from clfd_bench.harness.protocol import load_learner
    from clfd_bench.leaderboard.grid import RunSpec

    out = tmp_path / "lasa"
    base = ["study", "start", "--dataset", "lasa", "--methods", "hn", "--nodes", "t,s",
            "--profile", "smoke", "--tasks", "1", "--starts", "4", "--out", str(out)]
    assert main(base) == 2  # executing is refused, nothing studied
    err = capsys.readouterr().err
    assert "--no-exec" in err and not (out / "runs").exists()  # refused before training
    assert main([*base, "--no-exec", "--horizon", "3"]) == 0
    records = json.loads((out / "records.json").read_text())
    assert {r["method"] for r in records} == {"hn", "hn (sNODE)"}
    assert all(r["success"] is None for r in records)
    task = load_dataset("lasa").tasks[0]
    ref = next(r for r in records if r["method"] == "hn (sNODE)" and r["start_index"] == -1)
    starts = [r for r in records if r["start_index"] >= 0]
    assert all(0 < r["start_delta_m"] <= R + 1e-9 for r in starts)
    assert all(len(r["start"]) == 2 for r in records)
    run_dir = RunSpec("lasa", "hn", "smoke", 0, node="s", tasks=1, sim=False).run_dir(out)
    import torch

    monkeypatch.delenv("CLFD_THREADS", raising=False)
    torch.set_num_threads(2)
    load_learner(run_dir, threads=2)
    assert torch.get_num_threads() == 2
    learner, _ = load_learner(run_dir)  # predictions run on one thread unless told otherwise
    assert torch.get_num_threads() == 1
    times = sr.horizon_times(task.times, 3.0)
    assert len(times) == 3 * (len(task.times) - 1) + 1
    pred = learner.predict(0, task.demos[ref["demo"], :1], times)
    expected = float(np.linalg.norm(pred[0, -1] - task.goal)) * task.sim_scale
    assert ref["end_delta_m"] == pytest.approx(expected, rel=1e-5)
    dist = np.linalg.norm(pred[0] - task.goal, axis=1) * task.sim_scale
    outside = np.flatnonzero(dist > sr.SETTLE_M)
    if outside.size and outside[-1] == len(times) - 1:
        assert ref["settle_time"] is None
    else:
        first = 0 if not outside.size else outside[-1] + 1
        duration = task.times[-1] - task.times[0]
        assert ref["settle_time"] == pytest.approx((times[first] - times[0]) / duration)
    assert (out / "start_settling.png").stat().st_size > 0
    assert (out / "start_overview.png").stat().st_size > 0


def test_only_studies_the_named_learned_tasks(tmp_path, capsys):
    """--only restricts the study to learned tasks; a misspelt name is refused before anything
    is trained (with the closest name), a real task the runs did not learn after."""
    from clfd_bench.cli.main import main

    out = tmp_path / "only"
    base = ["study", "start", "--dataset", "lasa", "--methods", "sg", "--profile", "smoke",
            "--tasks", "2", "--starts", "2", "--no-exec", "--out", str(out)]
    assert main([*base, "--only", "BendedLin"]) == 2
    err = capsys.readouterr().err
    assert "--only 'BendedLin'" in err and "did you mean 'BendedLine'?" in err
    assert not out.exists()  # refused before training
    assert main([*base, "--only", "BendedLine"]) == 0
    records = json.loads((out / "records.json").read_text())
    assert {r["task"] for r in records} == {"BendedLine"} and len(records) == 3
    assert main([*base, "--only", "CShape"]) == 2  # a LASA shape, not learned by these runs
    assert "not learned by every run" in capsys.readouterr().err
