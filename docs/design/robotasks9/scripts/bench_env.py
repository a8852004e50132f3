"""Speed of the existing clfd/BottleShelving-v2 env (the repo's bench, read-only use):
clfd_bench.execution.bench.bench_env on demo 0, best of 2. Run from the repo root:
  nice -n 19 python docs/design/robotasks9/scripts/bench_env.py \
      > results/robotasks9/bench_env_results.txt"""
import json

from clfd_bench.execution.bench import bench_env, machine_note

print(machine_note())
r = bench_env("clfd/BottleShelving-v2", demo=0, repeats=2)
r["us_per_control_step_cpu"] = r["cpu_s"] / r["steps"] * 1e6
print(json.dumps(r, default=float))
