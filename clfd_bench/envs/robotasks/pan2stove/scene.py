"""PanToStove's scene: a pan taken out of a pan rack and laid on a stove."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.robotasks.common import obj_id
from clfd_bench.envs.robotasks.pan2stove import success
from clfd_bench.envs.robotasks.placing import TrayPlaceScene

__all__ = ["SCENE", "PanScene"]


class PanScene(TrayPlaceScene):
    """A pan standing on its rim in a pan rack (a base and four walls, one free body); a stove
    where the demos set it down. Success: `success.checks` (the rack never knocked; released
    by opening, low and where the demos release it; lying flat on the stove, its bottom
    down)."""

    object_bodies = ("pan", "rack")
    prop, support, support_half_key = "pan", "stove", "stove_half_size"
    support_geoms = ("stove_top", "stove_support")
    tray, tray_axis = "rack", 1
    checks = staticmethod(success.checks)

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.bottom = obj_id(model, mujoco.mjtObj.mjOBJ_GEOM, "pan_bottom")
        self._bottom_half = float(model.geom_size[self.bottom][1])

    def prop_centre(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the centre of the pan's bottom."""
        return data.geom_xpos[self.bottom]

    def rest(self, data: mujoco.MjData) -> tuple[bool, float, float, dict[str, Any]]:
        z = data.xmat[self.prop_id].reshape(3, 3)[:, 2]  # from the rim to the bottom
        outer = data.geom_xpos[self.bottom] + self._bottom_half * z
        on_top, height = self._on_support(data, outer)
        tilt = float(np.degrees(np.arccos(np.clip(-z[2], -1.0, 1.0))))  # 180: upside down
        return on_top, tilt, height, {"pan_tilt_deg": tilt, "pan_bottom_height": height,
                                      "on_stove": on_top}


SCENE = PanScene
