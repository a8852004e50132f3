"""BoxOpening's scene: a storage box whose lid turns on friction hinges."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.checks import checks_json
from clfd_bench.envs.robotasks.common import Scene, obj_id, yaw_quat
from clfd_bench.envs.robotasks.openbox import success
from clfd_bench.sim.grasp import Grasp

__all__ = ["SCENE", "OpenBoxScene"]


class OpenBoxScene(Scene):
    """A storage box whose lid turns on friction hinges (it stays where it is left). The gripper
    pinches the lid's front edge (`lid_handle`, welded to the hand): the edge may slide in the
    fingers (radially and along the hinge) and turn between them as far as the demonstrations
    need (`[grasp] slip_joints`), no further: past that it slips out. Placed by `[scene]
    hinge_pos`, `hinge_yaw_deg` (the hinge axis fitted to the demos' arcs)."""

    object_bodies = ("lid", "lid_handle")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        box = spec.body("box")
        box.pos = list(self.scene["hinge_pos"])
        box.quat = list(yaw_quat(np.radians(self.scene["hinge_yaw_deg"])))

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.box = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, "box")
        self.lid = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, "lid")
        self.handle = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, "lid_handle")
        j = {n: obj_id(model, mujoco.mjtObj.mjOBJ_JOINT, n)
             for n in ("lid_hinge", "handle_axial", "handle_radial", "handle_turn")}
        self.qadr = {n: int(model.jnt_qposadr[i]) for n, i in j.items()}
        self.jrange = {n: model.jnt_range[i].copy() for n, i in j.items()}
        self.handle_rest = model.body_pos[self.handle].copy()  # in the lid frame: (x, r, h)

    def lid_angle(self, data: mujoco.MjData) -> float:
        """Lid hinge angle, degrees (0 closed, positive open)."""
        return float(np.degrees(data.qpos[self.qadr["lid_hinge"]]))

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        # The grasp point in the hinge frame decides the lid angle and the edge's place in the
        # fingers (the handle's slides); the handle takes the hand's orientation (ball joint).
        rot = data.xmat[self.box].reshape(3, 3)
        local = rot.T @ (data.site_xpos[self.grasp_site] - data.xpos[self.box])
        x0, r0, h = self.handle_rest
        rho2 = local[1] ** 2 + local[2] ** 2
        r = float(np.sqrt(max(rho2 - h * h, 1e-12)))
        angle = float(np.arctan2(local[2], local[1]) - np.arctan2(h, r))
        lo, hi = self.jrange["lid_hinge"]
        if not lo <= angle <= hi:
            raise ValueError(f"demo {demo}'s start puts the gripper at lid angle "
                             f"{np.degrees(angle):.1f} deg, outside the hinge's range: the openbox "
                             "scene does not fit this demo; regenerate tasks/openbox.toml")
        data.qpos[self.qadr["lid_hinge"]] = angle
        data.qpos[self.qadr["handle_radial"]] = r - r0
        data.qpos[self.qadr["handle_axial"]] = local[0] - x0
        mujoco.mj_kinematics(self.model, data)
        lid_q = data.xquat[self.lid]
        hand_q = data.xquat[grasp.hand_id]
        turn = np.empty(4)
        inv = np.empty(4)
        mujoco.mju_negQuat(inv, lid_q)
        mujoco.mju_mulQuat(turn, inv, hand_q)
        adr = self.qadr["handle_turn"]
        data.qpos[adr:adr + 4] = turn / np.linalg.norm(turn)
        self.demo = demo

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        angle = self.lid_angle(data)
        need = np.atleast_1d(np.asarray(self.success_cfg["min_open_angle_deg"], dtype=float))
        self.record = {"max_held_angle": angle, "release_angle": None,
                       "need": float(self._demo_row(need))}

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        if grasp.held(data):
            angle = self.lid_angle(data)
            if angle > self.record["max_held_angle"]:
                self.record["max_held_angle"] = angle

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record["release_angle"] = self.lid_angle(data)

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        angle = self.lid_angle(data)
        need = self.record["need"]
        held_max = float(self.record["max_held_angle"])
        checks = success.checks(held_max, need, grasp.release_reason, angle, self.success_cfg)
        ok = all(ch.passed for ch in checks)
        return ok, {"lid_angle_deg": angle, "lid_max_held_angle_deg": held_max,
                    "lid_open_needed_deg": need, "lid_opened_by_grasp": bool(held_max >= need),
                    "checks": checks_json(checks)}


SCENE = OpenBoxScene
