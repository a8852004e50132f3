"""Task-specific measurements of the 5 new RoboTasks9 tasks (see memo.md).
Run from the repo root:
  nice -n 19 python docs/design/robotasks9/scripts/analyze_details.py \
      > results/robotasks9/analyze_details.txt"""
import numpy as np
from common import HZ, grasp, mats, rot, tasks

from clfd_bench.sim.grasp import grip_capacity

np.set_printoptions(precision=3, suppress=True)
T = tasks()


def deg(x):
    return np.degrees(x)


def tilt_from_vertical(v):
    return deg(np.arccos(np.clip(np.abs(v[..., 2]), 0, 1)))


def hdr(s):
    print("\n" + "=" * 8, s)


# ---------------------------------------------------------------- gravity in the hand frame
hdr("angle between the world vertical expressed in the hand frame at start and at end (deg):"
    " how much any held object turns relative to gravity")
for name in ["matfolding", "obstaclerotate", "pan2stove", "scoop", "wineglass"]:
    M = mats(T[name].quaternions)
    g0 = M[:, 0, 2, :]   # world z in hand coords = 3rd row
    g1 = M[:, -1, 2, :]
    a = deg(np.arccos(np.clip((g0 * g1).sum(1), -1, 1)))
    print(f"{name:15s} per demo {a.round(1)}  mean {a.mean():.1f}")
    for lab, k in (("start", 0), ("end", -1)):
        tl = {ax: tilt_from_vertical(M[:, k, :, i]) for i, ax in enumerate("xyz")}
        print(f"   {lab}: tilt from vertical of hand x {tl['x'].round(1)}\n"
              f"          hand y {tl['y'].round(1)}\n          hand z {tl['z'].round(1)}")

# ---------------------------------------------------------------- obstaclerotate
hdr("obstaclerotate")
t = T["obstaclerotate"]
P, Q = t.positions, t.quaternions
G = grasp(P, Q)
M = mats(Q)
for n in range(9):
    rr = rot(Q[n])
    rel = rr * rr[0].inv()
    ang = deg(rel.magnitude())
    k = int(ang.argmax())
    rv = rel[k].as_rotvec()
    yaw = deg(np.unwrap(np.arctan2(M[n, :, 1, 0], M[n, :, 0, 0])))
    yaw -= yaw[0]
    print(f"demo {n}: peak rotation {ang[k]:.1f} deg at t={k/HZ:.2f} s, world axis "
          f"{(rv/np.linalg.norm(rv)).round(3)}, grasp pt {G[n,k].round(3)}; yaw of hand x: "
          f"min {yaw.min():.1f} max {yaw.max():.1f} end {yaw[-1]:.1f}; hand-z tilt max "
          f"{tilt_from_vertical(M[n,:,:,2]).max():.1f}")
# the path's bend in the top view: in y slices, min/max x over demos and z there
print("y-slice: x range over demos (min, max), z range of the points in the slice")
for y0 in np.arange(-0.65, 0.2, 0.05):
    sel = np.abs(G[..., 1] - y0) < 0.01
    if sel.any():
        xs, zs = G[..., 0][sel], G[..., 2][sel]
        # per demo: x and z when crossing the slice
        per = []
        for n in range(9):
            s = np.abs(G[n, :, 1] - y0) < 0.01
            if s.any():
                per.append((G[n, s, 0].min(), G[n, s, 0].max(), G[n, s, 2].min()))
        per = np.array(per)
        print(f" y={y0:+.2f}: x in [{xs.min():.3f}, {xs.max():.3f}] (innermost demo max-x "
              f"{per[:,1].min():.3f}); z in [{zs.min():.3f}, {zs.max():.3f}]")
# chord from the corner (where y crosses -0.35) to the end; bulge of each demo from it
bul = []
for n in range(9):
    i0 = int(np.argmax(G[n, :, 1] > -0.35))
    a, b = G[n, i0, :2], G[n, -1, :2]
    d = (b - a) / np.linalg.norm(b - a)
    nrm = np.array([d[1], -d[0]])  # right-hand normal (towards +x for a +y chord)
    off = (G[n, i0:, :2] - a) @ nrm
    k = int(off.argmax())
    bul.append((off.max(), *G[n, i0 + k]))
bul = np.array(bul)
print("bulge from the corner->end chord (top view): max offset per demo (m)", bul[:, 0].round(3),
      "\n at grasp points x,y,z:\n", bul[:, 1:].round(3))
