"""Perturbation families do what their names say (hand-checked geometry), and the confusion
table flags exactly the cells that disagree with a family's expectation."""

from __future__ import annotations

import numpy as np
import pytest

from clfd_bench.execution.perturb import (
    FAMILIES,
    PerturbContext,
    family_names,
    min_jerk,
    perturb,
    resample,
)
from clfd_bench.execution.replay import MAX_FALSE_SUCCESS, confusion_table, format_confusion


def _pose_traj(T: int = 200) -> np.ndarray:
    """A quarter circle of radius 0.2 m at z = 0.3 with the hand turning 90° about z."""
    a = np.linspace(0.0, np.pi / 2, T)
    pos = np.column_stack([0.2 * np.cos(a), 0.2 * np.sin(a), np.full(T, 0.3)])
    quat = np.column_stack([np.cos(a / 2), np.zeros(T), np.zeros(T), np.sin(a / 2)])
    return np.hstack([pos, quat])


def _point_traj(T: int = 100) -> np.ndarray:
    return np.column_stack([np.linspace(0.0, 0.1, T), 0.05 * np.sin(np.linspace(0, np.pi, T))])


def test_family_table_and_kinds():
    assert family_names(poses=False) == [f for f in FAMILIES if f != "frozen-orientation"]
    assert family_names(poses=True) == [f for f in FAMILIES if f != "overrun"]
    assert family_names() == list(FAMILIES)
    succeed = [f for f, fam in FAMILIES.items() if fam.expect == "succeed"]
    assert succeed == ["demo", "slower", "faster", "noise", "start-offset"]
    assert len(FAMILIES) - len(succeed) >= 8


def test_resample_slerps_quaternions():
    traj = _pose_traj(3)  # 0°, 45°, 90° about z
    out = resample(traj, 5)
    assert out.shape == (5, 7)
    np.testing.assert_allclose(out[[0, 2, 4]], traj, atol=1e-12)
    # Half-way between 0° and 45°: 22.5° about z, unit norm (a linear blend would not be).
    np.testing.assert_allclose(out[1, 3:], [np.cos(np.pi / 16), 0, 0, np.sin(np.pi / 16)],
                               atol=1e-12)


def test_time_scaling_keeps_the_path():
    traj = _pose_traj()
    slow, fast = perturb("slower", traj), perturb("faster", traj)
    assert len(slow) == 2 * len(traj) - 1 and len(fast) == int(np.ceil(len(traj) / 1.5))
    for out in (slow, fast):
        np.testing.assert_allclose(out[[0, -1]], traj[[0, -1]], atol=1e-12)
        r = np.linalg.norm(out[:, :2], axis=1)
        np.testing.assert_allclose(r, 0.2, atol=1e-3)  # still on the circle (chords of it)


@pytest.mark.parametrize("traj,amp", [(_pose_traj(), 0.01), (_point_traj(), 0.003)])
def test_noise_is_smooth_bounded_and_starts_on_the_demo(traj, amp):
    out = perturb("noise", traj, PerturbContext(demo=3))
    d = out[:, : min(3, traj.shape[1])] - traj[:, : min(3, traj.shape[1])]
    assert np.abs(d).max() == pytest.approx(amp)
    assert np.abs(d[0]).max() == 0.0
    assert np.abs(np.diff(d, axis=0)).max() < amp / 5  # smooth: small per-step change
    again = perturb("noise", traj, PerturbContext(demo=3))
    np.testing.assert_array_equal(out, again)  # seeded by family and demo
    assert not np.array_equal(out, perturb("noise", traj, PerturbContext(demo=4)))


def test_noise_scales_with_data_units():
    traj = _point_traj() * 100.0  # LASA-like units, 0.01 m per unit
    out = perturb("noise", traj, PerturbContext(units_per_m=100.0))
    assert np.abs(out - traj).max() == pytest.approx(0.3)  # 3 mm = 0.3 units


