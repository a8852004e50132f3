"""The grasp model of the RoboTasks scenes: a prop held in the closed gripper.

The Panda's fingers do not physically squeeze the prop. Instead, while the gripper is closed
the prop is attached to the `hand` body by a MuJoCo equality constraint, and the contacts
between the gripper (hand and fingers) and the prop are excluded:

- `weld` (bottle, plate, cup): the prop keeps the pose relative to the hand it had when it was
  attached (6 DoF held, like a firm grasp);
- `connect` (box lid): only the grasp point is held (3 DoF); the lid's handle body slides on
  the lid, so the gripper pinches the lid edge like a flange that can slide between the
  fingertips: radial and axial offsets of the hand's path from the lid's circle are absorbed,
  only the lid's hinge angle follows the hand.

The constraint is soft (its `solref`/`solimp`), so a prop pushed against an obstacle gives way a
little. When the separation between the grasp point and the prop's attachment point exceeds
`max_slip` (metres) or the weld's orientation error exceeds `max_slip_angle` (radians), the prop
slips out of the gripper: the constraint is switched off, as when the gripper opens. After the
release nothing holds the prop and physics decides what happens to it. A released prop is never
re-grasped during the episode.

The constraint is a row of the compiled model (added to the spec by `add_grasp_constraint`);
its anchors and relative pose are fixed by the `GraspSpec` (so a rebuilt model holds the prop
the same way); switching it on/off writes `data.eq_active`, which MuJoCo keeps in the physics
state, so a saved and restored state keeps the grasp.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from clfd_bench.sim.robot import GRASP_OFFSET, HAND_BODY

#: Bodies of the gripper whose contacts with a held prop are excluded.
GRIPPER_BODIES: tuple[str, ...] = ("hand", "left_finger", "right_finger")
KINDS = ("weld", "connect")


@dataclasses.dataclass(frozen=True)
class GraspSpec:
    """How a task's prop is held.

    Attributes:
        kind: "weld" (6-DoF hold) or "connect" (grasp point only).
        body: the prop body attached to the hand (for "connect", the handle body).
        solref: [2] constraint solref (time constant s, damping ratio).
        solimp: [5] constraint solimp.
        max_slip: separation (m) past which the prop slips out of the gripper.
        max_slip_angle: weld orientation error (rad) past which the prop slips out.
        release_below: gripper commands below this open the gripper and release the prop.
        closed_opening: finger opening (m, each finger) commanded while closed, so the fingers
            rest on the prop's surface instead of passing through it.
        exclude: further prop bodies whose contacts with the gripper are excluded (e.g. the
            lid the handle slides on).
        prop_pos: [3] "weld": the prop's position in the grasp-site frame (the grasp site is
            0.1034 m along the hand's z axis, with the hand's orientation), metres.
        prop_quat: [4] "weld": the prop's orientation in the grasp-site frame (w, x, y, z).
    """

    kind: str
    body: str
    solref: tuple[float, float] = (0.01, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    max_slip: float = 0.03
    max_slip_angle: float = 0.5
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
        if not 0.0 <= self.closed_opening <= 0.04:
            raise ValueError(f"closed_opening must be in [0, 0.04] m, got {self.closed_opening}")
        if len(self.prop_pos) != 3 or len(self.prop_quat) != 4 or not (
                abs(float(np.linalg.norm(self.prop_quat)) - 1.0) < 1e-6):
            raise ValueError(f"prop_pos must be [3] and prop_quat a unit [4] (w, x, y, z); got "
                             f"{self.prop_pos}, {self.prop_quat}")


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

    "connect" anchors at the grasp point (0.1034 m along the hand's z axis) and at the prop
    body's origin; "weld" holds the prop body's origin at `spec.prop_pos`, `spec.prop_quat` in
    the grasp-site frame.
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
    """

    def __init__(self, model: mujoco.MjModel, spec: GraspSpec):
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
        #: why the prop was let go: None (still held or never attached), "opened" or "slipped".
        self.release_reason: str | None = None

    def held(self, data: mujoco.MjData) -> bool:
        """Whether the prop is attached now."""
        return bool(data.eq_active[self.eq_id])

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

    def attach(self, data: mujoco.MjData) -> None:
        """Starts holding the prop (place it at `held_pose` first, see the scenes' `reset`)."""
        data.eq_active[self.eq_id] = 1
        self.release_reason = None

    def release(self, data: mujoco.MjData, reason: str = "opened") -> None:
        """Lets the prop go (no-op when it is not held)."""
        if self.held(data):
            data.eq_active[self.eq_id] = 0
            self.release_reason = reason

    def separation(self, data: mujoco.MjData) -> tuple[float, float]:
        """(distance m, angle rad) between where the grasp holds the prop and where it is
        (the angle is 0 for "connect")."""
        pos, quat = self.held_pose(data)
        dist = float(np.linalg.norm(pos - data.xpos[self.body_id]))
        if self.spec.kind == "connect":
            return dist, 0.0
        d = abs(float(np.dot(quat, data.xquat[self.body_id])))
        return dist, 2.0 * float(np.arccos(min(d, 1.0)))

    def update(self, data: mujoco.MjData) -> None:
        """Lets the prop slip out when it was pulled too far from the grasp (call each step)."""
        if not self.held(data):
            return
        dist, angle = self.separation(data)
        if dist > self.spec.max_slip or angle > self.spec.max_slip_angle:
            self.release(data, "slipped")