# free region on the concave side of the bend: grid points (x, y) that no path comes within
# 5 cm of (top view), between y=-0.35 and y=0.1 and x in [0.2, 0.6]
xs = np.arange(0.20, 0.61, 0.01)
ys = np.arange(-0.35, 0.11, 0.01)
pts = G.reshape(-1, 3)
free = np.zeros((len(ys), len(xs)), bool)
for i, y in enumerate(ys):
    for j, x in enumerate(xs):
        dmin = np.min(np.hypot(pts[:, 0] - x, pts[:, 1] - y))
        free[i, j] = dmin > 0.05
print("top-view cells no path comes within 5 cm of (rows y from -0.35 to 0.10 step 0.05, "
      "cols x 0.20..0.60 step 0.01; '#' free):")
for i in range(0, len(ys), 5):
    print(f" y={ys[i]:+.2f} " + "".join("#" if f else "." for f in free[i]))
# height of the paths over the region just inside the bend
for (x, y) in [(0.45, -0.2), (0.40, -0.15), (0.45, -0.1), (0.35, -0.25), (0.50, -0.25)]:
    d = np.hypot(pts[:, 0] - x, pts[:, 1] - y)
    near = d < 0.08
    print(f" around ({x},{y}) r 8 cm: {near.sum()} path samples, z min "
          f"{pts[near,2].min() if near.any() else float('nan'):.3f}")

# ---------------------------------------------------------------- pan2stove
hdr("pan2stove")
t = T["pan2stove"]
P, Q = t.positions, t.quaternions
G = grasp(P, Q)
M = mats(Q)
print("hand x (candidate handle axis) at start, per demo:\n", M[:, 0, :, 0].round(3))
print("hand x at end:\n", M[:, -1, :, 0].round(3))
print("hand z (candidate pan normal) at end:\n", M[:, -1, :, 2].round(3))
print("tilt of hand z from vertical at end", tilt_from_vertical(M[:, -1, :, 2]).round(1))
print("tilt of hand x from horizontal at end", (90 - tilt_from_vertical(M[:, -1, :, 0])).round(1))
print("tilt of hand z from vertical at start", tilt_from_vertical(M[:, 0, :, 2]).round(1))
# last 1.5 s: displacement of the grasp point (approach direction onto the stove)
k = int(1.5 * HZ)
print("grasp displacement over the last 1.5 s (m):\n", (G[:, -1] - G[:, -k]).round(3))
k = int(4 * HZ)
print("grasp displacement over the last 4 s (m):\n", (G[:, -1] - G[:, -k]).round(3))
# static gravity torque on a pan held at the handle, in the grasp frame, for candidates
cap = grip_capacity("patch", mu=0.5, grip_force=70.0)
print("patch capacity:", cap.as_dict())
for mass, lever, sign in [(0.5, 0.15, +1), (0.5, 0.15, -1), (0.8, 0.2, +1), (0.3, 0.12, +1)]:
    worst = []
    for n in range(9):
        r = []
        for s in range(0, 1000, 10):
            Rm = M[n, s]
            com = sign * lever * Rm[:, 0]          # pan COM along +-hand x from the grasp
            f = np.array([0, 0, -9.81 * mass])    # weight, world
            tau = np.cross(com, f)
            r.append(cap.ratio(Rm.T @ f, Rm.T @ tau)[0])
        worst.append(max(r))
    print(f" pan {mass} kg, COM {lever} m along {'+' if sign>0 else '-'}hand x: static load "
          f"ratio max per demo {np.round(worst,2)}")

# ---------------------------------------------------------------- wineglass
hdr("wineglass")
t = T["wineglass"]
P, Q = t.positions, t.quaternions
G = grasp(P, Q)
M = mats(Q)
print("hand x tilt from vertical at end", tilt_from_vertical(M[:, -1, :, 0]).round(1))
print("hand x tilt from horizontal at start", (90 - tilt_from_vertical(M[:, 0, :, 0])).round(1))
print("hand x z-component at end (+1 = pointing up)", M[:, -1, 2, 0].round(3))
print("hand z at end", M[:, -1, :, 2].mean(0).round(3),
      "hand z at start", M[:, 0, :, 2].mean(0).round(3))
for sec in (1.0, 2.0, 3.0):
    k = int(sec * HZ)
    print(f"grasp displacement over the last {sec} s (m), mean",
          (G[:, -1] - G[:, -k]).mean(0).round(3),
          "per-demo dz", (G[:, -1, 2] - G[:, -k, 2]).round(3))
