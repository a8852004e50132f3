"""The harness's lean rollout (the whole command stream planned before the physics,
`PandaEnv.plan_commands` / `run_plan`) gives what calling Gymnasium's `step` on each action
gives, to the last bit: the final physics state, the verdict and every info value, the failure
and its step, the per-step tracking record, and the env's own state afterwards (the IK tracker,
the command monitor), on demo replays and on must-fail trajectories that end in each kind of
failure. And the batched command check agrees with the per-step check on every command."""

from __future__ import annotations

import hashlib
import json
import pickle
from pathlib import Path

import mujoco
import numpy as np
import pytest

import clfd_bench  # noqa: F401
from clfd_bench.execution.env_pool import get_env
from clfd_bench.execution.replay import replay_trajectory
from clfd_bench.execution.rollout import plain_env, rollout
from clfd_bench.execution.trace import tracer
from clfd_bench.sim.limits import MotionMonitor, panda_limits


def _physics(base) -> np.ndarray:
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(base.model, spec))
    mujoco.mj_getState(base.model, base.data, state, spec)
    return state


def _same(a, b) -> bool:
    """Equal to the last bit (NaN equal to NaN), through dicts, lists and arrays."""
    return pickle.dumps(a) == pickle.dumps(b) or _equal(a, b)


def _equal(a, b) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (a != a and b != b)
    return type(a) is type(b) and a == b


def _both(env, traj, demo=0, **kwargs):
    """The rollout stepped through `env.step` and the lean one, with what each leaves behind."""
    out = []
    base = env.unwrapped
    for lean in (False, True):
        r = rollout(env, traj, demo=demo, lean=lean, **kwargs)
        out.append({"success": r.success, "steps": r.steps, "info": json.dumps(r.info,
                    sort_keys=True, default=repr), "stopped": r.stopped_early,
                    "ee": r.ee_path, "err": (r.tracking_error_pos, r.tracking_error_rot),
                    "physics": _physics(base), "monitor": base.motion_monitor.state(),
                    "tracker_q": base.tracker.configuration.q.copy(),
                    "target": (base._target_pos.copy(), base._target_quat.copy()),
                    "episode": base.__getstate__()["episode"]})
    return out


def _assert_same(stepped, lean, what):
    for key in stepped:
        assert _same(stepped[key], lean[key]), f"{what}: {key} differs"


@pytest.mark.parametrize("env_id", ["clfd/HelloWorld-h-v3", "clfd/LASA-Angle-v3",
                                    "clfd/HelloWorld-v3", "clfd/BoxOpening-v3",
                                    "clfd/Pouring-v3", "clfd/Scoop-v3"])
def test_demo_replay_is_bit_identical(env_id):
    env = get_env(env_id)
    stepped, lean = _both(env, env.unwrapped.demo_trajectory(1), demo=1)
    assert stepped["success"]
    _assert_same(stepped, lean, env_id)


def _far(traj: np.ndarray, step: int, offset: np.ndarray) -> np.ndarray:
    out = np.array(traj, dtype=float)
    out[step:, :len(offset)] += offset
    return out


@pytest.mark.parametrize("env_id, family, kind", [
    ("clfd/BoxOpening-v3", "teleport", "reflex"),
    ("clfd/BoxOpening-v3", "rush-wait", "tracking"),
    ("clfd/PlateStacking-v3", "other-task", None),
    ("clfd/HelloWorld-h-v3", "mirror", None),
    ("clfd/LASA-Angle-v3", "drift", None),
])
def test_must_fail_families_end_the_same_way(env_id, family, kind):
    env = get_env(env_id)
    traj = replay_trajectory(env.unwrapped, 0, family)
    for stop in (False, True):
        stepped, lean = _both(env, traj, stop_when_decided=stop)
        assert not stepped["success"]
        if kind is not None:
            assert json.loads(stepped["info"])["failure"]["kind"] == kind
        _assert_same(stepped, lean, f"{env_id} {family} stop={stop}")


def test_refused_commands_of_every_kind_end_the_same_way():
    env = get_env("clfd/BottleShelving-v3")
    base = env.unwrapped
    demo = base.demo_trajectory(0)
    cases = {
        "unreachable": _far(demo, 300, np.array([1.5, 0.0, 0.0])),  # beyond the reach
        "reflex at step 0": _far(demo, 0, np.array([0.05, 0.0, 0.0])),
        "floor": _far(demo, 500, np.array([0.0, 0.0, -2.0])),
    }
    kinds = set()
    for name, traj in cases.items():
        stepped, lean = _both(env, traj)
        failure = json.loads(stepped["info"])["failure"]
        kinds.add(failure["kind"])
        _assert_same(stepped, lean, name)
    assert kinds == {"unreachable", "reflex"}


def test_zero_quaternion_keeps_the_last_orientation_in_both():
    env = get_env("clfd/BoxOpening-v3")
    traj = np.array(env.unwrapped.demo_trajectory(0), dtype=float)
    traj[400:410, 3:7] = 0.0  # no orientation: the env keeps the last one
    stepped, lean = _both(env, traj)
    _assert_same(stepped, lean, "zero quaternion")


def test_a_nan_action_is_an_error_naming_its_step_before_any_physics():
    env = get_env("clfd/HelloWorld-h-v3")
    base = env.unwrapped
    traj = np.array(base.demo_trajectory(0), dtype=float)
    traj[250, 1] = np.nan
    env.reset(options={"demo": 0})
    before = _physics(base)
    with pytest.raises(ValueError, match=r"action at step 250 has non-finite entries at "
                                         r"indices \[1\]"):
        base.plan_commands(base.trajectory_to_actions(traj))
    assert _physics(base).tobytes() == before.tobytes()  # nothing ran
    with pytest.raises(ValueError, match="non-finite"):
        rollout(env, traj, demo=0, lean=True)
    with pytest.raises(ValueError, match="non-finite"):
        rollout(env, traj, demo=0, lean=False)


