"""BottleShelving's scene: a bottle laid on a shelf."""

from __future__ import annotations

from typing import Any

import mujoco

from clfd_bench.envs.checks import checks_json
from clfd_bench.envs.robotasks.bottle2shelf import success
from clfd_bench.envs.robotasks.common import tilt_from_vertical
from clfd_bench.envs.robotasks.placing import PlaceScene
from clfd_bench.sim.grasp import Grasp

__all__ = ["SCENE", "BottleScene"]


class BottleScene(PlaceScene):
    """A bottle held upright by its neck; a shelf where the demos end. Success: `success.checks`
    (released by opening, low and where the demos release it; lying on the shelf)."""

    object_bodies = ("bottle",)
    prop, support, support_half_key = "bottle", "shelf", "shelf_half_size"
    support_geoms = ("shelf_board", "shelf_support")

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        h, off = self.released()
        on_top, height = self._on_support(data, data.xipos[self.prop_id])
        axis = data.xmat[self.prop_id].reshape(3, 3)[:, 2]
        tilt = 90.0 - tilt_from_vertical(axis)  # from horizontal
        checks = success.checks(grasp.release_reason, grasp.held(data), h, off, on_top, tilt,
                                height, self.success_cfg)
        info = {"release_height": h, "release_offset": off, "bottle_tilt_deg": tilt,
                "bottle_height": height, "on_shelf": on_top, "checks": checks_json(checks)}
        return all(ch.passed for ch in checks), info


SCENE = BottleScene
