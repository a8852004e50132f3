"""Standalone MJCF test of a flexible mat on a table (not the repo's scenes): MuJoCo flex cloth
(<flexcomp dim=2>) vs a hinged plate chain. A point of the mat (a corner, or the near edge's
middle) is attached by a connect constraint to a mocap body moved along a lift-and-fold arc
(3 s, min-jerk), held 0.3 s, let go, and the mat settles 0.5 s. Physics dt 2 ms as the envs.

Usage (from the repo root):
  nice -n 19 python docs/design/robotasks9/scripts/mat_bench.py VARIANT [--attach=corner|edge]
      [--weld=DEG] [--L=M --W=M --mass=KG] [--render]
Prints one JSON line: speed (sim s per wall s and per CPU s), model size, fold quality.
--render writes $RT9_OUT/plots/mat_*.png (default results/robotasks9/plots in the repo).
run_mat_all.sh runs every variant the memo quotes.
"""
import json
import os
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

L, W, T = 0.30, 0.20, 0.003          # mat length (fold direction, y), width (x), thickness
MASS = 0.10                          # kg (30 x 20 cm rubber-ish mat)
DT = 0.002
FOLD_S, HOLD_S, SETTLE_S = 3.0, 0.3, 0.5
ARC_H = 0.35 * L                     # apex height / travel, as the demos (0.2 m / 0.6 m)

VARIANTS = {
    # name: (kind, options)
    # MuJoCo 4.0.1 refuses flex elasticity under implicit/implicitfast ("set integrator='discrete',
    # or 'Euler' with a small timestep"): elastic variants use 'discrete'
    "flex13x9_noself_discrete": ("flex", dict(nx=9, ny=13, selfcollide="none", young=2e5,
                                              integrator="discrete")),
    "flex13x9_self_discrete": ("flex", dict(nx=9, ny=13, selfcollide="auto", young=2e5,
                                            integrator="discrete")),
    "flex13x9_self_E2e6_discrete": ("flex", dict(nx=9, ny=13, selfcollide="auto", young=2e6,
                                                 integrator="discrete")),
    "flex7x5_self_discrete": ("flex", dict(nx=5, ny=7, selfcollide="auto", young=2e5,
                                           integrator="discrete")),
    "flex13x9_self_edgeeq": ("flex", dict(nx=9, ny=13, selfcollide="auto", young=0,
                                          integrator="implicitfast", edge_eq=True)),
    "flex7x5_self_edgeeq": ("flex", dict(nx=5, ny=7, selfcollide="auto", young=0,
                                         integrator="implicitfast", edge_eq=True)),
    "flex13x9_noself_edgeeq": ("flex", dict(nx=9, ny=13, selfcollide="none", young=0,
                                            integrator="implicitfast", edge_eq=True)),
    "chain6": ("chain", dict(n=6)),
    "chain12": ("chain", dict(n=12)),
}


def flex_xml(o):
    sx = W / (o["nx"] - 1)
    sy = L / (o["ny"] - 1)
    r = T / 2
    elast = ""
    if o["young"] > 0:
        elast = (f'<elasticity young="{o["young"]}" poisson="0.3" thickness="{T}" '
                 f'damping="0.002" elastic2d="both"/>')
    edge = '<edge equality="true" damping="0.01"/>' if o.get("edge_eq") else ""
    return f"""
      <flexcomp name="mat" type="grid" dim="2" count="{o['nx']} {o['ny']} 1"
                spacing="{sx} {sy} 0.01" pos="0 {L/2} {r + 0.0005}" radius="{r}" mass="{MASS}"
                rgba="0.2 0.5 0.8 1">
        <contact condim="3" friction="0.9" selfcollide="{o["selfcollide"]}"
                 solref="0.004 1"/>
        {elast}{edge}
      </flexcomp>"""


def chain_xml(o):
    n = o["n"]
    seg = L / n
    m = MASS / n
    hy = seg / 2 - 0.0005
    # plate 0 at the near edge (y in [0, seg]), the next plates hinged along x at their edges
    body = (f'<body name="p0" pos="0 {seg/2} {T/2 + 0.0005}"><freejoint/>'
            f'<geom type="box" size="{W/2} {hy} {T/2}" mass="{m}" friction="0.9" '
            f'rgba="0.2 0.5 0.8 1"/>')
    close = "</body>"
    for i in range(1, n):
        body += (f'<body name="p{i}" pos="0 {seg} 0"><joint type="hinge" axis="1 0 0" '
                 f'pos="0 {-seg/2} 0" damping="0.002" stiffness="0.0" armature="0.0001"/>'
                 f'<geom type="box" size="{W/2} {hy} {T/2}" mass="{m}" friction="0.9" '
                 f'rgba="0.2 0.5 0.8 1"/>')
        close += "</body>"
    return body + close


