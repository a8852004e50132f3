"""Which grip limit is tightest for a pan held by its handle (static gravity), per demo.
Run from the repo root:
  nice -n 19 python docs/design/robotasks9/scripts/pan_grip_limit.py \
      > results/robotasks9/pan_grip_limit.txt"""
import collections

import numpy as np
from common import mats, tasks

from clfd_bench.sim.grasp import grip_capacity

cap = grip_capacity("patch", mu=0.5, grip_force=70.0)
M = mats(tasks()["pan2stove"].quaternions)
for mass, lever in [(0.3, 0.12), (0.5, 0.15)]:
    kinds = collections.Counter()
    worst = (0, None, None)
    for n in range(9):
        for s in range(0, 1000, 10):
            Rm = M[n, s]
            f = np.array([0, 0, -9.81 * mass])
            tau = np.cross(lever * Rm[:, 0], f)
            r, k = cap.ratio(Rm.T @ f, Rm.T @ tau)
            if r > worst[0]:
                worst = (r, k, (n, s))
            kinds[k] += 1
    print(f"pan {mass} kg at {lever} m: worst ratio {worst[0]:.2f} ({worst[1]}, "
          f"demo {worst[2][0]} sample {worst[2][1]}); tightest limit counts {dict(kinds)}")
