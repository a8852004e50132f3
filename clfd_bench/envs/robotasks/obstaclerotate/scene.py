"""ObstacleRotate's scene: a box carried around an obstacle, turned on the way, put on a shelf."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.checks import checks_json
from clfd_bench.envs.robotasks.common import first_toucher, obj_id, tilt_from_vertical
from clfd_bench.envs.robotasks.obstaclerotate import success
from clfd_bench.envs.robotasks.placing import PlaceScene
from clfd_bench.sim.grasp import Grasp
from clfd_bench.sim.scene_fit import lowest_point

__all__ = ["SCENE", "ObstacleScene"]


class ObstacleScene(PlaceScene):
    """A box carried around an obstacle (a static block standing in the demos' bend), turned
    about the vertical on the way, and put down on a shelf. Success: `success.checks`
    (the obstacle never touched by the box or the arm; the box turned as the demos turn it;
    released by opening, low and where the demos release it; lying on the shelf)."""

    object_bodies = ("object",)
    prop, support, support_half_key = "object", "shelf", "shelf_half_size"
    support_geoms = ("shelf_board", "shelf_support")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        x0, x1, y0, y1 = (float(v) for v in s["obstacle_xy"])
        half_h = (float(s["obstacle_top"]) - self.table_z) / 2
        spec.body("obstacle").pos = [(x0 + x1) / 2, (y0 + y1) / 2, self.table_z]
        g = spec.geom("obstacle_box")
        g.size = [(x1 - x0) / 2, (y1 - y0) / 2, half_h]
        g.pos = [0.0, 0.0, half_h]

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.obstacle_geom = obj_id(model, mujoco.mjtObj.mjOBJ_GEOM, "obstacle_box")
        self._is_obstacle = np.zeros(model.ngeom, dtype=bool)
        self._is_obstacle[self.obstacle_geom] = True
        self._is_world_geom = model.geom_bodyid == 0  # the table plane it stands on
        self._obstacle_top = float(self.scene["obstacle_top"])
        self._turn_sign = float(self.success_cfg.get("turn_sign", 1.0))

    def _heading(self, data: mujoco.MjData) -> float:
        """Heading (rad) of the box's long axis (its x) seen from above."""
        x = data.xmat[self.prop_id].reshape(3, 3)[:, 0]
        return math.atan2(float(x[1]), float(x[0]))

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        super().start_record(data, grasp)
        self.record.update({"obstacle_touched_by": None, "heading": self._heading(data),
                            "turn": 0.0, "max_turn_deg": 0.0, "release_turn_deg": None})

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        super().on_release(data, grasp)
        self.record["release_turn_deg"] = math.degrees(self.record["turn"])

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """How far the held box has turned about the vertical, in the demos' direction (the
        heading unwrapped step by step), at most while its centre is lower than the obstacle's
        top (beside it, where the demos turn it); the first body that touches the obstacle
        (anything but the table it stands on)."""
        rec = self.record
        if grasp.held(data):  # the turn counts while the box passes beside the obstacle
            heading = self._heading(data)
            step = (heading - rec["heading"] + math.pi) % (2 * math.pi) - math.pi
            rec["heading"] = heading
            rec["turn"] += step
            turned = math.degrees(rec["turn"]) * self._turn_sign
            beside = data.xipos[self.prop_id][2] < self._obstacle_top
            if beside and turned > rec["max_turn_deg"]:
                rec["max_turn_deg"] = turned
        if rec["obstacle_touched_by"] is None:
            rec["obstacle_touched_by"] = first_toucher(self.model, data, self._is_obstacle,
                                                       self._is_world_geom)

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        on_top, _ = self._on_support(data, data.xipos[self.prop_id])
        height = lowest_point(self.model, data, self.prop) - float(self.scene["shelf_top"][2])
        z = data.xmat[self.prop_id].reshape(3, 3)[:, 2]
        tilt = tilt_from_vertical(z)
        touched = self.record["obstacle_touched_by"]
        back = self.record["release_turn_deg"]
        turn = float(self.record["max_turn_deg"])
        h, off = self.released()
        checks = success.checks(touched, turn, back, grasp.release_reason, grasp.held(data), h,
                                off, on_top, tilt, height, self.success_cfg)
        info = {"release_height": h, "release_offset": off, "object_tilt_deg": tilt,
                "object_height": height, "on_shelf": on_top, "obstacle_touched_by": touched,
                "object_max_turn_deg": turn, "object_release_turn_deg": back,
                "checks": checks_json(checks)}
        return all(ch.passed for ch in checks), info


SCENE = ObstacleScene