def build(name, attach):
    kind, o = VARIANTS[name]
    integ = o.get("integrator", "implicitfast")
    mat = flex_xml(o) if kind == "flex" else chain_xml(o)
    xml = f"""
<mujoco model="mat test {name}">
  <option timestep="{DT}" integrator="{integ}"/>
  <visual><global offwidth="640" offheight="480"/></visual>
  <worldbody>
    <light pos="0 0 1.5" dir="0 0 -1"/>
    <geom name="table" type="plane" size="1 1 0.01" rgba="0.7 0.6 0.5 1" friction="0.9"/>
    <body name="grip" mocap="true" pos="0 0 0.05">
      <geom type="sphere" size="0.008" contype="0" conaffinity="0" rgba="1 0 0 1"/>
    </body>
    {mat}
  </worldbody>
</mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return kind, model, data, xml


def mat_points(kind, model, data):
    """[K, 3] world points of the mat: flex vertices, or plate corners (4 per plate top)."""
    if kind == "flex":
        return data.flexvert_xpos.copy()
    pts = []
    for b in range(model.nbody):
        nm = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or ""
        if nm.startswith("p"):
            R = data.xmat[b].reshape(3, 3)
            g = model.body_geomadr[b]
            hx, hy, _ = model.geom_size[g]
            for sx in (-1, 1):
                for sy in (-1, 1):
                    pts.append(data.xpos[b] + R @ np.array([sx * hx, sy * hy, 0.0]))
    return np.array(pts)


def main():
    global L, W, MASS, ARC_H
    name = sys.argv[1]
    weld_deg = None
    for a in sys.argv[2:]:
        if a.startswith("--L="):
            L = float(a[4:])
            ARC_H = 0.35 * L
        elif a.startswith("--W="):
            W = float(a[4:])
        elif a.startswith("--mass="):
            MASS = float(a[7:])
        elif a.startswith("--weld="):
            weld_deg = float(a[7:])  # weld instead of connect; mocap turns this much about -x
    attach = "corner"
    for a in sys.argv[2:]:
        if a.startswith("--attach="):
            attach = a.split("=", 1)[1]
    render = "--render" in sys.argv
    kind, model, data, xml = build(name, attach)
    # the attached point: a corner (x=-W/2, y=0) or the near edge's middle (x=0, y=0)
    target_xy = np.array([-W / 2 if attach == "corner" else 0.0, 0.0])
    spec = mujoco.MjSpec.from_string(xml)
    if kind == "flex":
        # the flex vertex body nearest the attach point
        best, bid = 1e9, -1
        for b in range(model.nbody):
            nm = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or ""
            if nm.startswith("mat_"):
                d = np.linalg.norm(data.xpos[b][:2] - target_xy)
                if d < best:
                    best, bid = d, b
        b1 = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, bid)
        anchor = [0, 0, 0]
    else:
        b1 = "p0"
        seg = L / VARIANTS[name][1]["n"]
        anchor = [float(target_xy[0]), -seg / 2, 0.0]
    # the mocap starts at the attached point (a connect keeps the bodies' offset in qpos0)
    bid0 = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b1)
    p_att_ref = data.xpos[bid0] + data.xmat[bid0].reshape(3, 3) @ np.array(anchor)
    spec.body("grip").pos = [float(v) for v in p_att_ref]
    eq = spec.add_equality()
    eq.type = mujoco.mjtEq.mjEQ_CONNECT if weld_deg is None else mujoco.mjtEq.mjEQ_WELD
    eq.name1, eq.name2 = b1, "grip"
    eq.objtype = mujoco.mjtObj.mjOBJ_BODY
    if weld_deg is None:
        eq.data[0:3] = anchor
    else:
        # (all zero relpose = the bodies' relative pose in qpos0, as an MJCF weld without relpose;
        # the mocap starts at the attached point)
        eq.data[0:10] = [0.0] * 10
        eq.data[10] = 1.0
    eq.solref = [0.01, 1.0]
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    b1id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b1)
    R = data.xmat[b1id].reshape(3, 3)
    p_att0 = data.xpos[b1id] + R @ np.array(anchor)
    start = p_att0.copy()
    data.mocap_pos[0] = start
    end = start + np.array([0.0, L, 2 * T])   # on top of the bottom layer
    nfold = int(FOLD_S / DT)
    nhold = int(HOLD_S / DT)
    nsettle = int(SETTLE_S / DT)
    nefc, ncon = [], []
    warn0 = data.warning.number.copy()
    w0, c0 = time.perf_counter(), time.process_time()
    for i in range(nfold + nhold + nsettle):
        if i < nfold:
            s = (i + 1) / nfold
            s = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5
            p = start + (end - start) * (1 - np.cos(np.pi * s)) / 2 * np.array([1, 1, 1])
            p = np.array([start[0], start[1] + L * (1 - np.cos(np.pi * s)) / 2,
                          start[2] + (end[2] - start[2]) * s + ARC_H * np.sin(np.pi * s)])
            data.mocap_pos[0] = p
            if weld_deg is not None:
                a = -np.radians(weld_deg) * s
                data.mocap_quat[0] = [np.cos(a / 2), np.sin(a / 2), 0.0, 0.0]
        if i == nfold + nhold:
            corner_before_release = (
                data.xpos[b1id] + data.xmat[b1id].reshape(3, 3) @ np.array(anchor)
            ).copy()
            data.eq_active[0] = 0
        mujoco.mj_step(model, data)
        if i % 10 == 0:
            nefc.append(data.nefc)
            ncon.append(data.ncon)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    sim = (nfold + nhold + nsettle) * DT
    p_att = data.xpos[b1id] + data.xmat[b1id].reshape(3, 3) @ np.array(anchor)
    pts = mat_points(kind, model, data)
    goal = np.array([target_xy[0], L])
    warn = (data.warning.number - warn0)
    res = {
        "variant": name, "attach": attach, "L": L, "W": W, "mass": MASS,
        "grasp": ("connect" if weld_deg is None
                  else f"weld, hand turns {weld_deg} deg about -x"),
        "kind": kind, "nv": int(model.nv), "nbody": int(model.nbody),
        "sim_s": sim, "wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
        "x_realtime_wall": round(sim / wall, 2), "x_realtime_cpu": round(sim / cpu, 2),
        "us_per_physics_step_cpu": round(cpu / (nfold + nhold + nsettle) * 1e6, 1),
        "nefc_mean": float(np.mean(nefc)), "nefc_max": int(np.max(nefc)),
        "ncon_mean": float(np.mean(ncon)),
        "warnings": {mujoco.mjtWarning(i).name: int(w) for i, w in enumerate(warn) if w},
        "finite": bool(np.all(np.isfinite(data.qpos))),
        "attached_point_end_xy_err_m": round(float(np.linalg.norm(p_att[:2] - goal)), 4),
        "attached_point_before_release_xy_err_m": round(
            float(np.linalg.norm(corner_before_release[:2] - goal)), 4),
        "attached_point_end_z": round(float(p_att[2]), 4),
        "mat_y_extent_end": [round(float(pts[:, 1].min()), 3), round(float(pts[:, 1].max()), 3)],
        "mat_x_extent_end": [round(float(pts[:, 0].min()), 3), round(float(pts[:, 0].max()), 3)],
        "mat_z_range_end": [round(float(pts[:, 2].min()), 4), round(float(pts[:, 2].max()), 4)],
        "frac_points_upper_layer(z>T)": round(float((pts[:, 2] > T).mean()), 3),
    }
    print(json.dumps(res))
    if render:
        os.environ.setdefault("MUJOCO_GL", "egl")
        r = mujoco.Renderer(model, 480, 640)
        cam = mujoco.MjvCamera()
        cam.lookat[:] = [0, L / 2, 0.02]
        cam.distance, cam.azimuth, cam.elevation = 0.75, 135, -35
        r.update_scene(data, cam)
        import imageio
        tag = ("" if (L == 0.30 and weld_deg is None)
               else f"_L{L}" + ("" if weld_deg is None else f"_weld{int(weld_deg)}"))
        cam.lookat[:] = [0, L / 2, 0.02]
        cam.distance = 2.5 * L
        r.update_scene(data, cam)
        default = Path(__file__).resolve().parents[4] / "results" / "robotasks9"
        plots = Path(os.environ.get("RT9_OUT") or default) / "plots"
        plots.mkdir(parents=True, exist_ok=True)
        imageio.imwrite(plots / f"mat_{name}_{attach}{tag}.png", r.render())


if __name__ == "__main__":
    main()
