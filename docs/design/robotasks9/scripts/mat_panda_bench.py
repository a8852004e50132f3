"""Bare-physics cost of the Menagerie Panda scene (robot holding its home pose, 2 ms steps,
8 substeps per 60 Hz control step as the envs) with and without a folding mat added next to it
(same mat models and mocap fold as mat_bench.py). No IK, no env bookkeeping: add the env's
~150 us per control step (bench_env.py: total minus physics) for a whole-env estimate.
Usage (from the repo root):
  nice -n 19 python docs/design/robotasks9/scripts/mat_panda_bench.py VARIANT
  VARIANT: none | chain6 | chain12 | flex7x5_* | flex13x9_*  (run_mat_all.sh runs the memo's)
The Panda scene is the Menagerie Panda's scene.xml (clfd_bench.sim.robot.menagerie_dir)."""
import json
import os
import sys
import time

import mat_bench as mb
import mujoco
import numpy as np

from clfd_bench.sim.robot import menagerie_dir

PANDA = os.path.join(str(menagerie_dir()), "scene.xml")


def main():
    name = sys.argv[1]
    spec = mujoco.MjSpec.from_file(PANDA)
    spec.option.timestep = mb.DT
    attach_body, anchor = None, [0.0, 0.0, 0.0]
    if name != "none":
        kind, o = mb.VARIANTS[name]
        # the mat as a child spec (mat_bench's MJCF), attached in front of the robot at x=0.45
        _, m0, d0, xml = mb.build(name, "edge")
        child = mujoco.MjSpec.from_string(xml)
        frame = spec.worldbody.add_frame()
        frame.pos = [0.45, -0.15, 0.0]
        # drop the child's table plane and light (the Panda scene has a floor)
        for g in list(child.geoms):
            if g.name == "table":
                child.delete(g)
        spec.attach(child, frame=frame, prefix="m_")
        spec.option.integrator = getattr(
            mujoco.mjtIntegrator, "mjINT_" + o.get("integrator", "implicitfast").upper()
        )
        if kind == "flex":
            m = spec.compile()
            d = mujoco.MjData(m)
            mujoco.mj_forward(m, d)
            best, bid = 1e9, -1
            for b in range(m.nbody):
                nm = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or ""
                if nm.startswith("m_mat_"):
                    dd = np.linalg.norm(d.xpos[b][:2] - np.array([0.45, -0.15]))
                    if dd < best:
                        best, bid = dd, b
            attach_body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, bid)
        else:
            attach_body = "m_p0"
            anchor = [0.0, -mb.L / o["n"] / 2, 0.0]
        m = spec.compile()
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, attach_body)
        p = d.xpos[b] + d.xmat[b].reshape(3, 3) @ np.array(anchor)
        spec.body("m_grip").pos = [float(v) for v in p - np.array([0.45, -0.15, 0.0])]
        eq = spec.add_equality()
        eq.type = mujoco.mjtEq.mjEQ_CONNECT
        eq.name1, eq.name2 = attach_body, "m_grip"
        eq.objtype = mujoco.mjtObj.mjOBJ_BODY
        eq.data[0:3] = anchor
    model = spec.compile()
    data = mujoco.MjData(model)
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")
    mujoco.mj_resetDataKeyframe(model, data, key)
    mujoco.mj_forward(model, data)
    start = data.mocap_pos[0].copy() if model.nmocap else None
    n = int(3.8 / mb.DT)
    nfold = int(mb.FOLD_S / mb.DT)
    c0 = time.process_time()
    for i in range(n):
        if start is not None and i < nfold:
            s = (i + 1) / nfold
            s = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5
            data.mocap_pos[0] = [start[0], start[1] + mb.L * (1 - np.cos(np.pi * s)) / 2,
                                 start[2] + 2 * mb.T * s + mb.ARC_H * np.sin(np.pi * s)]
        if start is not None and i == nfold + int(mb.HOLD_S / mb.DT):
            data.eq_active[0] = 0
        mujoco.mj_step(model, data)
    cpu = time.process_time() - c0
    qerr = float(np.abs(data.qpos[:7] - model.key_qpos[key][:7]).max())
    print(json.dumps({"variant": name, "nv": int(model.nv),
                      "integrator": mujoco.mjtIntegrator(model.opt.integrator).name,
                      "physics_us_per_control_step_cpu": round(cpu / n * 8 * 1e6, 1),
                      "x_realtime_physics_only_cpu": round(n * mb.DT / cpu, 1),
                      "arm_home_drift_rad": round(qerr, 5),
                      "finite": bool(np.all(np.isfinite(data.qpos)))}))


if __name__ == "__main__":
    main()
