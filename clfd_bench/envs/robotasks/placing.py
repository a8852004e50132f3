"""Scenes where a held prop is laid on a support (a shelf, a platform, a stove): `PlaceScene`;
and taken out of a tray or rack that must not be knocked first: `TrayPlaceScene`,
`KnockWatch`."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.checks import Check, checks_json
from clfd_bench.envs.robotasks.common import (
    Scene,
    box_walls,
    obj_id,
    set_free_pose,
    size_support,
    yaw_quat,
)
from clfd_bench.sim.grasp import Grasp
from clfd_bench.sim.scene_fit import lowest_point

__all__ = ["KnockWatch", "PlaceScene", "TrayPlaceScene"]


class KnockWatch:
    """Follows a free body that must not be knocked (a dish rack, a drying tray): its largest
    shift (m) from where it was put at reset and its largest tilt (deg) at any step."""

    def __init__(self, body: int):
        self.body = body
        self.start = np.zeros(3)

    def place(self, start: np.ndarray) -> None:
        """Where the body was put at reset (world position [3])."""
        self.start = np.asarray(start, dtype=float).copy()

    def track(self, data: mujoco.MjData, rec: dict[str, Any], name: str) -> None:
        """Updates `rec[f"max_{name}_shift"]` (m) and `rec[f"max_{name}_tilt_deg"]`."""
        p, s0 = data.xpos[self.body], self.start
        shift = math.sqrt((p[0] - s0[0]) ** 2 + (p[1] - s0[1]) ** 2 + (p[2] - s0[2]) ** 2)
        cos_tilt = abs(float(data.xmat[self.body, 8]))  # the body's z axis' world z component
        key_shift, key_tilt = f"max_{name}_shift", f"max_{name}_tilt_deg"
        if shift > rec[key_shift]:
            rec[key_shift] = shift
        tilt = math.degrees(math.acos(min(1.0, cos_tilt)))
        if tilt > rec[key_tilt]:
            rec[key_tilt] = tilt


class PlaceScene(Scene):
    """A held prop laid on a support (shelf, platform): the release and the end state count."""

    prop = ""
    support = ""
    support_half_key = ""
    #: (board, column) geoms of the support, sized from `[scene] <support>_top`,
    #: `support_half_key` and `<support>_yaw_deg`.
    support_geoms: tuple[str, str] = ("", "")

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        size_support(spec, self.support, s[self.support + "_top"], s[self.support_half_key],
                     np.radians(s.get(self.support + "_yaw_deg", 0.0)), self.table_z,
                     *self.support_geoms)

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.prop_id = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, self.prop)
        self.support_id = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, self.support)

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self.place_held_prop(data, grasp)

    def prop_centre(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the prop's centre (what `place_radius` is measured on)."""
        return data.xipos[self.prop_id]

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record = {"release_height": None, "release_offset": None, "release_point": None}

    def on_release(self, data: mujoco.MjData, grasp: Grasp) -> None:
        mujoco.mj_kinematics(self.model, data)
        top = data.xpos[self.support_id][2]
        self.record["release_height"] = lowest_point(self.model, data, self.prop) - float(top)
        centre = np.asarray(self.scene["place_centre"], dtype=float).reshape(-1, 2)
        centre = self._demo_row(centre)
        point = self.prop_centre(data)[:2].copy()
        # where it is let go (x, y): the derivation's demos' release spread is measured on it
        self.record["release_point"] = point
        self.record["release_offset"] = float(np.linalg.norm(point - centre))

    def released(self) -> tuple[float | None, float | None]:
        """(release height, release offset) as `on_release` measured them (m; None: the
        gripper has not opened)."""
        h, off = self.record["release_height"], self.record["release_offset"]
        return (None if h is None else float(h)), (None if off is None else float(off))

    def _on_support(self, data: mujoco.MjData, point: np.ndarray) -> tuple[bool, float]:
        rot = data.xmat[self.support_id].reshape(3, 3)
        local = rot.T @ (point - data.xpos[self.support_id])
        half = self.scene[self.support_half_key]
        return bool(abs(local[0]) <= half[0] and abs(local[1]) <= half[1]), float(local[2])


