#!/bin/bash
# Re-runs every mat / speed measurement of the memo (../README.md, section 3), one process at a
# time, niced, saving JSON lines. Each run < 5 s of CPU; ~1 min in all.
# Usage (from anywhere): bash docs/design/robotasks9/scripts/run_mat_all.sh
# Outputs go to $RT9_OUT (default: results/robotasks9 in the repo, git-ignored): the two .jsonl
# files, bench_env_results.txt, mat_bench_results.jsonl.load (uptime) and plots/mat_*.png.
# MuJoCo's MUJOCO_LOG.TXT, if any, lands there too.
SCRIPTS="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$SCRIPTS/../../../.." && pwd)"
source "$REPO/.venv/bin/activate"
export MUJOCO_GL=egl OMP_NUM_THREADS=1
export RT9_OUT="${RT9_OUT:-$REPO/results/robotasks9}"
mkdir -p "$RT9_OUT"
cd "$RT9_OUT" || exit 1
MB="$SCRIPTS/mat_bench.py"
uptime > mat_bench_results.jsonl.load
: > mat_bench_results.jsonl
for v in chain6 chain12; do for a in edge corner; do
  timeout 170 nice -n 19 python "$MB" $v --attach=$a --render >> mat_bench_results.jsonl; done; done
for v in chain6 chain12; do
  timeout 170 nice -n 19 python "$MB" $v --attach=edge --weld=75 --render \
    >> mat_bench_results.jsonl
  timeout 170 nice -n 19 python "$MB" $v --attach=edge --L=0.6 --W=0.3 --mass=0.3 --render \
    >> mat_bench_results.jsonl
  timeout 170 nice -n 19 python "$MB" $v --attach=edge --weld=75 --L=0.6 --W=0.3 --mass=0.3 \
    --render >> mat_bench_results.jsonl
done
for v in flex7x5_self_discrete flex7x5_self_edgeeq flex13x9_self_discrete flex13x9_self_edgeeq \
         flex13x9_noself_discrete flex13x9_noself_edgeeq flex13x9_self_E2e6_discrete; do
  timeout 170 nice -n 19 python "$MB" $v --attach=corner --render >> mat_bench_results.jsonl; done
for v in flex7x5_self_discrete flex13x9_self_discrete; do
  timeout 170 nice -n 19 python "$MB" $v --attach=edge --render >> mat_bench_results.jsonl; done
: > mat_panda_results.jsonl
for v in none chain6 chain12 flex7x5_self_discrete flex7x5_self_edgeeq; do
  timeout 170 nice -n 19 python "$SCRIPTS/mat_panda_bench.py" $v 2>/dev/null \
    >> mat_panda_results.jsonl; done
timeout 170 nice -n 19 python "$SCRIPTS/bench_env.py" > bench_env_results.txt
uptime >> mat_bench_results.jsonl.load
