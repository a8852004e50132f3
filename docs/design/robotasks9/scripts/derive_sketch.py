"""Sketch of the scene derivations proposed in memo.md, in the style of
clfd_bench.envs.robotasks.derive (lowest point of the held prop - 1.5 cm, etc.), with simple
geometric prop models (design assumptions, stated below). Run from the repo root:
  nice -n 19 python docs/design/robotasks9/scripts/derive_sketch.py \
      > results/robotasks9/derive_sketch.txt"""
import numpy as np
from common import HZ, grasp, mats, tasks

np.set_printoptions(precision=3, suppress=True)
T = tasks()
MARGIN = 0.015  # the repo's POSITION_MARGIN


def pts_in_hand(G, M, local):
    """world points [N, L, K, 3] of prop points given in the grasp frame (hand axes)."""
    return G[..., None, :] + np.einsum("nlij,kj->nlki", M, local)


def ring(center, axis_u, axis_v, r, k=24):
    a = np.linspace(0, 2 * np.pi, k, endpoint=False)
    return center[None] + r * (
        np.cos(a)[:, None] * axis_u[None] + np.sin(a)[:, None] * axis_v[None]
    )


ex, ey, ez = np.eye(3)

print("======== wineglass: glass axis along hand x (bowl towards +x), stem grasped")
# design: foot disc r 3.5 cm at -7 cm along the axis; bowl widest r 4 cm at +7 cm,
# rim r 3.5 cm at +12 cm
glass = np.concatenate([ring(-0.07 * ex, ey, ez, 0.035), ring(0.07 * ex, ey, ez, 0.04),
                        ring(0.12 * ex, ey, ez, 0.035)])
t = T["wineglass"]
G = grasp(t.positions, t.quaternions)
M = mats(t.quaternions)
P = pts_in_hand(G, M, glass)
n5 = P.shape[1] // 5
start_low = P[:, :n5, :, 2].min(axis=(1, 2))
end_low = P[:, -1, :, 2].min(1)
print(" lowest glass point in the first fifth per demo", start_low.round(3),
      "-> table_z = min - 1.5 cm =", round(float(start_low.min() - MARGIN), 3))
print(" lowest glass point at the demos' end (foot) per demo", end_low.round(3),
      "-> support top = min - 1.5 cm (the bottle2shelf rule) =",
      round(float(end_low.min() - MARGIN), 3),
      "; release heights above it", (end_low - (end_low.min() - MARGIN)).round(3))
foot_end = G[:, -1] - 0.07 * M[:, -1, :, 0]
print(" foot centre at end: mean", foot_end.mean(0).round(3), "spread",
      round(float(np.linalg.norm(foot_end - foot_end.mean(0), axis=1).max()), 3))
foot_start = G[:, 0] - 0.07 * M[:, 0, :, 0]
print(" foot centre at start: mean", foot_start.mean(0).round(3))
# how low does the glass get in the middle (carried over the table?)
print(" lowest glass point over the whole demo per demo", P[..., 2].min(axis=(1, 2)).round(3))

print("\n======== pan2stove: handle along hand x, pan body towards +hand x (hangs below the "
      "handle at the start)")
# design: pan r 10 cm, its centre 15 cm along +hand x from the grasp and its bottom 5 cm along
# +hand z (below the handle when the pan lies flat); rim 4 cm above the bottom
t = T["pan2stove"]
G = grasp(t.positions, t.quaternions)
M = mats(t.quaternions)
c_bottom = 0.15 * ex + 0.05 * ez
pan = np.concatenate([ring(c_bottom, ex, ey, 0.10), ring(c_bottom - 0.04 * ez, ex, ey, 0.11)])
P = pts_in_hand(G, M, pan)
n5 = P.shape[1] // 5
print(" pan normal (hand z) tilt from vertical at start",
      np.degrees(np.arccos(np.abs(M[:, 0, 2, 2]))).round(1))
print(" lowest pan point in the first fifth per demo", P[:, :n5, :, 2].min(axis=(1, 2)).round(3))
print(" lowest pan point at start", P[:, 0, :, 2].min(1).round(3), " pan centre at start",
      (G[:, 0] + np.einsum("nij,j->ni", M[:, 0], c_bottom)).mean(0).round(3))