class TrayPlaceScene(PlaceScene):
    """A held prop taken out of a free tray or rack (a base and four walls, one body named
    `tray`: its geoms `<tray>_base`, `<tray>_wall_{back,front,right,left}`) and laid on a
    support. The tray's frame: origin on what it stands on (`[scene]
    stand_top`'s height if the scene has a stand, else the table) under the grasp point at the
    start, x along the held prop's axis `tray_axis` (its horizontal part); the walls' inner
    faces at `[scene] tray_walls` (x_lo, x_hi, y_lo, y_hi), their tops `tray_wall_height` above
    the base. Success: the task's predicate `checks` (its `success.checks`) of the release
    (`released`), the tray's record (never knocked) and how the prop rests (`rest`)."""

    tray = "tray"
    #: the prop body's axis (0 x, 1 y, 2 z) the tray's x follows.
    tray_axis = 0
    #: the task's success predicate: (release_reason, held, release_height, release_offset,
    #: tray shift, tray tilt, on the support, tilt, height, cfg) -> checks.
    checks: Callable[..., list[Check]]

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        if "stand_top" in s:
            size_support(spec, "stand", s["stand_top"], s["stand_half_size"],
                         np.radians(s.get("stand_yaw_deg", 0.0)), self.table_z, "stand_top",
                         "stand_support")
        t = float(s.get("tray_base_thickness", 0.005))
        w = float(s.get("tray_wall_thickness", 0.008)) / 2
        height = float(s["tray_wall_height"])
        faces = tuple(float(v) for v in s["tray_walls"])
        cx, cy, hx, hy = box_walls(spec, self.tray, faces, t, height, w)
        base = spec.geom(f"{self.tray}_base")
        base.size = [hx + 2 * w, hy + 2 * w, t / 2]
        base.pos = [cx, cy, t / 2]

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.tray_id = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, self.tray)
        self.tray_watch = KnockWatch(self.tray_id)

    def tray_floor(self) -> float:
        """World z of what the tray stands on."""
        return float(self.scene["stand_top"][2]) if "stand_top" in self.scene else self.table_z

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self.place_held_prop(data, grasp)
        mujoco.mj_kinematics(self.model, data)
        grasp_pt = data.site_xpos[self.grasp_site]
        axis = data.xmat[grasp.body_id].reshape(3, 3)[:, self.tray_axis]
        yaw = float(np.arctan2(axis[1], axis[0]))
        pos = np.array([grasp_pt[0], grasp_pt[1], self.tray_floor()])
        set_free_pose(self.model, data, self.tray_id, pos, yaw_quat(yaw))
        self.tray_watch.place(pos)

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        super().start_record(data, grasp)
        self.record.update({f"max_{self.tray}_shift": 0.0, f"max_{self.tray}_tilt_deg": 0.0})

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.tray_watch.track(data, self.record, self.tray)

    def rest(self, data: mujoco.MjData) -> tuple[bool, float, float, dict[str, Any]]:
        """How the prop rests now: (over the support's top, tilt (deg), height above the
        support's top (m), their info entries)."""
        raise NotImplementedError

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        rec = self.record
        shift, tilt = f"max_{self.tray}_shift", f"max_{self.tray}_tilt_deg"
        h, off = self.released()
        on_top, tilt_now, height, more = self.rest(data)
        checks = self.checks(grasp.release_reason, grasp.held(data), h, off, rec[shift],
                             rec[tilt], on_top, tilt_now, height, self.success_cfg)
        knock = (f"{self.tray}_shift", f"{self.tray}_tilt")
        info = {"release_height": h, "release_offset": off, **more,
                shift: float(rec[shift]), tilt: float(rec[tilt]),
                f"{self.tray}_in_place": all(ch.passed for ch in checks if ch.name in knock),
                "checks": checks_json(checks)}
        return all(ch.passed for ch in checks), info

    def scene_state(self) -> dict[str, Any]:
        state = super().scene_state()
        state["tray_start"] = self.tray_watch.start.copy()
        return state

    def restore_scene_state(self, state: dict[str, Any]) -> None:
        super().restore_scene_state(state)
        self.tray_watch.place(state["tray_start"])
