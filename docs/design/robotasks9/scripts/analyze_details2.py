"""More task-specific measurements (obstaclerotate: swept bar and free regions; pan2stove: first
motion; scoop: tool tip for the +hand-x hypothesis). Run from the repo root:
  nice -n 19 python docs/design/robotasks9/scripts/analyze_details2.py \
      > results/robotasks9/analyze_details2.txt"""
import numpy as np
from common import HZ, grasp, mats, tasks

np.set_printoptions(precision=3, suppress=True)
T = tasks()

print("======== pan2stove: grasp displacement from the start")
t = T["pan2stove"]
G = grasp(t.positions, t.quaternions)
M = mats(t.quaternions)
for sec in (1.0, 2.0, 3.0, 4.0):
    d = G[:, int(sec * HZ)] - G[:, 0]
    print(f" after {sec} s: mean {d.mean(0).round(3)}, per-demo dz {d[:, 2].round(3)}")
# displacement expressed in the hand frame at the start (along hand x, y, z)
d = G[:, int(2 * HZ)] - G[:, 0]
print(" first 2 s displacement in the start hand frame (x, y, z):\n",
      np.einsum("nij,ni->nj", M[:, 0], d).round(3))
# end: candidate pan centre for body along +hand x (12 cm) and +hand y (10 cm)
for lab, ax, L in (
    ("+hand x 0.12", 0, 0.12), ("-hand x 0.12", 0, -0.12), ("+hand y 0.10", 1, 0.10)
):
    c = G[:, -1] + L * M[:, -1, :, ax]
    print(f" pan centre at end if body along {lab}: mean {c.mean(0).round(3)}, spread "
          f"{np.linalg.norm(c - c.mean(0), axis=1).max():.3f}")
    c0 = G[:, 0] + L * M[:, 0, :, ax]
    print(f"   ... at start: mean {c0.mean(0).round(3)}, spread "
          f"{np.linalg.norm(c0 - c0.mean(0), axis=1).max():.3f}")

print("\n======== scoop: tool along +hand x, tip at L")
t = T["scoop"]
G = grasp(t.positions, t.quaternions)
M = mats(t.quaternions)
for L in (0.12, 0.18):
    tip = G + L * M[..., :, 0]
    for n in range(9):
        k = int(tip[n, :, 2].argmin())
        pitch = np.degrees(np.arcsin(-M[n, :, 2, 0]))
        up = -M[n, :, :, 2]  # candidate scoop opening normal (-hand z)
        el = 90 - np.degrees(np.arccos(np.clip(up[:, 2], -1, 1)))
        print(f" L={L} demo {n}: lowest tip {tip[n,k].round(3)} at t={k/HZ:.2f}s, pitch there "
              f"{pitch[k]:.1f} (start {pitch[0]:.1f} end {pitch[-1]:.1f}); opening (-hand z) "
              f"elevation start {el[0]:.0f} at-lowest {el[k]:.0f} end {el[-1]:.0f} deg; "
              f"tip end {tip[n,-1].round(3)};"
              f" tip z rise lowest->end {tip[n,-1,2]-tip[n,k,2]:.3f}")
    low = np.array([tip[n, tip[n, :, 2].argmin()] for n in range(9)])
    print(f" L={L}: lowest tips bbox min {low.min(0).round(3)} max {low.max(0).round(3)}")
    # time the tip spends within 3 cm above its lowest point
    dur = [(tip[n, :, 2] < tip[n, :, 2].min() + 0.03).sum() / HZ for n in range(9)]
    print(f" L={L}: time within 3 cm of the lowest tip height (s): {np.round(dur, 2)}")

print("\n======== obstaclerotate: swept top-view footprint of a bar held at its middle along "
      "hand x")
t = T["obstaclerotate"]
P, Q = t.positions, t.quaternions
G = grasp(P, Q)
M = mats(Q)
xs = np.arange(0.0, 0.75, 0.01)
ys = np.arange(-0.85, 0.35, 0.01)


def footprint(Gp, Mx, half, zmax=None):
    occ = np.zeros((len(ys), len(xs)), bool)
    s = np.linspace(-half, half, 25)
    for n in range(Gp.shape[0]):
        for k in range(0, Gp.shape[1], 3):
            if zmax is not None and Gp[n, k, 2] > zmax:
                continue
            pts = Gp[n, k, :2][None] + s[:, None] * Mx[n, k, :2][None]
            ix = np.clip(np.round((pts[:, 0] - xs[0]) / 0.01).astype(int), 0, len(xs) - 1)
            iy = np.clip(np.round((pts[:, 1] - ys[0]) / 0.01).astype(int), 0, len(ys) - 1)
            occ[iy, ix] = True
    return occ


for half in (0.10, 0.15):
    demo_occ = footprint(G, M[..., :, 0], half)
    frozen = np.repeat(M[:, :1], M.shape[1], axis=1)
    froz_occ = footprint(G, frozen[..., :, 0], half)
    extra = froz_occ & ~demo_occ
    iy, ix = np.nonzero(extra)
    print(f" bar half-length {half}: cells (1 cm) swept by the frozen-orientation bar and by no "
          f"demo's bar: {extra.sum()}; their bbox x [{xs[ix].min() if len(ix) else np.nan:.2f},"
          f" {xs[ix].max() if len(ix) else np.nan:.2f}] "
          f"y [{ys[iy].min() if len(iy) else np.nan:.2f},"
          f" {ys[iy].max() if len(iy) else np.nan:.2f}]")
    # where (in time) along the frozen paths do they enter those cells
    s = np.linspace(-half, half, 25)
    first = []
    for n in range(9):
        for k in range(0, P.shape[1], 3):
            pts = G[n, k, :2][None] + s[:, None] * frozen[n, k, :2, 0][None]
            ix2 = np.clip(np.round((pts[:, 0] - xs[0]) / 0.01).astype(int), 0, len(xs) - 1)
            iy2 = np.clip(np.round((pts[:, 1] - ys[0]) / 0.01).astype(int), 0, len(ys) - 1)
            if extra[iy2, ix2].any():
                first.append((n, k / HZ, *G[n, k].round(3)))
                break
    print("  first entry per demo (demo, t, grasp xyz):", first)
# the low segment: how long the grasp stays below 8 cm, and the y range then
for n in range(9):
    low = G[n, :, 2] < 0.08
    k1 = int(np.argmax(~low[5:]) + 5)
    print(f" demo {n}: grasp z < 8 cm for the first {k1/HZ:.2f} s, y from {G[n,0,1]:.3f} to "
          f"{G[n,k1,1]:.3f}, x from {G[n,0,0]:.3f} to {G[n,k1,0]:.3f}")
