"""MatFolding's scene: a mat folded in half by its near edge."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.checks import checks_json
from clfd_bench.envs.robotasks.common import Scene, obj_id, set_free_pose
from clfd_bench.envs.robotasks.matfolding import success
from clfd_bench.sim.grasp import Grasp

__all__ = ["SCENE", "MatScene"]


class MatScene(Scene):
    """A mat (a rigid far half `mat0` and a chain of strips hinged about x, `tasks/matfolding.xml`)
    lying on the table, pinched at its near edge (`mat_pinch`, welded to the hand; the edge
    turns between the pads on a ball joint, as far as the grasp's slip bound allows) and folded
    in half. Success: `success.checks` (held until the gripper opens, let go where demo j lets go in
    the room; at the end folded in half; never dragged further than the demos drag it plus a
    margin). The mat is judged relative to itself, not by where on the table it ends: the demos
    themselves drag it (lifting the edge 8 cm while moving it 1 cm pulls the mat towards it) by
    8-14 cm in the replays (`max_root_shift`), and how far depends on the path (the strip chain
    exaggerates that: a `flexcomp` cloth on the same paths slides 1-3 cm, docs/execution.md). A
    path that folds the mat so is a valid alternative to demo j's."""

    object_bodies = ("mat0", "mat_pinch")

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.strips = []
        k = 0
        while mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"mat{k}") >= 0:
            self.strips.append(obj_id(model, mujoco.mjtObj.mjOBJ_BODY, f"mat{k}"))
            k += 1
        if len(self.strips) < 4:
            raise ValueError("the matfolding scene needs a plate mat0 and a chain of at least "
                             "3 strips mat1..")
        self.root = self.strips[0]
        self.pinch = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, "mat_pinch")
        self.hinges = [int(model.jnt_qposadr[obj_id(model, mujoco.mjtObj.mjOBJ_JOINT,
                                                  f"mat_hinge{k}")])
                       for k in range(1, len(self.strips))]
        self.turn_adr = int(model.jnt_qposadr[obj_id(model, mujoco.mjtObj.mjOBJ_JOINT,
                                                   "pinch_turn")])
        plate = obj_id(model, mujoco.mjtObj.mjOBJ_GEOM, "mat0_geom")
        strip = obj_id(model, mujoco.mjtObj.mjOBJ_GEOM, "mat1_geom")
        self.half_length = 2.0 * float(model.geom_size[plate][1])  # the far half, along y
        self.width = 2.0 * float(model.geom_size[strip][1])  # a strip of the near half
        self.half_thick = float(model.geom_size[plate][2])
        self.root_start = np.zeros(3)

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        """The mat flat on the table along +y from its near edge, whose middle is at the grasp
        point; where the grasp point is above the mat, the last one or two strips ramp up to
        it."""
        self.demo = demo
        mujoco.mj_kinematics(self.model, data)
        g = data.site_xpos[self.grasp_site].copy()
        n, w = len(self.strips) - 1, self.width  # strips of the near half
        rise = float(g[2]) - (self.table_z + self.half_thick)
        ramp = max(1, math.ceil(rise / (0.9 * w)))
        if ramp > n // 2:
            raise ValueError(f"demo {demo}'s grasp point is {rise:.3f} m above the mat: the "
                             "matfolding scene does not fit this demo; regenerate "
                             "tasks/matfolding.toml")
        theta = math.asin(max(0.0, rise) / (ramp * w))
        for adr in self.hinges:
            data.qpos[adr] = 0.0
        data.qpos[self.hinges[n - ramp]] = -theta  # the hinge of strip n - ramp + 1
        # far edge to near edge along y
        reach = self.half_length + (n - ramp) * w + ramp * w * math.cos(theta)
        root = np.array([g[0], g[1] + reach, self.table_z + self.half_thick])
        set_free_pose(self.model, data, self.root, root, np.array([1.0, 0.0, 0.0, 0.0]))
        self.root_start = root
        mujoco.mj_kinematics(self.model, data)
        # the pinch takes the hand's orientation (the weld holds it there)
        turn, inv = np.empty(4), np.empty(4)
        mujoco.mju_negQuat(inv, data.xquat[self.strips[-1]])
        mujoco.mju_mulQuat(turn, inv, data.xquat[grasp.hand_id])
        data.qpos[self.turn_adr:self.turn_adr + 4] = turn / np.linalg.norm(turn)

    def near_edge(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the middle of the mat's near (pinched) edge (world)."""
        return data.xpos[self.pinch]

    def fold_vector(self, data: mujoco.MjData) -> np.ndarray:
        """[3] where the near edge's middle is in the far plate's frame (x along the edge, y
        towards the far edge, z up from the plate's middle plane; origin at the far edge's
        middle): (0, -mat length, 0) when flat, about (0, 0, 2 thicknesses) when folded edge
        on edge."""
        rot = data.xmat[self.root].reshape(3, 3)
        return rot.T @ (self.near_edge(data) - data.xpos[self.root])

    def heading_deg(self, data: mujoco.MjData) -> float:
        """The far plate's heading on the table (deg): the angle of its x axis (along its edges)
        from the world x, about the vertical; 0 as it is laid at reset."""
        rot = data.xmat[self.root].reshape(3, 3)
        return float(np.degrees(np.arctan2(rot[1, 0], rot[0, 0])))

    def turned_strips(self, data: mujoco.MjData) -> int:
        """How many strips of the near half lie turned over on the far half, in one layer: the
        strip upside down (its normal within 25 deg of the far plate's -z), its hinge over the
        far plate (in its frame: y within [-half length, 0]) and at most `[success]
        max_layer_height` above the plate's middle plane."""
        rot = data.xmat[self.root].reshape(3, 3)
        ids = self.strips[1:]
        local = (data.xpos[ids] - data.xpos[self.root]) @ rot
        normal_z = (data.xmat[ids].reshape(-1, 3, 3)[:, :, 2] @ rot)[:, 2]
        layer = float(self.success_cfg["max_layer_height"])
        over = (local[:, 1] >= -self.half_length - 1e-3) & (local[:, 1] <= 1e-3)
        return int(np.count_nonzero((normal_z <= -math.cos(math.radians(25.0))) & over
                                    & (local[:, 2] <= layer)))

    def _ref(self, key: str) -> np.ndarray:
        """Demo j's row of a per-demo `[scene]` reference."""
        ref = np.asarray(self.scene[key], dtype=float)
        return self._demo_row(ref.reshape(len(ref), -1))

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record = {"max_root_shift": 0.0, "release_edge": None}

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        mujoco.mj_kinematics(self.model, data)
        self.record["release_edge"] = self.near_edge(data).copy()

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        p, s0 = data.xpos[self.root], self.root_start
        shift = math.hypot(float(p[0] - s0[0]), float(p[1] - s0[1]))
        if shift > self.record["max_root_shift"]:
            self.record["max_root_shift"] = shift

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        rec = self.record
        edge_off = None
        if rec["release_edge"] is not None:
            edge_off = float(np.linalg.norm(rec["release_edge"] - self._ref("release_edge")))
        turned = self.turned_strips(data)
        height = float(data.xpos[self.root, 2] - self.table_z)
        checks = success.checks(grasp.release_reason, edge_off, height, turned,
                                float(rec["max_root_shift"]), self.success_cfg)
        passed = {c.name: c.passed for c in checks}
        ok = all(passed.values()) and not grasp.held(data)
        return ok, {"release_offset": edge_off, "fold_end_y": float(self.fold_vector(data)[1]),
                    "turned_strips": turned,
                    "mat_folded": all(passed[n] for n in success.MAT_FOLD_CHECKS),
                    "mat_heading_deg": self.heading_deg(data),
                    "max_root_shift": float(rec["max_root_shift"]),
                    "checks": checks_json(checks)}

    def scene_state(self) -> dict[str, Any]:
        state = super().scene_state()
        state["root_start"] = self.root_start.copy()
        return state

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        super().restore_scene_state(state)
        self.root_start = np.asarray(state["root_start"], dtype=float).copy()


SCENE = MatScene
