"""Per-task measurements of the RoboTasks9 demos (grasp point = hand + 0.1034 m along hand z).
Run from the repo root:
  nice -n 19 python docs/design/robotasks9/scripts/analyze_demos.py \
      > results/robotasks9/analyze_demos.json"""
import json

import numpy as np
from common import HZ, NEW, grasp, mats, rot, tasks

T = tasks()
out = {}


def smooth(x, k=9):
    ker = np.ones(k) / k
    xp = np.pad(x, ((k // 2, k // 2), (0, 0)), mode="edge")
    return np.stack([np.convolve(xp[:, i], ker, mode="valid") for i in range(x.shape[1])], 1)


def intervals(mask, min_len):
    res, start = [], None
    for i, v in enumerate(np.append(mask, False)):
        if v and start is None:
            start = i
        if not v and start is not None:
            if i - start >= min_len:
                res.append((start, i - 1))
            start = None
    return res


for name in NEW + ["openbox", "bottle2shelf", "platestandingtolying", "pouring"]:
    t = T[name]
    P, Q = t.positions, t.quaternions
    G = grasp(P, Q)
    M = mats(Q)
    N, L = P.shape[:2]
    r = {}
    r["hand_end_spread_m"] = float(np.linalg.norm(P[:, -1] - P[:, -1].mean(0), axis=1).max())
    r["grasp_end_spread_m"] = float(np.linalg.norm(G[:, -1] - G[:, -1].mean(0), axis=1).max())
    r["grasp_start_spread_m"] = float(np.linalg.norm(G[:, 0] - G[:, 0].mean(0), axis=1).max())
    r["grasp_start_mean"] = G[:, 0].mean(0).round(4).tolist()
    r["grasp_start_min"] = G[:, 0].min(0).round(4).tolist()
    r["grasp_start_max"] = G[:, 0].max(0).round(4).tolist()
    r["grasp_end_mean"] = G[:, -1].mean(0).round(4).tolist()
    r["hand_end_mean"] = P[:, -1].mean(0).round(4).tolist()
    # end orientation spread (deg) from the mean
    rots_end = rot(Q[:, -1])
    mean_end = rots_end.mean()
    r["end_ori_spread_deg"] = float(np.degrees((mean_end.inv() * rots_end).magnitude()).max())
    rots_start = rot(Q[:, 0])
    r["start_ori_spread_deg"] = float(
        np.degrees((rots_start.mean().inv() * rots_start).magnitude()).max()
    )
    plen = np.linalg.norm(np.diff(G, axis=1), axis=2).sum(1)
    r["path_len_m"] = [float(plen.min()), float(plen.mean()), float(plen.max())]
    z = G[..., 2]
    r["z_min"] = [float(z.min(1).min()), float(z.min(1).mean()), float(z.min(1).max())]
    r["z_min_t_s"] = (z.argmin(1) / HZ).round(2).tolist()
    r["z_max"] = [float(z.max(1).min()), float(z.max(1).mean()), float(z.max(1).max())]
    r["z_max_t_s"] = (z.argmax(1) / HZ).round(2).tolist()
    r["z_start_mean"] = float(z[:, 0].mean())
    r["z_end_mean"] = float(z[:, -1].mean())
    # total rotation start->end and its axis (base frame)
    ang, axes, pathang = [], [], []
    for n in range(N):
        rr = rot(Q[n])
        d = rr[-1] * rr[0].inv()  # world-frame rotation taking start to end
        rv = d.as_rotvec()
        ang.append(np.degrees(np.linalg.norm(rv)))
        axes.append(rv / max(np.linalg.norm(rv), 1e-9))
        inc = (rr[1:] * rr[:-1].inv()).magnitude()
        pathang.append(np.degrees(inc.sum()))
    axes = np.array(axes)
    r["rot_start_end_deg"] = [float(min(ang)), float(np.mean(ang)), float(max(ang))]
    r["rot_axis_mean_base"] = (axes.mean(0) / np.linalg.norm(axes.mean(0))).round(3).tolist()
    r["rot_axis_dev_deg_max"] = float(
        np.degrees(
            np.arccos(np.clip(axes @ (axes.mean(0) / np.linalg.norm(axes.mean(0))), -1, 1))
        ).max()
    )
    r["rot_path_integrated_deg"] = [
        float(min(pathang)), float(np.mean(pathang)), float(max(pathang))
    ]
    # hand axes at start and end (mean), base frame
    for lab, k in (("start", 0), ("end", -1)):
        for ai, an in enumerate("xyz"):
            v = M[:, k, :, ai].mean(0)
            r[f"hand_{an}_{lab}"] = (v / np.linalg.norm(v)).round(3).tolist()
    # speed profile: grasp point speed (m/s) and angular speed (deg/s), smoothed over 9 samples
    slow = []
    for n in range(N):
        v = np.linalg.norm(np.diff(smooth(G[n]), axis=0), axis=1) * HZ
        rr = rot(Q[n])
        w = np.degrees((rr[1:] * rr[:-1].inv()).magnitude()) * HZ
        w = np.convolve(np.pad(w, 4, mode="edge"), np.ones(9) / 9, mode="valid")
        mask = (v < 0.01) & (w < 5.0)
        iv = intervals(mask, int(0.3 * HZ))
        slow.append([
            (round(a / HZ, 2), round(b / HZ, 2), [round(x, 3) for x in G[n, (a + b) // 2]])
            for a, b in iv
        ])
        r.setdefault("speed_peak_m_s", []).append(round(float(v.max()), 3))
        r.setdefault("angspeed_peak_deg_s", []).append(round(float(w.max()), 1))
    r["slow_phases(v<1cm/s & w<5deg/s, >=0.3s): (t0,t1,grasp pt)"] = slow
    out[name] = r

print(json.dumps(out, indent=1))
