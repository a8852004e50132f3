"""The simulated Franka Panda: the Menagerie model plus the project's additions.

`panda_spec()` loads the Menagerie `franka_emika_panda` scene (robot, floor, light) through the
`mujoco_menagerie` package (which honours `MENAGERIE_ROOT`) and composes the project's own MJCF
from `assets/panda/` into it with `mujoco.MjSpec` attach:

- site `grasp`, 0.1034 m along the `hand` body's z axis (the fingertips' grasp point, where
  props held in the gripper go);
- with `tool="pen"`: a spring-loaded pen held between the fingers (body `pen`, slide joint
  `pen_slide`, site `pen_tip` 0.16 m along the hand's z axis).

The frame the datasets describe is the Menagerie `hand` body itself (offset 0): RoboTasks poses
are `hand` poses in the Panda base frame (`link0` at the world origin). Tweaks applied here:
gravity compensation on every robot body (as the real Panda's controller does), so that the
Menagerie joint position servos hold the arm without sag; no robot self-collisions (robot geoms
contype 2 / conaffinity 1, so they still collide with the floor and task objects).
"""

from __future__ import annotations

import functools

import mujoco
import numpy as np

from clfd_bench.resources import resource_path

MENAGERIE_NAME = "franka_emika_panda"
ARM_JOINTS: tuple[str, ...] = tuple(f"joint{i}" for i in range(1, 8))
ARM_ACTUATORS: tuple[str, ...] = tuple(f"actuator{i}" for i in range(1, 8))
FINGER_JOINTS: tuple[str, ...] = ("finger_joint1", "finger_joint2")
GRIPPER_ACTUATOR = "actuator8"
HAND_BODY = "hand"
GRASP_SITE = "grasp"
PEN_TIP_SITE = "pen_tip"
PEN_SLIDE_JOINT = "pen_slide"
ROBOT_BODIES: tuple[str, ...] = (
    "link0", "link1", "link2", "link3", "link4", "link5", "link6", "link7",
    "hand", "left_finger", "right_finger",
)
#: The joint whose axis point is the Panda's shoulder (joint 1's and 2's axes meet there, 0.333 m
#: above the base): the reach is measured from it.
SHOULDER_JOINT = "joint2"
#: Distance of the grasp point (between the fingertips) along the hand's z axis, metres.
GRASP_OFFSET = 0.1034
#: Distance of the relaxed pen tip along the hand's z axis, metres (see assets/panda/pen.xml).
PEN_TIP_OFFSET = 0.160
#: The Menagerie `home` keyframe's arm joints [7], radians.
HOME_QPOS = np.array([0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853])
#: Franka Panda joint velocity limits [7], rad/s (datasheet).
JOINT_VELOCITY_LIMITS = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
#: Finger opening (each finger, metres) when the gripper is fully open.
FINGER_OPEN = 0.04
#: Gripper actuator control range upper end (Menagerie maps 0..255 to 0..0.04 m per finger).
GRIPPER_CTRL_MAX = 255.0

TOOLS = (None, "pen")
#: Collision bits of robot geoms: they collide with the world and objects, not with each other.
ROBOT_CONTYPE = 2
ROBOT_CONAFFINITY = 1


def menagerie_dir():
    """The Menagerie `franka_emika_panda` directory (downloaded on first use unless
    `MENAGERIE_ROOT` points at a local Menagerie copy)."""
    import mujoco_menagerie

    return mujoco_menagerie.get(MENAGERIE_NAME).path()


_TMP_PREFIX = "clfdattach__"


def attach_spec(spec: mujoco.MjSpec, child: mujoco.MjSpec, parent: mujoco.MjsBody | None = None,
                prefix: str = "") -> mujoco.MjsFrame:
    """Attaches `child`'s worldbody (bodies, sites, geoms, ...) under `parent` (default: the
    world) of `spec`, with `prefix` prepended to the child's names (default: names kept as they
    are; they must then be unique in the composed model). Assets and defaults come along.

    Returns:
        The frame the child was attached to (move it with `.pos` / `.quat`).
    """
    frame = (parent if parent is not None else spec.worldbody).add_frame()
    # MjSpec warns about an empty prefix; attach with a unique temporary prefix, then rename the
    # elements and every string reference to them (geom.material, actuator.target, ...).
    spec.attach(child, prefix=_TMP_PREFIX, frame=frame)
    for group in _ELEMENT_GROUPS:
        for el in getattr(spec, group):
            _strip_prefix(el, prefix)
    return frame


_ELEMENT_GROUPS = (
    "bodies", "geoms", "sites", "joints", "cameras", "lights", "frames", "actuators", "sensors",
    "tendons", "equalities", "excludes", "pairs", "materials", "meshes", "textures", "hfields",
    "skins", "flexes", "keys", "numerics", "texts", "tuples",
)


def _strip_prefix(el: object, prefix: str) -> None:
    n = len(_TMP_PREFIX)
    for attr in dir(el):
        if attr.startswith("_") or attr in ("info", "signature"):
            continue
        try:
            value = getattr(el, attr)
        except Exception:  # noqa: BLE001 - some attributes are write-only or unsupported
            continue
        if isinstance(value, str):
            if value.startswith(_TMP_PREFIX):
                setattr(el, attr, prefix + value[n:])
        elif isinstance(value, mujoco.MjStringVec):
            items = list(value)
            if any(v.startswith(_TMP_PREFIX) for v in items):
                setattr(el, attr, [prefix + v[n:] if v.startswith(_TMP_PREFIX) else v
                                   for v in items])


