"""Compact table of analyze_demos.json for the memo. Run from the repo root:
  python docs/design/robotasks9/scripts/summarize.py [PATH/analyze_demos.json] \
      > results/robotasks9/summary.txt
PATH defaults to $RT9_OUT, else results/robotasks9 in the repo."""
import json
import os
import sys
from pathlib import Path

import numpy as np

if len(sys.argv) > 1:
    SRC = Path(sys.argv[1])
else:
    default = Path(__file__).resolve().parents[4] / "results" / "robotasks9"
    SRC = Path(os.environ.get("RT9_OUT") or default) / "analyze_demos.json"
with open(SRC) as fh:
    d = json.load(fh)
for k in ["matfolding", "obstaclerotate", "pan2stove", "scoop", "wineglass"]:
    v = d[k]
    slow = v["slow_phases(v<1cm/s & w<5deg/s, >=0.3s): (t0,t1,grasp pt)"]
    start_slow = [s for demo in slow for s in demo if s[0] < 2]
    end_slow = [s[0] for demo in slow for s in demo if s[1] > 15]
    mid_slow = [s for demo in slow for s in demo if s[0] >= 2 and s[1] <= 15]
    print(f"== {k}")
    print(f" grasp start mean {v['grasp_start_mean']} (min {v['grasp_start_min']} "
          f"max {v['grasp_start_max']}), spread {v['grasp_start_spread_m']:.3f}")
    print(f" grasp end mean {v['grasp_end_mean']} spread {v['grasp_end_spread_m']:.3f}; "
          f"hand end {v['hand_end_mean']} spread {v['hand_end_spread_m']:.1e}")
    print(f" path length min/mean/max {np.round(v['path_len_m'],3)}")
    print(f" z min (min/mean/max) {np.round(v['z_min'],3)} at t {v['z_min_t_s']}")
    print(f" z max {np.round(v['z_max'],3)} at t {v['z_max_t_s']}")
    print(f" rot start->end {np.round(v['rot_start_end_deg'],1)} axis "
          f"{v['rot_axis_mean_base']} (axis dev max {v['rot_axis_dev_deg_max']:.1f}); "
          f"path-integrated {np.round(v['rot_path_integrated_deg'],1)}")
    print(f" end ori spread from mean {v['end_ori_spread_deg']:.1f}, "
          f"start {v['start_ori_spread_deg']:.2f}")
    print(f" peak speed {min(v['speed_peak_m_s'])}-{max(v['speed_peak_m_s'])} m/s; "
          f"peak ang speed {min(v['angspeed_peak_deg_s'])}-{max(v['angspeed_peak_deg_s'])} deg/s")
    print(f" slow phases: at start (t0<2 s) {len(start_slow)} demos "
          f"{[s[:2] for s in start_slow]}; mid {mid_slow}; final-rest onset t {sorted(end_slow)}")
    for ax in "xyz":
        print(f"  hand {ax} start {v[f'hand_{ax}_start']} end {v[f'hand_{ax}_end']}")
