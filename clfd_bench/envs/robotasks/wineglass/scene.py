"""WineGlass's scene: a wine glass taken out of a drying tray and stood on a shelf."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.robotasks.common import obj_id
from clfd_bench.envs.robotasks.placing import TrayPlaceScene
from clfd_bench.envs.robotasks.wineglass import success

__all__ = ["SCENE", "GlassScene"]


class GlassScene(TrayPlaceScene):
    """A wine glass lying in a drying tray on a stand; a shelf where the demos stand it.
    Success: `success.checks` (the tray never knocked; released by opening, low and where the
    demos release it; standing upright on the shelf)."""

    object_bodies = ("glass", "tray")
    prop, support, support_half_key = "glass", "shelf", "shelf_half_size"
    support_geoms = ("shelf_board", "shelf_support")
    checks = staticmethod(success.checks)

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.foot = obj_id(model, mujoco.mjtObj.mjOBJ_GEOM, "glass_foot")
        self._foot_half = float(model.geom_size[self.foot][1])

    def prop_centre(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the centre of the glass's foot disc."""
        return data.geom_xpos[self.foot]

    def foot_bottom(self, data: mujoco.MjData) -> np.ndarray:
        """[3] the centre of the foot's bottom face (the glass's axis points from it to the
        bowl, the glass body's x)."""
        axis = data.xmat[self.prop_id].reshape(3, 3)[:, 0]
        return data.geom_xpos[self.foot] - self._foot_half * axis

    def rest(self, data: mujoco.MjData) -> tuple[bool, float, float, dict[str, Any]]:
        on_top, height = self._on_support(data, self.foot_bottom(data))
        axis = data.xmat[self.prop_id].reshape(3, 3)[:, 0]
        tilt = float(np.degrees(np.arccos(np.clip(axis[2], -1.0, 1.0))))  # 180: upside down
        return on_top, tilt, height, {"glass_tilt_deg": tilt, "glass_foot_height": height,
                                      "on_shelf": on_top}


SCENE = GlassScene