end_low = P[:, -1, :, 2].min(1)
cen_end = G[:, -1] + np.einsum("nij,j->ni", M[:, -1], c_bottom)
print(" lowest pan point at end per demo", end_low.round(3), "-> stove top = min - 1.5 cm =",
      round(float(end_low.min() - MARGIN), 3))
print(" pan bottom centre at end: mean", cen_end.mean(0).round(3), "spread",
      round(float(np.linalg.norm(cen_end[:, :2] - cen_end[:, :2].mean(0), axis=1).max()), 3))
print(" lowest pan point over the whole demo", P[..., 2].min(axis=(1, 2)).round(3))

print("\n======== scoop: tool along +hand x, scoop bowl (r 3 cm) centred 15 cm out, opening "
      "towards -hand z")
t = T["scoop"]
G = grasp(t.positions, t.quaternions)
M = mats(t.quaternions)
bowl = np.concatenate([ring(0.15 * ex + 0.015 * ez, ex, ey, 0.03), (0.15 * ex + 0.03 * ez)[None]])
P = pts_in_hand(G, M, bowl)
low = P[..., 2].min(2)
k = low.argmin(1)
lowpt = np.array([P[n, k[n]].mean(0) for n in range(9)])
print(" scoop bowl's lowest point per demo", low.min(1).round(3), "at t", (k / HZ).round(2))
print(" scoop bowl centre there: mean", lowpt.mean(0).round(3), "bbox", lowpt.min(0).round(3),
      lowpt.max(0).round(3))
# opening elevation at the end and the scoop's lowest point at the end
up_end = -M[:, -1, :, 2]
print(" opening normal tilt from vertical at end", np.degrees(np.arccos(up_end[:, 2])).round(1))
print(" bowl lowest point at end", low[:, -1].round(3))

print("\n======== obstaclerotate: the largest box the demos' paths avoid")
t = T["obstaclerotate"]
G = grasp(t.positions, t.quaternions)
pts = G.reshape(-1, 3)
c = 0.05 + MARGIN        # held object's half-size (design, 5 cm) + margin
REGION = dict(all=((0.25, 0.80), (-0.60, 0.35)), bend=((0.20, 0.65), (-0.35, 0.0)))


def largest_empty_rect(occ):
    """(area, (i0, i1, j0, j1)) of the largest all-False axis-aligned rectangle of occ [ny, nx]."""
    ny, nx = occ.shape
    h = np.zeros(nx, int)
    best = (0, None)
    for i in range(ny):
        h = np.where(occ[i], 0, h + 1)
        stack = []
        for j in range(nx + 1):
            cur = h[j] if j < nx else 0
            start = j
            while stack and stack[-1][1] >= cur:
                s, hh = stack.pop()
                area = hh * (j - s)
                if area > best[0]:
                    best = (area, (i - hh + 1, i, s, j - 1))
                start = s
            stack.append((start, cur))
    return best


chord = np.linspace(G[:, 0].mean(0), G[:, -1].mean(0), 200)
for reg, ((xa, xb), (ya, yb)) in REGION.items():
    xs = np.arange(xa, xb, 0.01)
    ys = np.arange(ya, yb + 1e-9, 0.01)
    X, Y = np.meshgrid(xs, ys, indexing="xy")
    print(f" search region {reg}: x [{xa}, {xb}] y [{ya}, {yb}]")
    for hgt in (0.10, 0.15, 0.20, 0.25, 0.30):
        low = pts[pts[:, 2] < hgt + c]
        occ = np.zeros(X.shape, bool)
        for p in low[::2]:
            occ |= (np.abs(X - p[0]) < c) & (np.abs(Y - p[1]) < c)
        area, (i0, i1, j0, j1) = largest_empty_rect(occ)
        box = (xs[j0], xs[j1], ys[i0], ys[i1])
        inside = ((chord[:, 0] >= box[0]) & (chord[:, 0] <= box[1]) & (chord[:, 1] >= box[2])
                  & (chord[:, 1] <= box[3]) & (chord[:, 2] < hgt))
        print(f" height {hgt:.2f} m above z=0: box x [{box[0]:.2f}, {box[1]:.2f}] "
              f"y [{box[2]:.2f}, {box[3]:.2f}]"
              f" ({(box[1]-box[0])*100:.0f} x {(box[3]-box[2])*100:.0f} cm); "
              f"the start->end straight line "
              f"runs through it: {bool(inside.any())}")
