"""Largest pairwise end-orientation difference between the demos of each task (deg), and the
hand-frame start/end position spreads (m). Run from the repo root:
  nice -n 19 python docs/design/robotasks9/scripts/end_orientation_pairs.py \
      > results/robotasks9/end_orientation_pairs.txt"""
import numpy as np
from common import rot, tasks

T = tasks()
for name, t in T.items():
    r = rot(t.quaternions[:, -1])
    d = max(np.degrees((r[i].inv() * r[j]).magnitude()) for i in range(9) for j in range(9))
    P = t.positions
    print(f"{name:22s} end-orientation max pair {d:5.1f} deg; hand start spread "
          f"(max dist from mean) "
          f"{np.linalg.norm(P[:,0]-P[:,0].mean(0),axis=1).max():.4f} m; hand end spread "
          f"{np.linalg.norm(P[:,-1]-P[:,-1].mean(0),axis=1).max():.1e} m; "
          f"duration {(P.shape[1]-1)/60:.2f} s")
