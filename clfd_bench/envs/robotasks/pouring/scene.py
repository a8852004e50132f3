"""Pouring's scene: a cup of beans emptied into a container."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from clfd_bench.envs.checks import checks_json
from clfd_bench.envs.robotasks.common import Scene, bean_pool, obj_id, set_free_pose, yaw_quat
from clfd_bench.envs.robotasks.pouring import success
from clfd_bench.sim.grasp import Grasp

__all__ = ["SCENE", "PouringScene"]


class PouringScene(Scene):
    """A cup holding `n_beans` beans (free spheres); a square container where the demos pour.
    Success: `success.checks` (the cup never slips; emptied where demo j empties it; enough
    beans in the container, few ever landed outside it)."""

    object_bodies = ("cup",)
    needs_release = False

    def __init__(self, doc: dict[str, Any]):
        super().__init__(doc)
        self.n_beans, self.bean_radius, self.bean_names = bean_pool(self.scene, "pouring")
        self.object_bodies = ("cup",) + self.bean_names

    def edit_spec(self, spec: mujoco.MjSpec) -> None:
        super().edit_spec(spec)
        s = self.scene
        cont = spec.body("container")
        cont.pos = [s["container_floor"][0], s["container_floor"][1], self.table_z]
        cont.quat = list(yaw_quat(np.radians(s.get("container_yaw_deg", 0.0))))
        a, h, t = float(s["container_half_size"]), float(s["container_height"]), 0.005
        floor = spec.geom("container_floor")
        floor.size = [a + 2 * t, a + 2 * t, 0.004]
        for i, (px, py, sx, sy) in enumerate([(a + t, 0, t, a + 2 * t), (-a - t, 0, t, a + 2 * t),
                                               (0, a + t, a, t), (0, -a - t, a, t)]):
            g = cont.add_geom()
            g.name = f"container_wall{i}"
            g.type = mujoco.mjtGeom.mjGEOM_BOX
            g.size = [sx, sy, h / 2]
            g.pos = [px, py, h / 2]
            g.rgba = [0.45, 0.45, 0.5, 1.0]
        for name in self.bean_names:
            b = spec.worldbody.add_body()
            b.name = name
            b.add_freejoint()
            g = b.add_geom()
            g.name = f"{name}_geom"
            g.type = mujoco.mjtGeom.mjGEOM_SPHERE
            g.size = [self.bean_radius, 0.0, 0.0]
            g.mass = float(s.get("bean_mass", 0.002))
            g.rgba = [0.35, 0.2, 0.1, 1.0]
            g.friction = [0.6, 0.005, 0.0001]
            g.condim = int(s.get("bean_condim", 3))
            g.priority = 1  # a bean's contact takes the bean's condim and friction

    def bind(self, model: mujoco.MjModel) -> None:
        super().bind(model)
        self.cup = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, "cup")
        self.container = obj_id(model, mujoco.mjtObj.mjOBJ_BODY, "container")
        self.bean_ids = np.array([obj_id(model, mujoco.mjtObj.mjOBJ_BODY, n)
                                  for n in self.bean_names])
        self.bean_local = self._bean_layout()
        # The container is static: its pose in the compiled model.
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        self._cont_pos = data.xpos[self.container].copy()
        self._cont_rot = data.xmat[self.container].reshape(3, 3).copy()
        self._half = float(self.scene["container_half_size"])
        self._height = float(self.scene["container_height"])
        self._outer = self._half + 0.01  # + the walls' thickness
        self._level = self._height + self.bean_radius
        self._pour_centres = np.asarray(self.scene.get("pour_centre", [[0.0, 0.0, 0.0]]),
                                        dtype=float).reshape(-1, 3)
        #: the cup's mouth along its axis, and how far out of its axis a bean is out of it.
        self._mouth = float(self.scene.get("cup_mouth", 0.05))
        self._cup_outer = float(self.scene.get("cup_inner_radius", 0.036)) + 0.01

    def _bean_layout(self) -> np.ndarray:
        """[n_beans, 3] bean centres in the cup frame: close-packed hexagonal layers from the
        cup's floor up, 1 mm apart (no two beans touch at reset)."""
        r = self.bean_radius
        inner = float(self.scene.get("cup_inner_radius", 0.036)) - r - 0.001
        floor = float(self.scene.get("cup_floor", -0.042)) + r + 0.001
        s = 2 * r + 0.001
        n = int(inner // s) + 2
        i, j = np.meshgrid(np.arange(-n, n + 1), np.arange(-n, n + 1))
        grid = np.stack([(i + 0.5 * (j % 2)) * s, j * s * np.sqrt(3) / 2], -1).reshape(-1, 2)
        pts: list[np.ndarray] = []
        layer = 0
        while len(pts) < self.n_beans:
            shift = np.array([s / 2, s / (2 * np.sqrt(3))]) if layer % 2 else np.zeros(2)
            xy = grid + shift
            xy = xy[np.linalg.norm(xy, axis=1) <= inner]
            if len(xy) == 0:
                raise ValueError(f"beans of radius {r} m do not fit in the cup")
            z = floor + layer * s * np.sqrt(2.0 / 3.0)
            pts.extend(np.column_stack([xy, np.full(len(xy), z)]))
            layer += 1
        return np.array(pts[: self.n_beans])

    def _place_beans(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.place_held_prop(data, grasp)
        mujoco.mj_kinematics(self.model, data)
        cup_pos = data.xpos[self.cup]
        cup_rot = data.xmat[self.cup].reshape(3, 3)
        for b, local in zip(self.bean_ids, self.bean_local, strict=True):
            set_free_pose(self.model, data, int(b), cup_pos + cup_rot @ local,
                          np.array([1.0, 0, 0, 0]))

    def _bean_local(self, data: mujoco.MjData) -> np.ndarray:
        """[n_beans, 3] bean centres in the container frame (static: its pose is the model's)."""
        return (data.xpos[self.bean_ids] - self._cont_pos) @ self._cont_rot

    def bean_fraction(self, data: mujoco.MjData) -> float:
        """Fraction of beans inside the container (below its rim, within its walls)."""
        local = self._bean_local(data)
        a, h = self._half, self._height
        inside = ((np.abs(local[:, 0]) <= a) & (np.abs(local[:, 1]) <= a)
                  & (local[:, 2] >= -0.01) & (local[:, 2] <= h))
        return float(np.count_nonzero(inside)) / self.n_beans

    def reset(self, data: mujoco.MjData, demo: int, grasp: Grasp) -> None:
        self.demo = demo
        self._place_beans(data, grasp)

    def start_record(self, data: mujoco.MjData, grasp: Grasp) -> None:
        self.record = {"spilled": np.zeros(self.n_beans, dtype=bool),
                       "left": np.zeros(self.n_beans, dtype=bool),
                       "pour_sum": np.zeros(3), "pour_count": 0}

    def track(self, data: mujoco.MjData, grasp: Grasp) -> None:
        """A bean has landed outside once it is below the container's rim outside its walls'
        outer faces (on the table, on the rim, on the floor...). When a bean leaves the cup
        (past its mouth or its wall), where the cup's mouth is then is where it was poured.
        (Runs every control step: the beans' positions [n_beans, 3] are read once; the cup
        test stops once every bean has left it.)"""
        p = data.xpos[self.bean_ids]
        local = (p - self._cont_pos) @ self._cont_rot  # `_bean_local`
        rec = self.record
        below = local[:, 2] < self._level
        if below.any():
            rec["spilled"] |= below & ((np.abs(local[:, 0]) > self._outer)
                                       | (np.abs(local[:, 1]) > self._outer))
        left = rec["left"]
        if not left.all():
            cup_pos = data.xpos[self.cup]
            rot = data.xmat[self.cup].reshape(3, 3)
            in_cup = (p - cup_pos) @ rot
            out = ((in_cup[:, 2] > self._mouth)
                   | (np.hypot(in_cup[:, 0], in_cup[:, 1]) > self._cup_outer)) & ~left
            if out.any():
                mouth = cup_pos + self._mouth * rot[:, 2]
                k = int(np.count_nonzero(out))
                rec["pour_sum"] = rec["pour_sum"] + k * mouth
                rec["pour_count"] += k
                left |= out

    def pour_offset(self) -> float | None:
        """Distance (m) between where the cup's mouth was, on average, when its beans left it and
        where it was when demo j's did (None: no bean has left the cup)."""
        count = self.record["pour_count"]
        if count == 0:
            return None
        ref = self._demo_row(self._pour_centres)
        return float(np.linalg.norm(self.record["pour_sum"] / count - ref))

    def success(self, data: mujoco.MjData, grasp: Grasp) -> tuple[bool, dict[str, Any]]:
        frac = self.bean_fraction(data)
        spilled = float(self.record["spilled"].mean())
        has_centre = "pour_centre" in self.scene
        offset = self.pour_offset() if has_centre else 0.0
        checks = success.checks(grasp.release_reason, offset, has_centre, self.n_beans, frac,
                                spilled, self.success_cfg)
        return all(ch.passed for ch in checks), {
            "bean_fraction": frac, "spilled_fraction": spilled, "pour_offset": offset,
            "checks": checks_json(checks)}


SCENE = PouringScene
