"""Pose tracking with mink differential IK.

`PoseTracker` follows a stream of target poses of one frame (the Panda `hand` body by default)
at the control rate: each `track()` call runs a few mink QP iterations (FrameTask + PostureTask,
ConfigurationLimit + VelocityLimit) from the previous solution and returns the arm joint
command. Unreachable targets are tracked as closely as the limits allow and the remaining
error is reported; nothing raises for them.
"""

from __future__ import annotations

import math

import daqp
import mink
import mujoco
import numpy as np

from clfd_bench.sim.robot import ARM_JOINTS, HOME_QPOS, JOINT_VELOCITY_LIMITS, RobotIndex


def _check_finite(name: str, x: np.ndarray) -> None:
    bad = ~np.isfinite(x)
    if bad.any():
        raise ValueError(f"{name} has non-finite entries at indices {np.flatnonzero(bad).tolist()}"
                         f" (values {x[bad].tolist()}); pass finite numbers")


def quat_angle(q1: np.ndarray, q2: np.ndarray) -> float:
    """Rotation angle (rad, in [0, pi]) between two unit quaternions [4] (w, x, y, z)."""
    d = abs(float(q1 @ q2))
    return 2.0 * math.acos(min(d, 1.0))


class PoseTracker:
    """Differential-IK tracker of one frame's pose.

    Args:
        model: a compiled model holding the Panda arm joints `joint1..7`, best the robot-only
            model (`clfd_bench.sim.robot.robot_model(tool)`): the QP has one variable per DoF,
            so a scene with free-floating objects makes it slower. DoFs other than the arm's
            (fingers, pen spring, objects) are held at their `reset` value by the posture task.
        frame: name of the tracked frame (default the `hand` body, the frame of the data).
        frame_type: "body", "site" or "geom".
        posture_cost: cost of the posture task pulling towards the configuration given to
            `reset` (keeps the arm in its IK branch; also regularises redundancy).
        position_cost, orientation_cost: FrameTask costs.
        iterations: QP iterations per `track` call.
        dt: integration step of one QP iteration, seconds. The velocity limits bound each
            iteration's motion to `dt * v_max`, so `iterations * dt` should be the control period
            (default 1 × 1/60 s) for physically consistent joint speeds.
        solver: a qpsolvers solver name ("daqp" default).
        velocity_limits: apply the Panda's joint velocity limits (datasheet values).
        lm_damping: Levenberg-Marquardt damping of the frame task (helps near singularities and
            for unreachable targets).
        posture_gain: fraction of the posture error the posture task corrects per QP
            iteration (mink's task gain). 1 corrects it at once: in the arm's null space nothing
            opposes the posture task, so whenever that null space turns (e.g. as the wrist
            rotates) the arm swings back towards the posture at the joint velocity limit. Online
            tracking (the envs) uses a smaller gain (see `clfd_bench.envs.base`).
    """

    def __init__(self, model, frame: str = "hand", frame_type: str = "body",
                 posture_cost: float = 1e-3, position_cost: float = 1.0,
                 orientation_cost: float = 1.0, iterations: int = 1, dt: float = 1.0 / 60.0,
                 solver: str = "daqp", velocity_limits: bool = True, lm_damping: float = 1e-4,
                 posture_gain: float = 1.0):
        if iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {iterations}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        self.model = model
        self.frame = frame
        self.frame_type = frame_type
        self.iterations = int(iterations)
        self.dt = float(dt)
        self.solver = solver
        self.index = RobotIndex(model)
        kinds = {"body": mujoco.mjtObj.mjOBJ_BODY, "site": mujoco.mjtObj.mjOBJ_SITE,
                 "geom": mujoco.mjtObj.mjOBJ_GEOM}
        if frame_type not in kinds:
            raise ValueError(f"frame_type must be one of {sorted(kinds)}, got {frame_type!r}")
        self._frame_kind = kinds[frame_type]
        self._frame_id = mujoco.mj_name2id(model, self._frame_kind, frame)
        if self._frame_id < 0:
            raise ValueError(f"model has no {frame_type} named {frame!r}")
        self._target_pos: np.ndarray | None = None
        self._target_quat: np.ndarray | None = None
        self.configuration = mink.Configuration(model)
        self.frame_task = mink.FrameTask(frame, frame_type, position_cost=position_cost,
                                         orientation_cost=orientation_cost,
                                         lm_damping=lm_damping)
        if not 0.0 < posture_gain <= 1.0:
            raise ValueError(f"posture_gain must be in (0, 1], got {posture_gain}")
        self.posture_task = mink.PostureTask(model, cost=posture_cost, gain=posture_gain)
        self.tasks = [self.frame_task, self.posture_task]
        self.limits: list = [mink.ConfigurationLimit(model)]
        self._velocity_limit = None
        if velocity_limits:
            vmax = dict(zip(ARM_JOINTS, JOINT_VELOCITY_LIMITS.tolist(), strict=True))
            self._velocity_limit = mink.VelocityLimit(model, vmax)
            self.limits.append(self._velocity_limit)
        self._qp: _TrackingQP | None = (_TrackingQP(self) if solver == "daqp"
                                        and _TrackingQP.supports(self) else None)
        q0 = model.qpos0.copy()
        q0[self.index.arm_qpos] = HOME_QPOS
        self._q_full0 = q0
        self.reset(HOME_QPOS)

    @property
    def q(self) -> np.ndarray:
        """The current arm solution [7]."""
        return self.configuration.q[self.index.arm_qpos].copy()

    def reset(self, q: np.ndarray, posture: np.ndarray | None = None) -> None:
        """Restarts tracking from arm configuration `q` [7] (or a full model qpos [nq]).

        Args:
            q: [7] arm joints (other DoFs from the model's default) or [nq].
            posture: [7] or [nq] posture target; default `q`.
        """
        full = self._full(q)
        lo, hi = self.index.arm_range[:, 0], self.index.arm_range[:, 1]
        full[self.index.arm_qpos] = np.clip(full[self.index.arm_qpos], lo, hi)
        self.configuration.update(full)
        self.posture_task.set_target(self._full(posture) if posture is not None else full)

    def _full(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        _check_finite("configuration", q)
        if q.shape == (7,):
            full = self._q_full0.copy()
            full[self.index.arm_qpos] = q
            return full
        if q.shape == (self.model.nq,):
            return q.copy()
        raise ValueError(f"configuration must have shape (7,) or ({self.model.nq},), got {q.shape}")

    def set_target(self, target_pos: np.ndarray, target_quat: np.ndarray) -> None:
        """Sets the frame target: position [3] m, quaternion [4] w,x,y,z (normalised here)."""
        pos = np.asarray(target_pos, dtype=float).reshape(3)
        quat = np.asarray(target_quat, dtype=float).reshape(4)
        n2 = float(quat @ quat)
        if not math.isfinite(n2 + float(pos @ pos)):  # NaN/inf (or a huge value: checked here)
            _check_finite("target position", pos)
            _check_finite("target quaternion", quat)
        n = math.sqrt(n2)
        if n < 1e-9:
            raise ValueError("target quaternion has zero norm; pass a unit quaternion (w, x, y, z)")
        self._target_pos = pos
        self._target_quat = quat / n
        self.frame_task.set_target(mink.SE3(np.concatenate([self._target_quat, pos])))

    def step(self, iterations: int | None = None) -> None:
        """Runs QP iterations towards the current target (default `self.iterations`)."""
        for _ in range(self.iterations if iterations is None else iterations):
            vel = self._solve_velocity()
            if vel is None:
                # Infeasible QP (should not happen with these limits): hold the configuration.
                return
            self.configuration.integrate_inplace(vel, self.dt)

    def _solve_velocity(self) -> np.ndarray | None:
        if self._qp is not None:
            return self._qp.solve(self.dt)
        try:
            return mink.solve_ik(self.configuration, self.tasks, self.dt, self.solver,
                                 limits=self.limits)
        except mink.NoSolutionFound:
            return None

    def error(self) -> tuple[float, float]:
        """(position error m, rotation error rad) of the current solution to the target."""
        if self._target_pos is None:
            raise ValueError("no target set; call set_target or track first")
        data = self.configuration.data
        if self._frame_kind == mujoco.mjtObj.mjOBJ_BODY:
            pos, quat = data.xpos[self._frame_id], data.xquat[self._frame_id]
        else:
            site = self._frame_kind == mujoco.mjtObj.mjOBJ_SITE
            xpos = data.site_xpos if site else data.geom_xpos
            xmat = data.site_xmat if site else data.geom_xmat
            pos = xpos[self._frame_id]
            quat = np.empty(4)
            mujoco.mju_mat2Quat(quat, xmat[self._frame_id])
        diff = pos - self._target_pos
        return math.sqrt(float(diff @ diff)), quat_angle(quat, self._target_quat)

    def track(self, target_pos: np.ndarray, target_quat: np.ndarray,
              iterations: int | None = None) -> tuple[np.ndarray, float, float]:
        """One control step: move the solution towards the target pose.

        Args:
            target_pos: [3] metres, base frame.
            target_quat: [4] w, x, y, z.
            iterations: QP iterations (default `self.iterations`).

        Returns:
            (q_cmd [7] arm joint command, position error m, rotation error rad) of the solution.
        """
        self.set_target(target_pos, target_quat)
        self.step(iterations)
        pos_err, rot_err = self.error()
        return self.q, pos_err, rot_err

    def solve(self, target_pos: np.ndarray, target_quat: np.ndarray, max_iterations: int = 300,
              pos_tol: float = 1e-5, rot_tol: float = 1e-4, dt: float = 0.05
              ) -> tuple[np.ndarray, float, float]:
        """Converges to a static target (e.g. a start configuration): iterates until the error
        is under (pos_tol m, rot_tol rad) or `max_iterations`; velocity limits still apply with
        step `dt`. Returns (q [7], position error m, rotation error rad)."""
        self.set_target(target_pos, target_quat)
        old_dt, self.dt = self.dt, dt
        try:
            for _ in range(max_iterations):
                self.step(1)
                pos_err, rot_err = self.error()
                if pos_err < pos_tol and rot_err < rot_tol:
                    break
        finally:
            self.dt = old_dt
        pos_err, rot_err = self.error()
        return self.q, pos_err, rot_err


class _TrackingQP:
    """The QP of `mink.build_ik` for the tracker's two tasks and two limits, assembled into
    preallocated arrays and handed to DAQP directly.

    mink builds the same problem generically every iteration (task lists, `vstack`s, a
    `qpsolvers.Problem`), which costs more than the solve for a 7-DoF arm. Here the constant
    parts are computed once: the posture task's Jacobian is the identity, so its rows of the
    stacked weighted Jacobian are `diag(cost)`; the configuration limit's and the velocity
    limit's inequality matrices do not depend on the configuration, and the velocity limit's
    right-hand side only on `dt`. Per iteration only mink's frame-task residual (error and
    Jacobian, mink's own code), the posture error and the configuration limit's right-hand
    side are computed, with the same operations in the same order as mink, so the problem is
    the same to the last bit (`tests/test_sim_ik.py` compares it with `mink.build_ik`).

    Used when the model has no free or ball joints (the robot-only models); otherwise
    `PoseTracker` calls `mink.solve_ik`.
    """

    def __init__(self, tracker: PoseTracker):
        model = tracker.model
        self.tracker = tracker
        self.model = model
        nv = model.nv
        conf_limit = tracker.limits[0]
        self.conf_limit = conf_limit
        idx = np.asarray(conf_limit.indices, dtype=int)
        self.idx = idx
        proj = conf_limit.projection_matrix
        vel = tracker._velocity_limit
        vel_proj = None if vel is None else vel.projection_matrix
        blocks = [proj, -proj] + ([] if vel_proj is None else [vel_proj, -vel_proj])
        self.G = np.vstack(blocks)
        self.h = np.empty(len(self.G))
        self.nb = len(idx)
        self.vel_limit = None if vel_proj is None else np.asarray(vel.limit, dtype=float)
        self.h_dt: float | None = None
        self.sense = np.zeros(len(self.h), dtype=np.intc)
        self.lower_bound = np.full(len(self.h), -1e30)
        posture = tracker.posture_task
        self.W = np.zeros((6 + nv, nv))
        self.W[6:] = np.diag(posture.cost)
        self.e = np.empty(6 + nv)
        self.posture_err = np.empty(nv)
        self.dq_max = np.empty(nv)
        self.dq_min = np.empty(nv)

    @staticmethod
    def supports(tracker: PoseTracker) -> bool:
        """True when the model has only hinge and slide joints (no free or ball joint) and the
        limits are the tracker's own (configuration limit, optional velocity limit)."""
        m = tracker.model
        simple = all(int(t) in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
                     for t in m.jnt_type)
        conf_limit = tracker.limits[0]
        return (simple and isinstance(conf_limit, mink.ConfigurationLimit)
                and conf_limit.projection_matrix is not None)

    def problem(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(H [nv, nv], c [nv], G [m, nv], h [m]) of the QP in the displacement dq
        (minimise 1/2 dq' H dq + c' dq subject to G dq <= h), as `mink.build_ik` builds it
        with damping 1e-12. G and h are this object's buffers (valid until the next call)."""
        t = self.tracker
        conf = t.configuration
        model, q = self.model, conf.data.qpos
        posture = t.posture_task
        wf, ef, mu_frame = t.frame_task.compute_qp_residual(conf)
        mujoco.mj_differentiatePos(model, self.posture_err, 1.0, posture.target_q, q)
        ep = posture.cost * (-posture.gain * self.posture_err)
        mu_posture = posture.lm_damping * float(ep @ ep)
        W, e = self.W, self.e
        W[:6] = wf
        e[:6] = ef
        e[6:] = ep
        H = W.T @ W
        c = -(e @ W)
        H.flat[:: model.nv + 1] += 1e-12 + (mu_frame + mu_posture)  # mink's order of sums
        # Configuration limit (mink's formula), then the velocity limit (constant for a dt).
        lim = self.conf_limit
        mujoco.mj_differentiatePos(model, self.dq_max, 1.0, q, lim.upper)
        mujoco.mj_differentiatePos(model, self.dq_min, 1.0, lim.lower, q)
        nb, h = self.nb, self.h
        h[:nb] = lim.gain * self.dq_max[self.idx]
        h[nb:2 * nb] = lim.gain * self.dq_min[self.idx]
        if self.vel_limit is not None and self.h_dt != dt:
            n = len(self.vel_limit)
            h[2 * nb:2 * nb + n] = dt * self.vel_limit
            h[2 * nb + n:] = dt * self.vel_limit
            self.h_dt = dt
        return H, c, self.G, h

    def solve(self, dt: float) -> np.ndarray | None:
        """The joint velocity [nv] of one QP iteration with step `dt`, or None when DAQP
        reports the problem infeasible."""
        H, c, G, h = self.problem(dt)
        x, _, exitflag, _ = daqp.solve(H, c, G, h, self.lower_bound, self.sense)
        if exitflag <= 0:
            return None
        return x / dt
