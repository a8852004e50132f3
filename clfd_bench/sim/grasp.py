"""The grasp model of the RoboTasks scenes: a prop held between the Franka Hand's finger pads.

The fingers do not squeeze the prop through contacts (a stable simulated friction grasp would
need a much smaller time step). While the gripper is closed the prop is attached to the `hand`
body by a MuJoCo **weld** equality constraint: it is held in position AND orientation, at the
pose it had when it was grasped. Contacts between the gripper (hand, fingers) and the prop are
excluded. The grasp **breaks** (the prop slips out of the fingers, `release_reason = "slipped"`)
when the wrench the weld has to transmit to keep the prop in place exceeds what a friction grip
of the two pads can hold:

- the wrench is the weld's, read from MuJoCo every control step and expressed in the
  grasp-site frame (the hand's axes at the fingertips' grasp point: x across the pads, y the
  fingers' closing axis, z the approach axis). `Grasp.wrench` reads the weld's rows of
  `efc_force` (`efc_type == mjCNSTR_EQUALITY`, `efc_id ==` the constraint's id; the force rows
  are the world-frame force on the prop at its origin, the rotation rows 2 x the torque on the
  prop in its own frame): the force at the last physics step. Those rows ring at the physics
  step's Nyquist rate whenever the servo reference jumps (the stair-stepped orientation samples
  of some demos do that every few steps), and one sample per control step aliases that ringing
  into loads of 1-2 x the capacity that the prop never feels on average. So for a free prop
  (bottle, plate, cup) the load is the weld's wrench averaged over the control period
  (`Grasp.mean_wrench`): Newton-Euler on the prop, its momentum change over the period less
  gravity and the contact forces on it (MuJoCo's `cfrc_ext` less the weld's rows, at the
  period's end: the beans in the cup, a support the prop is pushed on). The lid's edge
  is no free body (it rides on the lid's joints): its load is the `efc_force` reading;
- its load ratio against the grip's capacity (`GripCapacity.ratio`) is averaged over the last
  `filter_steps` control steps (6 steps = 0.1 s at 60 Hz), so a short peak (an impact) does not
  break a grasp that only a sustained load would;
- the capacity (`grip_capacity`) is that of two flat pads pressed together with the Franka
  Hand's continuous grasp force, 70 N (datasheet; 140 N peak), friction coefficient `mu`:

  | load (grasp-site frame) | capacity | kind |
  |---|---|---|
  | force in the pads' plane (x, z) | F_t = 2 mu F | friction (both pads) |
  | force along the closing axis (y) | 140 N (peak force) | the fingers give way |
  | torsion about y | T_y = 2 mu F rho | friction, rho = mean lever |
  | tilt about x (lever along z) | T_x = F l_z (cylinder along x: 2 mu F R) | pressure shift |
  | tilt about z (lever along x) | T_z = F l_x (cylinder along z: 2 mu F R) | pressure shift |

  Friction forces and torsion share the pads' friction: they combine as an ellipse,
  (f_x^2 + f_z^2) / F_t^2 + tau_y^2 / T_y^2 <= 1 (the usual limit-surface approximation); the
  other loads are checked on their own. `contact` names the contact geometry: "patch" (a flat
  prop covering the pads: plate rim, lid edge; rho = 0.383 x pad side for a square pad, levers
  = pad sides), "line_z" (a cylinder along the approach axis: a bottle neck; contact lines as
  long as the pad, rho = l / 4, rolling about its own axis resisted by 2 mu F R), "line_x" (a
  cylinder along the pads' width: a cup's side).

  Defaults: F = 70 N (Franka Hand datasheet, continuous), mu = 0.5 (`DEFAULT_MU`: the stock
  Franka fingertips are a hard, ribbed polymer; static friction of such polymers on PET, glazed
  ceramic or cardboard is about 0.3-0.7; 0.5 is the middle), pads 17 x 17 mm (the Menagerie
  model's `fingertip_pad_collision_1` box, the fingertip's flat face). With these: F_t = 70 N;
  patch: T_y = 0.46 Nm, T_x = T_z = 1.19 Nm; line_z (bottle neck, R = 13.5 mm): T_y = 0.30 Nm,
  T_x = 1.19 Nm, T_z = 0.95 Nm.

A grip can also be **compliant** in some directions (`slip_joints`): joints of the scene between
the held body and the rest of the prop that let the prop move relative to the fingers within
bounds; the grasp slips out when one of them moves further than its bound from where it was at
the grasp (a slide: metres; a hinge: radians; a ball: the rotation angle, radians). The box lid
uses this: its edge may slide in the pads and turn between them as much as the demonstrations
need (see `tasks/openbox.toml`), no further. The demos need it: about the fitted hinge they turn
the hand up to 38 deg against the lid and move the grasp point up to 3 cm across and along the
lid's edge (the real edge turned and slid in the fingers, or the lid flexed), which a rigid hold
of a rigid lid on one hinge cannot follow; a hand that does not turn with the lid at all (its
orientation frozen) turns 90 deg against it and loses it.

A released prop is never re-grasped during the episode. The constraint is a row of the compiled
model (added to the spec by `add_grasp_constraint`); switching it on/off writes
`data.eq_active`, which MuJoCo keeps in the physics state; the slip bookkeeping
(`Grasp.state` / `Grasp.restore`) goes with the env's pickled episode state.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import mujoco
import numpy as np

from clfd_bench.sim.robot import GRASP_OFFSET, HAND_BODY

#: Bodies of the gripper whose contacts with a held prop are excluded.
GRIPPER_BODIES: tuple[str, ...] = ("hand", "left_finger", "right_finger")
KINDS = ("weld", "connect")
CONTACTS = ("patch", "line_z", "line_x")

#: Franka Hand grasp force, N: continuous and peak (Franka Emika datasheet).
GRIP_FORCE = 70.0
GRIP_FORCE_PEAK = 140.0
#: Friction coefficient of the fingertips on the props (see the module docstring).
DEFAULT_MU = 0.5
#: Fingertip pad size (m): across the pad (hand x) and along the approach axis (hand z); the
#: Menagerie Panda's `fingertip_pad_collision_1` box is 2 x 0.0085 m on both.
PAD_SIZE = (0.017, 0.017)
#: Mean distance from its centre of a point of a uniformly loaded square (x side length).
_SQUARE_MEAN_RADIUS = 0.3826


@dataclasses.dataclass(frozen=True)
class GripCapacity:
    """The wrench a two-pad friction grip holds, in the grasp-site frame (x across the pads, y
    the closing axis, z the approach axis).

    Attributes:
        tangential: F_t (N), friction force in the pads' plane (x, z).
        normal: F_y (N), force along the closing axis.
        torsion: T_y (Nm), torque about the closing axis (friction).
        tilt_x: T_x (Nm), torque about x.
        tilt_z: T_z (Nm), torque about z.
    """

    tangential: float
    normal: float
    torsion: float
    tilt_x: float
    tilt_z: float

    def ratio(self, force: np.ndarray, torque: np.ndarray) -> tuple[float, str]:
        """Load ratio (> 1: the grip cannot hold it) of a wrench on the prop [3] N, [3] Nm in the
        grasp-site frame, and which limit is the tightest ("friction", "normal", "tilt_x",
        "tilt_z")."""
        f0, f1, f2 = np.asarray(force, dtype=float).tolist()
        t0, t1, t2 = np.asarray(torque, dtype=float).tolist()
        ratios = ((((f0 * f0 + f2 * f2) / self.tangential ** 2
                    + t1 * t1 / self.torsion ** 2) ** 0.5, "friction"),
                  (abs(f1) / self.normal, "normal"), (abs(t0) / self.tilt_x, "tilt_x"),
                  (abs(t2) / self.tilt_z, "tilt_z"))
        return max(ratios)

    def as_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)


def _sub(a: list[float], b: list[float]) -> list[float]:
    """a - b for [3] vectors as floats (the IEEE operations numpy does elementwise)."""
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def _cross(a: list[float], b: list[float]) -> list[float]:
    """a x b for [3] vectors as floats (np.cross costs ~10x more on single vectors)."""
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def grip_capacity(contact: str = "patch", *, grip_force: float = GRIP_FORCE,
                  peak_force: float = GRIP_FORCE_PEAK, mu: float = DEFAULT_MU,
                  pad: tuple[float, float] = PAD_SIZE, radius: float = 0.0) -> GripCapacity:
    """Capacity of the Franka Hand's two-pad grip (formulas in the module docstring).

    Args:
        contact: "patch" (flat prop covering the pads), "line_z" (a cylinder of radius
            `radius` along the approach axis), "line_x" (a cylinder along the pads' width).
        grip_force: squeezing force F (N).
        peak_force: force along the closing axis the fingers withstand (N).
        mu: friction coefficient pad-prop.
        pad: (width along hand x, length along hand z) of a pad's contact face, m.
        radius: the cylinder's radius (m) for the line contacts.
    """
    if contact not in CONTACTS:
        raise ValueError(f"contact must be one of {CONTACTS}, got {contact!r}")
    if contact != "patch" and not radius > 0:
        raise ValueError(f"contact {contact!r} needs the cylinder's radius > 0, got {radius}")
    lx, lz = pad
    ft = 2.0 * mu * grip_force
    if contact == "patch":
        rho = _SQUARE_MEAN_RADIUS * float(np.sqrt(lx * lz))
        return GripCapacity(ft, peak_force, ft * rho, grip_force * lz, grip_force * lx)
    roll = 2.0 * mu * grip_force * radius
    if contact == "line_z":
        return GripCapacity(ft, peak_force, ft * lz / 4.0, grip_force * lz, roll)
    return GripCapacity(ft, peak_force, ft * lx / 4.0, roll, grip_force * lx)


@dataclasses.dataclass(frozen=True)
class GraspSpec:
    """How a task's prop is held.

    Attributes:
        kind: "weld" (6-DoF hold, the grasp of every RoboTasks prop) or "connect" (grasp point
            only; kept for scenes that want a pivoting hold).
        body: the prop body attached to the hand.
        solref: [2] constraint solref (time constant s, damping ratio).
        solimp: [5] constraint solimp.
        capacity: the grip's `GripCapacity` (None: never breaks on load).
        filter_steps: control steps the load ratio is averaged over before it breaks the grasp.
        max_slip: separation (m) of prop and grasp past which the prop is out of the fingers
            (a backstop: the load limit normally breaks the grasp first).
        max_slip_angle: likewise for the weld's orientation error (rad).
        slip_joints: ((joint name, lower, upper), ...): compliant directions of the grip (see
            the module docstring); the grasp slips out when joint q - q_at_grasp leaves
            [lower, upper] (m or rad; a ball joint: its rotation angle since the grasp, upper
            bound only).
        release_below: gripper commands below this open the gripper and release the prop.
        closed_opening: finger opening (m, each finger) commanded while closed, so the fingers
            rest on the prop's surface instead of passing through it.
        exclude: further prop bodies whose contacts with the gripper are excluded.
        prop_pos: [3] "weld": the prop's position in the grasp-site frame (the grasp site is
            0.1034 m along the hand's z axis, with the hand's orientation), metres.
        prop_quat: [4] "weld": the prop's orientation in the grasp-site frame (w, x, y, z).
    """

    kind: str
    body: str
    solref: tuple[float, float] = (0.01, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    capacity: GripCapacity | None = None
    filter_steps: int = 6
    max_slip: float = 0.03
    max_slip_angle: float = 0.5
    slip_joints: tuple[tuple[str, float, float], ...] = ()
    release_below: float = 0.5
    closed_opening: float = 0.0
    exclude: tuple[str, ...] = ()
    prop_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    prop_quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"grasp kind must be one of {KINDS}, got {self.kind!r}")
        if not self.max_slip > 0 or not self.max_slip_angle > 0:
            raise ValueError(f"max_slip ({self.max_slip}) and max_slip_angle "
                             f"({self.max_slip_angle}) must be > 0")
        if self.filter_steps < 1:
            raise ValueError(f"filter_steps must be >= 1, got {self.filter_steps}")
        if not 0.0 <= self.closed_opening <= 0.04:
            raise ValueError(f"closed_opening must be in [0, 0.04] m, got {self.closed_opening}")
        if len(self.prop_pos) != 3 or len(self.prop_quat) != 4 or not (
                abs(float(np.linalg.norm(self.prop_quat)) - 1.0) < 1e-6):
            raise ValueError(f"prop_pos must be [3] and prop_quat a unit [4] (w, x, y, z); got "
                             f"{self.prop_pos}, {self.prop_quat}")
        for entry in self.slip_joints:
            if len(entry) != 3 or not entry[1] <= entry[2]:
                raise ValueError(f"slip_joints entries are (joint, lower, upper) with lower <= "
                                 f"upper, got {entry!r}")


def _eq_data(spec: GraspSpec) -> np.ndarray:
    """The constraint's `eq_data`: connect: [anchor in hand, anchor in prop]; weld: [anchor in
    prop (its origin), prop pose in the hand frame (pos, quat), torque scale]."""
    data = np.zeros(mujoco.mjNEQDATA)
    if spec.kind == "connect":
        data[0:3] = (0.0, 0.0, GRASP_OFFSET)
    else:
        data[3:6] = np.asarray(spec.prop_pos, dtype=float) + (0.0, 0.0, GRASP_OFFSET)
        data[6:10] = spec.prop_quat
        data[10] = 1.0
    return data


def constraint_name(spec: GraspSpec) -> str:
    """Name of the equality constraint that holds `spec.body`."""
    return f"grasp_{spec.body}"


def add_grasp_constraint(mjspec: mujoco.MjSpec, spec: GraspSpec) -> None:
    """Adds the (inactive) equality constraint holding `spec.body` to the hand, and excludes
    contacts between the gripper bodies and the prop (and `spec.exclude`).

    "weld" holds the prop body's origin at `spec.prop_pos`, `spec.prop_quat` in the grasp-site
    frame; "connect" anchors at the grasp point (0.1034 m along the hand's z axis) and at the
    prop body's origin.
    """
    if mjspec.body(spec.body) is None:
        raise ValueError(f"the scene has no body {spec.body!r} to grasp; check the task's MJCF")
    eq = mjspec.add_equality()
    eq.name = constraint_name(spec)
    eq.type = (mujoco.mjtEq.mjEQ_WELD if spec.kind == "weld" else mujoco.mjtEq.mjEQ_CONNECT)
    eq.objtype = mujoco.mjtObj.mjOBJ_BODY
    eq.name1 = HAND_BODY
    eq.name2 = spec.body
    eq.active = False
    eq.solref = list(spec.solref)
    eq.solimp = list(spec.solimp)
    eq.data = _eq_data(spec)
    for prop in (spec.body,) + tuple(spec.exclude):
        for gripper_body in GRIPPER_BODIES:
            ex = mjspec.add_exclude()
            ex.bodyname1 = gripper_body
            ex.bodyname2 = prop


class Grasp:
    """Runtime state of one grasp in a compiled model.

    Args:
        model: compiled model holding the constraint added by `add_grasp_constraint`.
        spec: the same `GraspSpec`.
        control_dt: the period (s) between `update` calls (the env's control period).
    """

    def __init__(self, model: mujoco.MjModel, spec: GraspSpec, control_dt: float = 1.0 / 60.0):
        self.spec = spec
        self.model = model
        name = constraint_name(spec)
        self.eq_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, name)
        if self.eq_id < 0:
            raise ValueError(f"model has no equality {name!r}; build the scene with "
                             "clfd_bench.sim.grasp.add_grasp_constraint")
        self.hand_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, HAND_BODY)
        self.body_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, spec.body)
        # The compiler fills anchors / relative poses left zero from qpos0: set them again.
        model.eq_data[self.eq_id] = _eq_data(spec)
        self._slip = []
        for jname, lo, hi in spec.slip_joints:
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, jname)
            if j < 0:
                raise ValueError(f"grasp slip joint {jname!r} is not in the model")
            ball = model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
                raise ValueError(f"grasp slip joint {jname!r} must be a slide, hinge or ball")
            self._slip.append((jname, int(model.jnt_qposadr[j]), ball, float(lo), float(hi)))
        self._slip_start: dict[str, np.ndarray] = {}
        self.control_dt = float(control_dt)
        jnt = model.body_jntadr[self.body_id]
        #: whether the load is the momentum-based control-period average (a free prop body
        #: without child bodies) or the weld's `efc_force` reading.
        self.free_prop = bool(jnt >= 0 and model.jnt_type[jnt] == mujoco.mjtJoint.mjJNT_FREE
                              and not np.any(model.body_parentid[1:] == self.body_id))
        self._mass = float(model.body_mass[self.body_id])
        self._weight = self._mass * model.opt.gravity.copy()
        self._weight_list = self._weight.tolist()
        self._inertia = model.body_inertia[self.body_id].copy()
        self._vel = np.empty(6)
        self._view_data: mujoco.MjData | None = None
        self._v: dict[str, np.ndarray] = {}
        self._sum = 0.0
        self._rows_cache: tuple[int, int, mujoco.MjData | None] = (-1, -1, None)
        self._momentum_prev: tuple[np.ndarray, np.ndarray] | None = None
        self._history = np.zeros(spec.filter_steps)
        self._count = 0
        self._reset_record()

    def _reset_record(self) -> None:
        #: why the prop was let go: None (still held or never attached), "opened" or "slipped".
        self.release_reason: str | None = None
        #: what made it slip (e.g. "torsion load 1.3 x capacity"), None otherwise.
        self.slip_cause: str | None = None
        #: largest filtered load ratio of this grasp so far (1 = at the grip's capacity).
        self.max_load: float = 0.0
        #: the largest slip of each slip joint so far, as a fraction of its bound.
        self.max_slip_fraction: float = 0.0
        self._history[:] = 0.0
        self._sum = 0.0
        self._count = 0

    # ------------------------------------------------------------------ queries
    def held(self, data: mujoco.MjData) -> bool:
        """Whether the prop is attached now."""
        if self._view_data is not data:
            self._views(data)
        return bool(self._eq_active[self.eq_id])

    def held_pose(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """World pose (position [3], quaternion [4]) where the grasp holds the prop body's origin
        ("connect": the grasp point; its orientation is the hand's)."""
        eq = self.model.eq_data[self.eq_id]
        hpos, hquat = data.xpos[self.hand_id], data.xquat[self.hand_id]
        local = eq[0:3] if self.spec.kind == "connect" else eq[3:6]
        pos = np.empty(3)
        mujoco.mju_rotVecQuat(pos, local, hquat)
        quat = hquat.copy()
        if self.spec.kind == "weld":
            mujoco.mju_mulQuat(quat, hquat, eq[6:10])
        return hpos + pos, quat

    def separation(self, data: mujoco.MjData) -> tuple[float, float]:
        """(distance m, angle rad) between where the grasp holds the prop and where it is
        (the angle is 0 for "connect")."""
        pos, quat = self.held_pose(data)
        dist = float(np.linalg.norm(pos - data.xpos[self.body_id]))
        if self.spec.kind == "connect":
            return dist, 0.0
        d = abs(float(np.dot(quat, data.xquat[self.body_id])))
        return dist, 2.0 * float(np.arccos(min(d, 1.0)))

    def _rows(self, data: mujoco.MjData) -> int:
        """Index of the grasp constraint's first row in the constraint arrays, or -1 (inactive).
        The equality rows come first, ordered by constraint id."""
        ne = data.ne
        if ne == self._rows_cache[0] and self._rows_cache[2] is data:
            r0 = self._rows_cache[1]
            if r0 < 0 or data.efc_id[r0] == self.eq_id:
                return r0
        ids = data.efc_id[:ne]
        r0 = int(np.searchsorted(ids, self.eq_id))
        r0 = r0 if r0 < len(ids) and ids[r0] == self.eq_id else -1
        self._rows_cache = (ne, r0, data)
        return r0

    def _views(self, data: mujoco.MjData) -> dict[str, np.ndarray]:
        """Views of `data`'s rows the load computation reads (cached per MjData: MuJoCo's
        arrays of an MjData never move)."""
        if self._view_data is not data:
            b = self.body_id
            self._v = {"xpos": data.xpos[b], "xipos": data.xipos[b],
                       "xmat": data.xmat[b].reshape(3, 3), "ximat": data.ximat[b].reshape(3, 3),
                       "hand_xmat": data.xmat[self.hand_id].reshape(3, 3),
                       "hand_xmat_T": data.xmat[self.hand_id].reshape(3, 3).T,
                       "cfrc_ext": data.cfrc_ext[b],
                       "subtree_com": data.subtree_com[self.model.body_rootid[b]]}
            self._eq_active = data.eq_active
            self._view_data = data
        return self._v

    def wrench(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """The wrench the grasp constraint applies to the prop now (at the last physics step):
        force [3] (N) at the prop body's origin and torque [3] (Nm), both in the grasp-site
        frame (hand axes). Zero when the prop is not held."""
        r0 = self._rows(data)
        if r0 < 0:
            return np.zeros(3), np.zeros(3)
        v = self._views(data)
        hand_rot = v["hand_xmat"]
        if self.spec.kind == "connect":
            return -(hand_rot.T @ data.efc_force[r0:r0 + 3]), np.zeros(3)
        f = data.efc_force[r0:r0 + 6]
        # Force rows: world frame, constraint space = position(prop) - position(hand); rotation
        # rows: ~2 x the torque on the prop, in its frame.
        return -(hand_rot.T @ f[0:3]), -0.5 * (hand_rot.T @ (v["xmat"] @ f[3:6]))

    def _momentum(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """The prop's linear momentum [3] and angular momentum about its centre of mass [3],
        world frame."""
        vel = self._vel
        mujoco.mj_objectVelocity(self.model, data, mujoco.mjtObj.mjOBJ_BODY, self.body_id, vel, 0)
        rot = self._views(data)["ximat"]
        return self._mass * vel[3:], rot @ (self._inertia * (rot.T @ vel[:3]))

    def _contact_wrench(self, data: mujoco.MjData, com: list[float] | None = None,
                        origin: list[float] | None = None
                        ) -> tuple[list[float], list[float]]:
        """The contact forces on the prop now: force [3] and torque about its centre of mass
        [3], world frame, as floats. MuJoCo's `cfrc_ext` (contacts and the weld) less the
        weld's rows. Elementwise arithmetic on floats (the same IEEE operations as on numpy
        [3] vectors, in the same order); the one matrix product stays numpy's. `com`,
        `origin`: the prop's centre of mass and origin [3] (world) when already read."""
        if data.ncon == 0:
            return [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        mujoco.mj_rnePostConstraint(self.model, data)
        v = self._views(data)
        # [torque, force] about the subtree com of the prop's tree
        ext = v["cfrc_ext"].tolist()
        force = ext[3:]
        com = v["xipos"].tolist() if com is None else com
        arm = _cross(_sub(v["subtree_com"].tolist(), com), force)
        torque = [ext[k] + arm[k] for k in range(3)]
        r0 = self._rows(data)
        if r0 >= 0:
            f = data.efc_force[r0:r0 + 6]
            weld = [-x for x in f[0:3].tolist()]  # the weld's force on the prop
            force = [force[k] - weld[k] for k in range(3)]
            rot = (v["xmat"] @ f[3:6]).tolist()
            origin = v["xpos"].tolist() if origin is None else origin
            arm = _cross(_sub(origin, com), weld)
            torque = [torque[k] - (-0.5 * rot[k] + arm[k]) for k in range(3)]
        return force, torque

    def mean_wrench(self, data: mujoco.MjData,
                    momentum: tuple[np.ndarray, np.ndarray] | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
        """The weld's wrench on a free prop averaged over the last control period (see the
        module docstring): force [3] (N) at the prop body's origin and torque [3] (Nm) about
        it, in the grasp-site frame. Needs the momentum at the period's start (`update` keeps
        it; the first call after `attach` takes the prop as at rest before); `momentum` is the
        current one if already computed. (Elementwise on floats, as `_contact_wrench`.)"""
        p1, l1 = momentum if momentum is not None else self._momentum(data)
        if self._momentum_prev is not None:
            p0, l0 = self._momentum_prev[0].tolist(), self._momentum_prev[1].tolist()
        else:
            p0 = l0 = [0.0, 0.0, 0.0]
        v = self._views(data)
        origin, com = v["xpos"].tolist(), v["xipos"].tolist()
        fc, tc = self._contact_wrench(data, com, origin)
        rate = 1.0 / self.control_dt
        p1, l1, w = p1.tolist(), l1.tolist(), self._weight_list
        force = [(p1[k] - p0[k]) * rate - w[k] - fc[k] for k in range(3)]
        arm = _cross(_sub(origin, com), force)
        torque = [(l1[k] - l0[k]) * rate - tc[k] - arm[k] for k in range(3)]
        hand_rot_t = v["hand_xmat_T"]
        return hand_rot_t @ np.array(force), hand_rot_t @ np.array(torque)

    def load(self, data: mujoco.MjData, momentum: tuple[np.ndarray, np.ndarray] | None = None
             ) -> tuple[float, str]:
        """Unfiltered load ratio of the weld's wrench (`mean_wrench` for a free prop, else
        `wrench`) against the grip's capacity, and the tightest limit (0.0, "" without a
        capacity). `mean_wrench` needs `update`'s bookkeeping: call this from `update`."""
        if self.spec.capacity is None:
            return 0.0, ""
        force, torque = (self.mean_wrench(data, momentum) if self.free_prop
                         else self.wrench(data))
        return self.spec.capacity.ratio(force, torque)

    def slips(self, data: mujoco.MjData) -> dict[str, float]:
        """Each slip joint's motion since the grasp (m or rad; ball: rotation angle)."""
        out = {}
        for name, adr, ball, _, _ in self._slip:
            if name not in self._slip_start:
                continue
            if ball:
                q0 = self._slip_start[name]
                d = abs(float(np.dot(q0, data.qpos[adr:adr + 4])))
                out[name] = 2.0 * float(np.arccos(min(d, 1.0)))
            else:
                out[name] = float(data.qpos[adr] - self._slip_start[name][0])
        return out

    # ------------------------------------------------------------------ changes
    def attach(self, data: mujoco.MjData) -> None:
        """Starts holding the prop (place it at `held_pose` first, see the scenes' `reset`)."""
        data.eq_active[self.eq_id] = 1
        self._reset_record()
        self._momentum_prev = self._momentum(data) if self.free_prop else None
        self._slip_start = {}
        for name, adr, ball, _, _ in self._slip:
            self._slip_start[name] = data.qpos[adr:adr + (4 if ball else 1)].copy()

    def release(self, data: mujoco.MjData, reason: str = "opened") -> None:
        """Lets the prop go (no-op when it is not held)."""
        if self.held(data):
            data.eq_active[self.eq_id] = 0
            self.release_reason = reason

    def update(self, data: mujoco.MjData) -> None:
        """Lets the prop slip out when the grip cannot hold it (call once per control step,
        after the physics): filtered load over capacity, a slip joint past its bound, or the
        prop pulled `max_slip` / `max_slip_angle` away from the grasp."""
        if not self.held(data):
            return
        momentum = self._momentum(data) if self.free_prop else None
        ratio, which = self.load(data, momentum)
        self._momentum_prev = momentum
        n = len(self._history)
        slot = self._count % n
        self._sum += ratio - self._history[slot]
        self._history[slot] = ratio
        self._count += 1
        filtered = self._sum / n if self._count >= n else 0.0
        if filtered > self.max_load:
            self.max_load = filtered
        if filtered > 1.0:
            self.slip_cause = (f"{which} load {filtered:.2f} x the grip's capacity over "
                               f"{len(self._history)} control steps")
            self.release(data, "slipped")
            return
        qpos = data.qpos
        for name, adr, ball, lo, hi in self._slip:
            start = self._slip_start.get(name)
            if start is None:
                continue
            if ball:
                q = qpos[adr:adr + 4]
                d = abs(start[0] * q[0] + start[1] * q[1] + start[2] * q[2] + start[3] * q[3])
                s = 2.0 * math.acos(min(float(d), 1.0))
            else:
                s = float(qpos[adr] - start[0])
            frac = s / hi if s >= 0 else (s / lo if lo < 0 else math.inf)
            if frac > self.max_slip_fraction:
                self.max_slip_fraction = float(frac)
            if s > hi or (not ball and s < lo):
                self.slip_cause = (f"{name} moved {s:.4f} from where it was grasped, beyond "
                                   f"[{lo}, {hi}]")
                self.release(data, "slipped")
                return
        if self.spec.capacity is None or self._count % 10 == 0:  # a backstop: rarely needed
            dist, angle = self.separation(data)
            if dist > self.spec.max_slip or angle > self.spec.max_slip_angle:
                self.slip_cause = (f"pulled {dist:.3f} m / {np.degrees(angle):.1f} deg off the "
                                   "grasp")
                self.release(data, "slipped")

    # ------------------------------------------------------------------ pickling
    def state(self) -> dict[str, Any]:
        """Bookkeeping beyond the physics state (for the env's pickled episode state)."""
        return {"release_reason": self.release_reason, "slip_cause": self.slip_cause,
                "max_load": self.max_load, "max_slip_fraction": self.max_slip_fraction,
                "history": self._history.copy(), "count": self._count,
                "slip_start": {k: v.copy() for k, v in self._slip_start.items()},
                "momentum_prev": (None if self._momentum_prev is None else
                                  [v.copy() for v in self._momentum_prev])}

    def restore(self, state: dict[str, Any]) -> None:
        self.release_reason = state["release_reason"]
        self.slip_cause = state.get("slip_cause")
        self.max_load = float(state.get("max_load", 0.0))
        self.max_slip_fraction = float(state.get("max_slip_fraction", 0.0))
        self._history = np.asarray(state.get("history", self._history), dtype=float).copy()
        self._sum = float(self._history.sum())
        self._count = int(state.get("count", 0))
        self._slip_start = {k: np.asarray(v, dtype=float).copy()
                            for k, v in state.get("slip_start", {}).items()}
        mom = state.get("momentum_prev")
        self._momentum_prev = None if mom is None else tuple(np.asarray(v, dtype=float).copy()
                                                             for v in mom)