# time at which hand x passes 45 deg and 80 deg from horizontal (upright-ness)
for n in range(9):
    el = 90 - tilt_from_vertical(M[n, :, :, 0])
    t45 = np.argmax(el > 45) / HZ
    t80 = np.argmax(el > 80) / HZ
    print(f" demo {n}: hand x elevation >45 deg at {t45:.2f}s (grasp z {G[n, int(t45*HZ), 2]:.3f}),"
          f" >80 deg at {t80:.2f}s (grasp z {G[n, int(t80*HZ), 2]:.3f}); lowest z after that "
          f"{G[n, int(t80*HZ):, 2].min():.3f}")

# ---------------------------------------------------------------- scoop
hdr("scoop")
t = T["scoop"]
P, Q = t.positions, t.quaternions
G = grasp(P, Q)
M = mats(Q)
for n in range(9):
    k = int(G[n, :, 2].argmin())
    v = np.linalg.norm(np.diff(G[n], axis=0), axis=1) * HZ
    v = np.convolve(np.pad(v, 15, mode="edge"), np.ones(31) / 31, "valid")
    rr = rot(Q[n])
    w = deg((rr[1:] * rr[:-1].inv()).magnitude()) * HZ
    w = np.convolve(np.pad(w, 15, mode="edge"), np.ones(31) / 31, "valid")
    # speed minimum in the middle part (3..14 s)
    a, b = int(3 * HZ), int(14 * HZ)
    km = a + int(v[a:b].argmin())
    pitch = deg(np.arcsin(-M[n, :, 2, 0]))  # hand x below horizontal (deg, + = tip down)
    print(f"demo {n}: lowest grasp z {G[n,k,2]:.3f} at t={k/HZ:.2f}s, pos {G[n,k].round(3)}, "
          f"hand-x pitch there {pitch[k]:.1f} deg (start {pitch[0]:.1f}, end {pitch[-1]:.1f}); "
          f"slowest (3-14 s) {v[km]:.3f} m/s at t={km/HZ:.2f}s z={G[n,km,2]:.3f} while turning "
          f"{w[km]:.1f} deg/s; rotation from start at lowest "
          f"{deg((rr[k]*rr[0].inv()).magnitude()):.1f}"
          f", from lowest to end {deg((rr[-1]*rr[k].inv()).magnitude()):.1f}")
# which axis is the tool? tip = grasp + L * axis: spread of the tips' lowest points
print("tool-axis hypotheses: tip = grasp + L*axis; lowest tip point per demo: spread (max dist "
      "from mean, m) and mean lowest tip z")
for axn, ai, sg in (("+x", 0, 1), ("-x", 0, -1), ("+z", 2, 1)):
    for L in (0.0, 0.1, 0.15, 0.2, 0.25):
        tip = G + L * sg * M[..., :, ai]
        low = np.array([tip[n, tip[n, :, 2].argmin()] for n in range(9)])
        spread = np.linalg.norm(low - low.mean(0), axis=1).max()
        print(f"  axis {axn} L={L:.2f}: spread {spread:.3f}, lowest tip mean "
              f"{low.mean(0).round(3)}, z range [{low[:,2].min():.3f},{low[:,2].max():.3f}]")

# ---------------------------------------------------------------- matfolding
hdr("matfolding")
t = T["matfolding"]
P, Q = t.positions, t.quaternions
G = grasp(P, Q)
M = mats(Q)
print("grasp start per demo:\n", G[:, 0].round(3))
print("grasp end per demo:\n", G[:, -1].round(3))
print("start-end horizontal distance per demo",
      np.linalg.norm(G[:, -1, :2] - G[:, 0, :2], axis=1).round(3))
apex = np.array([G[n, G[n, :, 2].argmax()] for n in range(9)])
print("apex per demo:\n", apex.round(3))
mid = (G[:, 0, 1] + G[:, -1, 1]) / 2
print("apex y minus the start/end mid-y per demo", (apex[:, 1] - mid).round(3))
# hand flip: angle of hand z about world x at start and end (atan2 of y,z components)
ang0 = deg(np.arctan2(M[:, 0, 1, 2], -M[:, 0, 2, 2]))
ang1 = deg(np.arctan2(M[:, -1, 1, 2], -M[:, -1, 2, 2]))
print("hand z leaning towards +y from straight down (deg) at start", ang0.round(1),
      "end", ang1.round(1))
# time the grasp point first gets within 2 cm of its end position (horizontal)
for n in range(9):
    d = np.linalg.norm(G[n, :, :2] - G[n, -1, :2], axis=1)
    k = int(np.argmax(d < 0.02))
    print(f" demo {n}: within 2 cm (xy) of the end at t={k/HZ:.2f}s, z then {G[n,k,2]:.3f}; "
          f"z lowest in the last 30% {G[n,700:,2].min():.3f}; speed first sample "
          f"{np.linalg.norm(G[n,1]-G[n,0])*HZ:.3f} m/s")