def _attach_asset(spec: mujoco.MjSpec, parent: mujoco.MjsBody, name: str) -> None:
    child = mujoco.MjSpec.from_file(str(resource_path("assets", "panda", name)))
    attach_spec(spec, child, parent)


def _robot_collisions_only_with_world(spec: mujoco.MjSpec) -> None:
    """Robot geoms (links, hand, fingers, tools) get contype 2 / conaffinity 1: they collide
    with everything of contype 1 (floor, task objects: the MJCF default) but not with each other.
    The demos never self-collide, and skipping the robot's mesh-mesh self-collision checks
    halves the cost of a physics step."""
    stack = [spec.body(ROBOT_BODIES[0])]
    while stack:
        body = stack.pop()
        for geom in body.geoms:
            if geom.contype or geom.conaffinity:
                geom.contype, geom.conaffinity = ROBOT_CONTYPE, ROBOT_CONAFFINITY
        stack.extend(body.bodies)


def panda_spec(tool: str | None = None) -> mujoco.MjSpec:
    """The Panda scene as an editable spec: Menagerie scene (robot, floor, light) + `grasp` site
    (+ pen when `tool="pen"`), gravity compensation on the robot bodies, robot self-collisions
    off (robot geoms: contype 2 / conaffinity 1; task objects keep the default 1 / 1 and collide
    with the robot).

    Args:
        tool: None (gripper only) or "pen".

    Returns:
        A fresh `mujoco.MjSpec` (compile with `.compile()`).
    """
    if tool not in TOOLS:
        raise ValueError(f"unknown tool {tool!r}; valid tools: {TOOLS}")
    import mujoco_menagerie

    spec = mujoco_menagerie.get(MENAGERIE_NAME).spec("scene")
    spec.modelname = "clfd_panda" if tool is None else f"clfd_panda_{tool}"
    hand = spec.body(HAND_BODY)
    _attach_asset(spec, hand, "grasp.xml")
    if tool == "pen":
        _attach_asset(spec, hand, "pen.xml")
    for name in ROBOT_BODIES:
        spec.body(name).gravcomp = 1.0
    _robot_collisions_only_with_world(spec)
    # Offscreen framebuffer large enough for the default render sizes.
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, 1280)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, 960)
    return spec


@functools.lru_cache(maxsize=4)
def _robot_model_cached(tool: str | None) -> mujoco.MjModel:
    return panda_spec(tool).compile()


def robot_model(tool: str | None = None) -> mujoco.MjModel:
    """The compiled robot-only model (no task objects), e.g. for IK. Cached per tool: treat the
    returned model as read-only."""
    return _robot_model_cached(tool)


class RobotIndex:
    """Addresses of the Panda's joints and actuators in a compiled model (robot-only or a whole
    task scene).

    Attributes:
        arm_qpos: [7] qpos addresses of joint1..7.
        arm_dof: [7] dof addresses of joint1..7.
        arm_act: [7] actuator ids of actuator1..7.
        finger_qpos: [2] qpos addresses of the finger joints.
        gripper_act: actuator id of the gripper.
        hand_body: body id of `hand`.
        arm_ctrl_tau: [7] velocity-feedforward time constant kv/kp of each arm servo, seconds.
    """

    def __init__(self, model: mujoco.MjModel):
        def jid(name: str) -> int:
            i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if i < 0:
                raise ValueError(f"model has no joint {name!r}: is it a Panda scene from "
                                 "clfd_bench.sim.robot.panda_spec()?")
            return i

        arm = [jid(n) for n in ARM_JOINTS]
        self.arm_qpos = np.array([model.jnt_qposadr[j] for j in arm])
        self.arm_dof = np.array([model.jnt_dofadr[j] for j in arm])
        self.arm_act = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n)
                                 for n in ARM_ACTUATORS])
        a0 = int(self.arm_act[0])
        contiguous = np.array_equal(self.arm_act, np.arange(a0, a0 + 7))
        #: a slice for ctrl when the arm actuators are contiguous (faster), else the id array
        self.arm_act_slice = slice(a0, a0 + 7) if contiguous else self.arm_act
        fingers = [jid(n) for n in FINGER_JOINTS]
        self.finger_qpos = np.array([model.jnt_qposadr[j] for j in fingers])
        self.finger_dof = np.array([model.jnt_dofadr[j] for j in fingers])
        self.gripper_act = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, GRIPPER_ACTUATOR)
        self.hand_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, HAND_BODY)
        kp = -model.actuator_biasprm[self.arm_act, 1]
        kv = -model.actuator_biasprm[self.arm_act, 2]
        self.arm_ctrl_tau = kv / kp
        self.arm_ctrl_range = model.actuator_ctrlrange[self.arm_act].copy()
        self.arm_range = model.jnt_range[arm].copy()


def gripper_ctrl(opening: float) -> float:
    """Gripper actuator control for a finger opening in [0, FINGER_OPEN] metres per finger."""
    return min(max(float(opening) / FINGER_OPEN, 0.0), 1.0) * GRIPPER_CTRL_MAX


def hand_pose(model: mujoco.MjModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics of the `hand` body at arm configuration `q` [7].

    Returns:
        (position [3] m, quaternion [4] w,x,y,z) in the base (world) frame.
    """
    data = mujoco.MjData(model)
    idx = RobotIndex(model)
    data.qpos[idx.arm_qpos] = np.asarray(q, dtype=float)
    mujoco.mj_kinematics(model, data)
    return data.xpos[idx.hand_body].copy(), data.xquat[idx.hand_body].copy()