def test_wrapped_or_recording_envs_are_stepped():
    env = get_env("clfd/HelloWorld-h-v3")
    assert plain_env(env)
    assert not plain_env(tracer(env, None))


def test_the_stream_check_gives_the_step_checks_verdicts_and_state():
    """Random command streams, some within the limits and some beyond, judged at once and
    one command at a time: the same first refused command, the same violation, and the
    monitor's state after any prefix equal to the bit."""
    rng = np.random.default_rng(4)
    q0 = np.array([0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853])
    pos0, quat0 = np.array([0.3, 0.0, 0.5]), np.array([0.0, 1.0, 0.0, 0.0])
    refused = 0
    for trial in range(40):
        n = 120
        scale = [0.2, 1.0, 4.0][trial % 3]
        t = np.linspace(0, 1, n)[:, None]
        pos = pos0 + scale * 0.1 * np.sin(2 * np.pi * t * rng.uniform(0.5, 3, 3))
        axis = rng.normal(size=3)
        angle = scale * 0.3 * np.sin(2 * np.pi * t[:, 0] * rng.uniform(0.5, 3))
        quat = np.array([[np.cos(a / 2), *(np.sin(a / 2) * axis / np.linalg.norm(axis))]
                         for a in angle])
        quat = np.array([_mul(quat0, qq) for qq in quat])
        q = q0 + scale * 0.2 * np.sin(2 * np.pi * t * rng.uniform(0.5, 3, 7))
        if trial % 5 == 4:
            pos[n // 2:] += [2.0, 0.0, 0.0]  # beyond the reach
        step_monitor = MotionMonitor(panda_limits(), 1 / 60, np.array([0, 0, 0.333]),
                                     floor_height=0.0)
        step_monitor.reset(pos0, quat0, q0)
        stream_monitor = MotionMonitor(panda_limits(), 1 / 60, np.array([0, 0, 0.333]),
                                       floor_height=0.0)
        stream_monitor.reset(pos0, quat0, q0)
        check = stream_monitor.check_stream(pos, quat, q)
        first, violation = None, None
        for k in range(n):
            v = step_monitor.check_command(pos[k], quat[k], q[k])
            if v is not None:
                first, violation = k, v
                break
            if k in (0, 7, n // 3):
                assert _same(check.monitor_state(k + 1), step_monitor.state())
        assert check.refused_at == first and check.violation == violation
        executed = n if first is None else first + 1
        assert _same(check.monitor_state(executed), step_monitor.state())
        refused += first is not None
    assert 10 <= refused <= 35  # both kinds of stream were tried


def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(4)
    mujoco.mju_mulQuat(out, a, b)
    return out


def _machine() -> dict:
    cfg = np.show_config(mode="dicts")
    cpu = [line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
           if line.startswith("model name")]
    return {"mujoco": mujoco.__version__, "numpy": np.__version__,
            "blas": cfg["Build Dependencies"]["blas"]["version"],
            "simd": sorted(cfg["SIMD Extensions"]["found"]), "cpu": cpu[0] if cpu else ""}


BEFORE = Path(__file__).parent / "data" / "execution_before_issue40.json"


def test_demo_replays_end_where_they_did_before_the_planned_execution():
    """The rollouts the code before the planned execution made (pinned hashes of the final
    state, hand path and tracking record, tests/data/execution_before_issue40.json) are made
    again bit for bit, by the lean path (where the signature of the machine matches the one
    they were pinned on: bit-identical physics needs the same BLAS kernels and ISA)."""
    pinned = json.loads(BEFORE.read_text())
    if _machine() != pinned["machine"]:
        pytest.skip(f"hashes pinned on {pinned['machine']}, this machine is {_machine()}")
    for key, want in pinned["replays"].items():
        env_id, demo = key.rsplit("/", 1)
        env = get_env(env_id)
        r = rollout(env, env.unwrapped.demo_trajectory(int(demo)), demo=int(demo))
        assert r.timing is not None  # the lean path ran
        digest = hashlib.sha256(_physics(env.unwrapped).tobytes()
                                + np.nan_to_num(r.ee_path, nan=-9).tobytes()
                                + np.nan_to_num(r.tracking_error_pos, nan=-9).tobytes())
        got = {"hash": digest.hexdigest()[:16], "success": r.success, "steps": r.steps,
               "failure": r.info.get("failure_reason")}
        assert got == want, key


def test_replay_families_give_the_verdicts_they_gave_before_the_planned_execution():
    """Every perturbation family on demo 0 of a letter, a LASA shape and a RoboTasks scene:
    the verdict, failure reason and steps that `clfd-bench replay` recorded with the code before
    the planned execution (`replay_families` in the pinned file). Verdicts and reasons do not
    hang on the last bit of the physics, so this runs on any machine."""
    pinned = json.loads(BEFORE.read_text())["replay_families"]
    assert len(pinned) >= 40
    for want in pinned:
        env = get_env(want["env"])
        traj = replay_trajectory(env.unwrapped, want["demo"], want["family"])
        r = rollout(env, traj, demo=want["demo"])
        got = {"success": r.success, "failure_reason": r.info.get("failure_reason"),
               "steps": r.info.get("step")}
        assert got == {k: want[k] for k in got}, (want["env"], want["family"])