def test_start_offset_leaves_and_rejoins_the_demo():
    traj = _pose_traj()
    out = perturb("start-offset", traj, PerturbContext(demo=1))
    np.testing.assert_allclose(out[0], traj[0])  # begins where the robot is
    assert len(out) == len(traj) + 29
    off = np.linalg.norm(out[29:, :3] - traj[:, :3], axis=1)
    assert off[0] == pytest.approx(0.01) and off.max() == pytest.approx(0.01)
    assert np.all(off[len(traj) // 2:] < 1e-12)


def test_wrong_families_by_hand():
    traj = _pose_traj()
    T = len(traj)
    mirror = perturb("mirror", traj)
    np.testing.assert_allclose(mirror[[0, -1]], traj[[0, -1]], atol=1e-12)
    mid = T // 2
    chord_mid = traj[0, :3] + (mid / (T - 1)) * (traj[-1, :3] - traj[0, :3])
    np.testing.assert_allclose(mirror[mid, :3], 2 * chord_mid - traj[mid, :3], atol=1e-12)
    drift = perturb("drift", traj, PerturbContext(demo=0))
    assert np.linalg.norm(drift[-1, :3] - traj[-1, :3]) == pytest.approx(0.05)
    assert np.linalg.norm(drift[0, :3] - traj[0, :3]) == 0.0
    teleport = perturb("teleport", traj)
    assert np.all(teleport == traj[-1])
    frozen = perturb("frozen-orientation", traj)
    assert np.all(frozen[:, 3:] == traj[0, 3:]) and np.array_equal(frozen[:, :3], traj[:, :3])
    rush = perturb("rush-wait", traj)
    assert len(rush) == T and np.all(rush[T // 10:] == traj[-1])
    short = perturb("shortcut", traj)
    np.testing.assert_allclose(short[:, 2], 0.3)
    assert np.allclose(np.cross(short[:, :3] - traj[0, :3], traj[-1, :3] - traj[0, :3]), 0)
    assert len(perturb("stop-early", traj)) == T // 2
    np.testing.assert_array_equal(perturb("reverse", traj), traj[::-1])


def test_point_drift_is_relative_with_a_floor():
    traj = _point_traj()  # bounding box diagonal ~0.112 m: 15 % is below the 2 cm floor
    out = perturb("drift", traj)
    assert np.linalg.norm(out[-1] - traj[-1]) == pytest.approx(0.02)
    big = traj * 5  # diagonal ~0.56 m: 15 % of it
    diag = np.linalg.norm(big.max(0) - big.min(0))
    assert np.linalg.norm(perturb("drift", big)[-1] - big[-1]) == pytest.approx(0.15 * diag)


def test_overrun_is_the_demo_then_a_straight_run_on_past_its_end():
    # A straight stroke along x, then a quarter circle of radius 5 cm turning to +y: its last
    # 2 cm (the floor: the bounding box is ~0.1 m, 15 % of it is 1.5 cm) is an arc whose chord
    # gives the direction to run on in.
    line = np.column_stack([np.linspace(0.0, 0.05, 50), np.zeros(50)])
    a = np.linspace(0.0, np.pi / 2, 80)[1:]
    arc = np.column_stack([0.05 + 0.05 * np.sin(a), 0.05 - 0.05 * np.cos(a)])
    traj = np.vstack([line, arc])
    out = perturb("overrun", traj)
    np.testing.assert_array_equal(out[: len(traj)], traj)  # the letter itself, unchanged
    run_on = out[len(traj) - 1:]
    assert np.linalg.norm(run_on[-1] - traj[-1]) == pytest.approx(0.02)  # the drift's distance
    # The chord of the last 2 cm of arc: 2 cm of a 5 cm radius subtend 0.4 rad, so its chord
    # points 0.2 rad short of +y, towards +x (the stretch starts at a sample, at most one
    # sample, 0.02 rad of arc, earlier: its chord turns by half of that at most).
    step = run_on[-1] - traj[-1]
    assert np.arctan2(step[0], step[1]) == pytest.approx(0.2, abs=0.0101)
    off = run_on - traj[-1]
    np.testing.assert_allclose(off[:, 0] * step[1] - off[:, 1] * step[0], 0.0, atol=1e-15)
    d = np.linalg.norm(run_on - traj[-1], axis=1)
    assert np.all(np.diff(d) >= 0)  # on away from the end, from rest (min-jerk) ...
    assert d[1] < 0.01 * d[-1]
    # ... over the demo's own time for that stretch (the samples of its last 2 cm).
    arcs = np.concatenate([[0.0], np.linalg.norm(np.diff(traj, axis=0), axis=1).cumsum()])
    k = np.flatnonzero(arcs <= arcs[-1] - 0.02)[-1]  # where the last 2 cm begin
    assert len(run_on) == len(traj) - k  # the end point, then one sample per demo sample
    big = traj * 5  # 15 % of the diagonal above the floor
    diag = np.linalg.norm(big.max(0) - big.min(0))
    assert np.linalg.norm(perturb("overrun", big)[-1] - big[-1]) == pytest.approx(0.15 * diag)
    with pytest.raises(ValueError, match="pen \\(point\\) trajectories only"):
        perturb("overrun", _pose_traj())
    with pytest.raises(ValueError, match="needs a trajectory that moves"):
        perturb("overrun", np.zeros((10, 2)))


def test_min_jerk_profile():
    p = min_jerk(101)
    assert p[0] == 0 and p[-1] == 1 and p[50] == pytest.approx(0.5)
    assert np.all(np.diff(p) >= 0)


def test_errors_name_the_fix():
    with pytest.raises(ValueError, match="unknown perturbation family 'wobble'; valid: "):
        perturb("wobble", _pose_traj())
    with pytest.raises(ValueError, match="7-D pose trajectories only"):
        perturb("frozen-orientation", _point_traj())
    with pytest.raises(ValueError, match="needs PerturbContext.other"):
        perturb("other-task", _point_traj())


def _rec(env, family, success, kind=None):
    return {"env": env, "family": family, "success": success,
            "info": {"failure": {"kind": kind}} if kind else {}}


def test_confusion_table_flags_disagreements():
    rows = ([_rec("clfd/A-v1", "demo", True)] * 20
            + [_rec("clfd/A-v1", "mirror", True)] + [_rec("clfd/A-v1", "mirror", False)] * 19
            + [_rec("clfd/B-v1", "demo", True)] * 19 + [_rec("clfd/B-v1", "demo", False)]
            + [_rec("clfd/B-v1", "teleport", True)] * 2
            + [_rec("clfd/B-v1", "teleport", False, "reflex")] * 18
            + [dict(_rec("clfd/A-v1", "mirror", True), applicable=False)] * 3)
    table = confusion_table(rows)
    assert MAX_FALSE_SUCCESS == 0.05
    assert table["clfd/A-v1"]["demo"]["ok"] and table["clfd/A-v1"]["mirror"]["ok"]  # 1/20 = 5 %
    assert not table["clfd/B-v1"]["demo"]["ok"]  # a must-succeed family failed once
    assert not table["clfd/B-v1"]["teleport"]["ok"]  # 2/20 = 10 % false successes
    assert table["clfd/B-v1"]["teleport"]["failure_kinds"] == {"reflex": 18}
    text = format_confusion(table)
    assert table["clfd/A-v1"]["mirror"]["not_applicable"] == 3
    assert "| A-v1 | 20/20 | 1/20 (3 n/a) | – |" in text
    assert "| B-v1 | 19/20 ✗ | – | 2/20 ✗ |" in text


def _angle_deg(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    return np.degrees(2 * np.arccos(np.clip(np.abs((q0 * q1).sum(-1)), 0.0, 1.0)))


def test_the_nearby_scene_edits_by_hand():
    """The edits every scene must survive (`clfd_bench.envs.robotasks.variants.NEARBY`), on a
    quarter circle of radius 0.2 m: each starts at the demo's start pose, then is the demo
    moved by exactly its amount; the clock edit keeps the path and both ends."""
    from clfd_bench.envs.robotasks.variants import shifted, time_warped, tool_tilted, yawed

    traj = _pose_traj()
    out = shifted((0.005, 0.0, 0.0))(traj)
    np.testing.assert_allclose(out[0], traj[0], atol=1e-12)
    np.testing.assert_allclose(out[20:, :3] - traj[20:, :3], [[0.005, 0, 0]] * 180, atol=1e-12)
    np.testing.assert_allclose(out[:, 3:], traj[:, 3:])
    out = yawed(3.0)(traj)
    np.testing.assert_allclose(out[0], traj[0], atol=1e-12)
    centre = traj[:, :3].mean(0)
    np.testing.assert_allclose(np.linalg.norm(out[:, :3] - centre, axis=1),
                               np.linalg.norm(traj[:, :3] - centre, axis=1), atol=1e-12)
    heading = np.arctan2(*(out[-1, 1::-1] - centre[1::-1]))
    heading0 = np.arctan2(*(traj[-1, 1::-1] - centre[1::-1]))
    assert np.degrees(heading - heading0) == pytest.approx(3.0)
    np.testing.assert_allclose(_angle_deg(out[50:, 3:], traj[50:, 3:]), 3.0, atol=1e-6)
    out = tool_tilted(3.0, (1.0, 0.0, 0.0))(traj)
    np.testing.assert_allclose(out[:, :3], traj[:, :3])
    np.testing.assert_allclose(_angle_deg(out[50:, 3:], traj[50:, 3:]), 3.0, atol=1e-6)
    out = time_warped(1.4)(traj)
    np.testing.assert_allclose(out[[0, -1]], traj[[0, -1]], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(out[:, :2], axis=1), 0.2, atol=1e-5)
    assert np.linalg.norm(out[100, :2] - traj[0, :2]) < np.linalg.norm(traj[100, :2]
                                                                       - traj[0, :2])


def test_the_scene_mistakes_by_hand():
    """`and_back`: the demo, then back along it to its start; `end_raised`: the end higher."""
    from clfd_bench.envs.robotasks.variants import and_back, end_raised

    traj = _pose_traj()
    out = and_back(0.3)(traj)
    np.testing.assert_allclose(out[[0, -1]], traj[[0, 0]], atol=1e-12)
    np.testing.assert_allclose(out[139], traj[-1], atol=1e-12)  # the end at 70 %
    np.testing.assert_allclose(np.linalg.norm(out[:, :2], axis=1), 0.2, atol=1e-5)
    out = end_raised(0.10)(traj)
    assert out[-1, 2] == pytest.approx(traj[-1, 2] + 0.10) and out[0, 2] == traj[0, 2]
