"""How a `clfd_bench.envs.base.PandaEnv` executes commands: one control step at a time (what
`step` does) or a whole stream planned before its physics runs (what the harness does).

The IK tracker runs on the robot-only model and never reads the simulated state, so the joint
references of a whole action stream can be computed before any physics; the controller's
command checks (`MotionMonitor.check_stream`) then judge the stream at once, vectorised. What
remains per control step is what depends on the physics: the servos' substeps, the blow-up,
collision and tracking checks, and the task's hook (`_after_step`: ink, grasp slips, records).
`run_plan` executes a `CommandPlan` that way, with the verdicts, failure reasons and final state
of `step` called on each action in turn, to the last bit (`tests/test_lean_rollout.py`); it
builds no observation or info per step and skips the per-step success check (`evaluate()`
decides at the end).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import mujoco
import numpy as np

from clfd_bench.sim.ik import quat_angle
from clfd_bench.sim.limits import StreamCheck, Violation

_BLOWUP_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
)
_I0, _I1, _I2 = (int(w) for w in _BLOWUP_WARNINGS)


def check_finite_action(action: np.ndarray, step: int | None = None) -> None:
    """Raises ValueError naming the NaN/inf entries of `action` (and its step, when given)."""
    bad = ~np.isfinite(action)
    if bad.any():
        idx = np.flatnonzero(bad).tolist()
        at = "" if step is None else f" at step {step}"
        raise ValueError(f"action{at} has non-finite entries at indices {idx} (values "
                         f"{action.reshape(-1)[bad.reshape(-1)].tolist()}); actions must be finite")


@dataclasses.dataclass
class CommandPlan:
    """An action stream turned into controller commands, before any physics ran
    (`CommandExecution.plan_commands`).

    Attributes:
        actions: [N, A] the actions.
        pos: [N, 3] commanded hand positions, m.
        quat: [N, 4] commanded hand orientations (w, x, y, z, normalised as the IK saw them).
        grip: [N] gripper commands, or None when the action has none.
        q_ref: [N, 7] the IK's joint references, rad.
        ik_error: [N, 2] the IK solution's position (m) and rotation (rad) error.
        check: the controller's verdict on the stream (None with the limits off).
        refs: [N, S, 7] the servo reference of every physics substep, valid up to the first
            failure (afterwards the robot holds).
        ik_s: seconds the IK took (`PoseTracker.track` alone).
    """

    actions: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    grip: np.ndarray | None
    q_ref: np.ndarray
    ik_error: np.ndarray
    check: StreamCheck | None
    refs: np.ndarray
    ik_s: float
    _raw: list[tuple[np.ndarray, np.ndarray]]  # the targets as given to the tracker
    _tracker_q: np.ndarray  # [N, nq] the tracker's configuration after each command

    def __len__(self) -> int:
        return len(self.actions)


@dataclasses.dataclass
class PlanRun:
    """What `CommandExecution.run_plan` did.

    Attributes:
        steps: control steps executed.
        ended: the episode ended (a failure or the horizon) before the plan's end, or at it.
        decided: the task's decided failure the run stopped on (`stop_when_decided`), or None.
        ee_pos: [N, 3] the `hand` position after each step (NaN for steps not run).
        tracking: [N, 2] the hand's position (m) and rotation (rad) error to the command after
            each step (NaN for steps not run).
        physics_s: seconds spent in MuJoCo's physics steps.
    """

    steps: int
    ended: bool
    decided: dict[str, Any] | None
    ee_pos: np.ndarray
    tracking: np.ndarray
    physics_s: float


class CommandExecution:
    """The control step of `PandaEnv` (a mixin: it uses the env's model, data, robot, tracker,
    monitors and task hooks)."""

    # ------------------------------------------------------------------ one step
    def _on_command(self, action: np.ndarray) -> None:
        """Hook: `action` reaches the controller (called once per command, refused or not)."""

    def _execute_command(self, action: np.ndarray, pos: np.ndarray, quat: np.ndarray,
                         grip: float | None, q_ref: np.ndarray, ik_error: tuple[float, float],
                         refused: Violation | None, refs: np.ndarray | None = None) -> bool:
        """Executes one checked command: the gripper, the servos' substeps towards `q_ref`
        [7], then the blow-up, collision and tracking checks and the task's `_after_step`.
        A `refused` command is not executed: the robot stops. Returns True when the episode
        failed at this step."""
        self._on_command(action)
        self._target_pos = pos
        self._target_quat = quat
        self._ik_error = ik_error
        step = self._step_count
        if refused is not None:  # the controller refuses the command: the robot stops
            self._fail(refused.reason, refused.as_dict())
            self._drive(self._hold_q)
            self._step_count += 1
            return True
        if grip is not None:
            self._apply_gripper(grip)
        self._drive(q_ref, refs)
        self._step_count += 1
        blowup = self._check_blowup(step)
        if blowup is not None:
            self._fail(blowup, {"kind": "blowup", "limit": "physics", "value": None,
                                "bound": None, "unit": "", "step": step})
            return True
        d = self.data
        hand = self.robot.hand_body
        diff = d.xpos[hand] - pos
        # = np.linalg.norm(diff) (which computes exactly this), without its dispatch
        self._tracking_error = (math.sqrt(diff.dot(diff)), quat_angle(d.xquat[hand], quat))
        if self.motion_monitor is not None:
            bad = (self.collision_monitor.check(d, step)
                   or self.motion_monitor.check_tracking(*self._tracking_error, step))
            if bad is not None:
                self._fail(bad.reason, bad.as_dict())
                return True
        self._after_step()
        return False

    def _drive(self, q_ref: np.ndarray, refs: np.ndarray | None = None) -> None:
        """Runs the physics of one control period with the servo reference moving linearly from
        the previous IK solution to `q_ref` [7], with velocity feed-forward (`refs` [S, 7]: the
        substeps' references when already computed, `_substep_refs`)."""
        refs_given = refs is not None  # the plan's: its q_ref rows are not written to
        if not refs_given:
            refs = self._substep_refs(self._q_ref_prev[None], np.asarray(q_ref)[None])[0]
        m, d = self.model, self.data
        ctrl = d.ctrl
        act = self.robot.arm_act_slice
        t0 = time.perf_counter()
        for ref in refs:
            ctrl[act] = ref
            mujoco.mj_step(m, d)
        self.physics_s += time.perf_counter() - t0
        self._q_ref_prev = q_ref if refs_given else np.array(q_ref, dtype=float)

    def _substep_refs(self, q_prev: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
        """Servo references [N, S, 7] of the substeps from `q_prev` [N, 7] to `q_ref` [N, 7]:
        linear within the period, plus the velocity feed-forward (the command leads by kv/kp ×
        the reference velocity), within the actuators' control range."""
        r = self.robot
        dq = q_ref - q_prev
        refs = (q_prev[:, None] + self._substep_fractions[None, :, None] * dq[:, None]
                + ((r.arm_ctrl_tau / self.control_dt) * dq)[:, None])
        np.maximum(refs, r.arm_ctrl_range[:, 0], out=refs)  # np.clip, at a fraction of its cost
        np.minimum(refs, r.arm_ctrl_range[:, 1], out=refs)
        return refs

    def _fail(self, reason: str, failure: dict[str, Any]) -> None:
        """Ends the episode as a failure; the robot holds the configuration it is at now."""
        self._failure_reason = reason
        self._failure = failure
        q = self.data.qpos[self.robot.arm_qpos]
        self._hold_q = q.copy() if np.isfinite(q).all() else self._q_ref_prev.copy()
        self._q_ref_prev = self._hold_q.copy()  # no feed-forward: the reference stands still

    def _check_blowup(self, step: int) -> str | None:
        w, base = self._warn_numbers, self._warn_base  # live view; the counts at the reset
        q, v = self._qpos, self._qvel  # live views of the state
        new = (w[_I0] > base[0], w[_I1] > base[1], w[_I2] > base[2])
        if not any(new) and math.isfinite(q @ q + v @ v):
            return None
        names = [w.name for w, hit in zip(_BLOWUP_WARNINGS, new, strict=True) if hit]
        what = f"MuJoCo warned {names} and reset the state" if names else "non-finite state"
        return (f"physics blow-up at step {step} ({what}); the scene is unstable: "
                "check the task MJCF (masses, solver settings, timestep)")

    # ------------------------------------------------------------------ a planned stream
    def check_actions(self, actions: np.ndarray) -> np.ndarray:
        """`actions` [N, A] as float64, or ValueError for a wrong shape or a non-finite action
        (naming its step and entries)."""
        actions = np.asarray(actions, dtype=np.float64)
        shape = self.action_space.shape
        if actions.ndim != 2 or actions.shape[1:] != shape:
            raise ValueError(f"actions must have shape [N, {shape[0]}], got {actions.shape}")
        finite = np.isfinite(actions).all(axis=1)
        if not finite.all():
            t = int(np.flatnonzero(~finite)[0])
            check_finite_action(actions[t], t)
        return actions

    def plan_commands(self, actions: np.ndarray) -> CommandPlan:
        """Turns actions [N, A] into commands from the current state (normally right after
        `reset`): the targets, the IK's joint references and the controller's verdict on the
        whole stream. Moves the IK tracker through the stream; `run_plan` leaves it where
        executing the same actions with `step` would. Raises ValueError for a wrong shape or a
        non-finite action (naming its step) before anything runs."""
        actions = self.check_actions(actions)
        if self._hold_q is not None:
            raise RuntimeError("the episode already failed; call reset() before planning")
        n = len(actions)
        tracker = self.tracker
        pos, quat = np.empty((n, 3)), np.empty((n, 4))
        q_ref, ik_error = np.empty((n, 7)), np.empty((n, 2))
        tracker_q = np.empty((n, len(tracker.configuration.q)))
        grips: list[float | None] = []
        raw = []
        ik_s = 0.0
        clock = time.perf_counter
        for t in range(n):
            p, qt, g = self._action_to_target(actions[t])
            t0 = clock()
            q, pe, re = tracker.track(p, qt)
            ik_s += clock() - t0
            pos[t] = p
            quat[t] = tracker._target_quat
            self._target_quat = quat[t]  # a zero quaternion keeps the last (the default hook)
            q_ref[t] = q
            ik_error[t] = pe, re
            tracker_q[t] = tracker.configuration.q
            grips.append(g)
            raw.append((p, qt))
        check = (self.motion_monitor.check_stream(pos, quat, q_ref)
                 if self.motion_monitor is not None else None)
        q_prev = np.concatenate([self._q_ref_prev[None], q_ref[:-1]])
        grip = None if grips and grips[0] is None else np.array(grips, dtype=float)
        return CommandPlan(actions, pos, quat, grip, q_ref, ik_error, check,
                           self._substep_refs(q_prev, q_ref), ik_s, raw, tracker_q)

    def run_plan(self, plan: CommandPlan, stop_when_decided: bool = False) -> PlanRun:
        """Executes a plan made by `plan_commands` right before (nothing else may step the env
        in between): each command as `step` would, stopping at a failure, at the horizon, or
        (with `stop_when_decided`) at the task's decided failure. Builds no observation or info
        and skips the per-step success check: call `evaluate()` afterwards."""
        n = len(plan)
        check = plan.check
        refused_at = check.refused_at if check is not None else None
        hand_pos = self.data.xpos[self.robot.hand_body]  # a live view
        ee = np.full((n, 3), np.nan)
        tracking = np.full((n, 2), np.nan)
        grips = [None] * n if plan.grip is None else plan.grip.tolist()
        ik_errors = [tuple(e) for e in plan.ik_error.tolist()]
        decided = None
        ended = False
        steps = 0
        physics0 = self.physics_s
        for t in range(n):
            failed = self._execute_command(
                plan.actions[t], plan.pos[t], plan.quat[t], grips[t], plan.q_ref[t],
                ik_errors[t], check.violation if t == refused_at else None, plan.refs[t])
            steps += 1
            ee[t] = hand_pos
            tracking[t] = self._tracking_error
            if failed or self._step_count >= self.horizon:
                ended = True
                break
            if stop_when_decided and (decided := self.decided_failure()) is not None:
                break
        last = steps - 1
        if last >= 0:
            self._target_pos = plan.pos[last].copy()
            self._target_quat = plan.quat[last].copy()
            if last < n - 1:  # the tracker ran the whole plan: back to where `step` leaves it
                self.tracker.configuration.update(plan._tracker_q[last])
                self.tracker.set_target(*plan._raw[last])
        if check is not None:
            self.motion_monitor.set_state(check.monitor_state(steps))
        return PlanRun(steps, ended, decided, ee, tracking, self.physics_s - physics0)
