"""PlateStacking's scene: a plate taken out of a dish rack and laid on a platform."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.checks import checks_json
from clfd_bench.envs.robotasks.common import obj_id, set_free_pose, tilt_from_vertical, yaw_quat
from clfd_bench.envs.robotasks.placing import KnockWatch, PlaceScene
from clfd_bench.envs.robotasks.platestandingtolying import success
from clfd_bench.sim.grasp import Grasp

__all__ = ["SCENE", "PlateScene"]


class PlateScene(PlaceScene):
    """A plate standing in a dish rack (a base with four pegs, one free body); a platform where
    the demos end. Success: `success.checks` (the rack never knocked; released by opening,
    low and where the demos release it; lying on the platform)."""

    object_bodies = ("plate", "rack")
    prop, support, support_half_key = "plate", "platform", "platform_half_size"
    support_geoms = ("platform_top", "platform_support")
    pegs = ("rack_peg1", "rack_peg2", "rack_peg3", "rack_peg4")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        # The rack (rack frame: origin on the table under the plate's centre): pegs at
        # `block_offsets`, from the base up to `block_height` above the table; the base spans
        # the pegs' footprint.
        t = float(s.get("rack_base_thickness", 0.005))
        height = float(s.get("block_height", 0.024))
        offsets = np.asarray(s["block_offsets"], dtype=float)
        peg = spec.geom(self.pegs[0]).size
        for name, (x, y) in zip(self.pegs, offsets, strict=True):
            g = spec.geom(name)
            g.size = [peg[0], peg[1], (height - t) / 2]
            g.pos = [float(x), float(y), t + (height - t) / 2]
        lo, hi = offsets.min(0) - [peg[0], peg[1]], offsets.max(0) + [peg[0], peg[1]]
        base = spec.geom("rack_base")
        base.size = [float(hi[0] - lo[0]) / 2, float(hi[1] - lo[1]) / 2, t / 2]
        base.pos = [float(hi[0] + lo[0]) / 2, float(hi[1] + lo[1]) / 2, t / 2]

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.disc = obj_id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate_disc")
        self.rack = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, "rack")
        self.rack_watch = KnockWatch(self.rack)

    def prop_centre(self, data: mujoco.MjData) -> np.ndarray:
        return data.geom_xpos[self.disc]

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self.place_held_prop(data, grasp)
        mujoco.mj_kinematics(self.model, data)
        # The rack stands on the table under the plate, turned with the plate's plane.
        centre = data.geom_xpos[self.disc]
        in_plane = data.xmat[grasp.body_id].reshape(3, 3)[:, 0]
        yaw = float(np.arctan2(in_plane[1], in_plane[0]))
        pos = np.array([centre[0], centre[1], self.table_z])
        set_free_pose(self.model, data, self.rack, pos, yaw_quat(yaw))
        self.rack_watch.place(pos)

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        super().start_record(data, grasp)
        self.record.update({"max_rack_shift": 0.0, "max_rack_tilt_deg": 0.0})

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.rack_watch.track(data, self.record, "rack")

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        rec = self.record
        h, off = self.released()
        on_top, height = self._on_support(data, data.geom_xpos[self.disc])
        normal = data.xmat[grasp.body_id].reshape(3, 3)[:, 1]
        tilt = tilt_from_vertical(normal)
        checks = success.checks(rec["max_rack_shift"], rec["max_rack_tilt_deg"],
                                grasp.release_reason, grasp.held(data), h, off, on_top, tilt,
                                height, self.success_cfg)
        info = {"release_height": h, "release_offset": off, "plate_tilt_deg": tilt,
                "plate_height": height, "on_platform": on_top,
                "max_rack_shift": float(rec["max_rack_shift"]),
                "max_rack_tilt_deg": float(rec["max_rack_tilt_deg"]),
                "rack_in_place": all(ch.passed for ch in checks[:2]),
                "checks": checks_json(checks)}
        return all(ch.passed for ch in checks), info

    def scene_state(self) -> dict[str, Any]:
        state = super().scene_state()
        state["rack_start"] = self.rack_watch.start.copy()
        return state

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        super().restore_scene_state(state)
        self.rack_watch.place(state["rack_start"])


SCENE = PlateScene
