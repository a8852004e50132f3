"""Scoop prototype (2026-12-04): does a single layer of beans on a false floor get scooped by
the demos? A kinematic scoop (mocap body at the demo's grasp poses: a 15 cm handle along hand x,
an open box bowl facing -hand z) passes through NB beans lying on a floor the scoop does not
collide with; prints how many beans are in the bowl 1 s after each demo's end.

    python docs/design/robotasks9/scripts/scoop_bed_proto.py FLOOR_Z NB SPACING BX,BY,BZ

FLOOR_Z: the floor's top (m); NB: beans (a square grid) of radius 9 mm, SPACING apart, centred
at (0.44, -0.32); BX, BY, BZ: the bowl's half sizes (m).
"""

import math
import sys

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from clfd_bench.data import load_dataset
from clfd_bench.sim.scene_fit import grasp_points

FLOOR = float(sys.argv[1]) if len(sys.argv) > 1 else 0.30
NB = int(sys.argv[2]) if len(sys.argv) > 2 else 16
SP = float(sys.argv[3]) if len(sys.argv) > 3 else 0.022
BX, BY, BZ = (float(v) for v in (sys.argv[4] if len(sys.argv) > 4 else "0.035,0.03,0.015")
              .split(","))
BEAN_R, L = 0.009, 0.15
G = int(round(math.sqrt(NB)))


def scene_xml() -> str:
    beans = []
    for i in range(NB):
        x = 0.44 + (i % G - (G - 1) / 2) * SP
        y = -0.32 + (i // G - (G - 1) / 2) * SP
        beans.append(f'<body name="b{i}" pos="{x} {y} {FLOOR + BEAN_R + 0.001}"><freejoint/>'
                     f'<geom type="sphere" size="{BEAN_R}" mass="0.002" contype="3" '
                     f'conaffinity="3" friction="0.6 0.005 0.0001"/></body>')
    wall = 'contype="1" conaffinity="1"'
    return f"""<mujoco><option timestep="0.002" integrator="implicitfast"/><worldbody>
  <body name="scoop" mocap="true">
    <geom type="cylinder" fromto="-0.04 0 0 0.11 0 0" size="0.006" {wall}/>
    <geom type="box" size="{BX} {BY} 0.0015" pos="{L} 0 {BZ}" {wall}/>
    <geom type="box" size="0.0015 {BY} {BZ}" pos="{L + BX} 0 0" {wall}/>
    <geom type="box" size="0.0015 {BY} {BZ}" pos="{L - BX} 0 0" {wall}/>
    <geom type="box" size="{BX} 0.0015 {BZ}" pos="{L} {BY} 0" {wall}/>
    <geom type="box" size="{BX} 0.0015 {BZ}" pos="{L} -{BY} 0" {wall}/>
  </body>
  <geom type="box" size="0.12 0.12 0.005" pos="0.44 -0.32 {FLOOR - 0.005}" contype="2"
    conaffinity="2"/>
  {''.join(beans)}
</worldbody></mujoco>"""


def main() -> None:
    ds = load_dataset("robotasks9")
    task = ds.tasks[ds.task_names.index("scoop")]
    grasp = grasp_points(task.positions, task.quaternions)
    model = mujoco.MjModel.from_xml_string(scene_xml())
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"b{i}") for i in range(NB)]
    counts = []
    for n in range(len(grasp)):
        mujoco.mj_resetData(model, data)
        quat = task.quaternions[n]
        for k in range(quat.shape[0]):
            data.mocap_pos[0], data.mocap_quat[0] = grasp[n, k], quat[k]
            mujoco.mj_step(model, data, nstep=8)
        mujoco.mj_step(model, data, nstep=8 * 60)
        end = Rotation.from_quat(np.r_[quat[-1, 1:], quat[-1, :1]])
        local = end.inv().apply(data.xpos[ids] - grasp[n, -1])
        inside = ((np.abs(local[:, 0] - L) < BX) & (np.abs(local[:, 1]) < BY)
                  & (local[:, 2] < BZ) & (local[:, 2] > -0.03))
        counts.append(int(inside.sum()))
    print("floor", FLOOR, "beans in the scoop at the end per demo", counts)


if __name__ == "__main__":
    main()
