#!/usr/bin/env bash
# The `full` profile's long runs (issue 38, item 5): the paper's seven methods at the paper's
# model sizes, one worker, one torch thread, niced, seed 0 of every dataset first (about 120 h
# of CPU, docs/studies/paper.md, "What the full runs still need"), in this order:
#   1. HelloWorld seed 0        2. RoboTasks seed 0
#   5. RoboTasks9 seed 0        6. LASA seed 0
#   3. HelloWorld seeds 0,1,2   4. RoboTasks seeds 0,1,2   (seed 0 is already done: reused)
# Each stage is `clfd-bench leaderboard --profile full`, which skips finished runs and resumes
# a killed one from its last task snapshot (written every 10 min, mid-task) or after its last
# finished task, so the same command resumes the whole list:
#
#   setsid nohup bash eval/full_runs.sh results/full >> results/full-runs.log 2>&1 &
#
# OUT (default results/full) gets one leaderboard folder per dataset (OUT/helloworld, ...).
# A second copy started while one runs exits at once (a lock in OUT). Environment: the
# caller's (CLFD_DATA_DIR, MENAGERIE_ROOT, an activated venv with clfd-bench installed);
# this checkout's clfd_bench is put first on PYTHONPATH. CLFD_FULL_STAGES="1 2" runs only
# those stages; CLFD_FULL_METHODS overrides the methods (default the paper's seven, the three
# issue 38 names first: hn,chn,rep,sg,ft,si,mas);
# CLFD_FULL_PROFILE another profile (default full; smoke checks this script in minutes).
# Finished runs are kept in the repository without their checkpoints (eval/full_keep.py),
# because a run outlives the machine it started on: before the first stage the kept runs
# missing under OUT are restored (so they are skipped; one another simulator executed is
# executed again), and after every stage the finished ones not kept yet, and the kept ones
# executed again, are archived into KEEP (CLFD_FULL_KEEP, default docs/studies/full-runs;
# "none" keeps nothing). Commit what it adds there.
# While the stages run, every CLFD_FULL_KEEP_EVERY seconds (default 1800; 0: never) the runs
# still training that learned a task since are kept too, with their checkpoint (up to
# CLFD_FULL_KEEP_MB, default 20: `full_keep.py save --partial`, which copies a run that trains
# until its files agree; docs/decisions.md, decision 7, gives each run's size), so a
# machine that ends without warning loses at most each run's task being learned; the next
# machine's restore lets the grid resume them after their last task. At a session's end run
# the same save once more by hand (no need to stop the runs) and commit what it adds.
set -uo pipefail
# Everything runs inside main, called on the last line: bash parses the whole file before the
# first run starts, so editing this file while it runs cannot change what it does.

stage() {  # stage N DATASET SEEDS
  local n="$1" dataset="$2" seeds="$3"
  case " $stages " in *" $n "*) ;; *) return 0 ;; esac
  echo "[full_runs] $(date -u +%FT%TZ) stage $n: $dataset seeds $seeds -> $out/$dataset"
  /usr/bin/time -f "[full_runs] stage $n: %U s user, %S s system, %e s wall" \
    nice -n 10 python -m clfd_bench.cli.main leaderboard --dataset "$dataset" \
    --profile "$profile" --methods "$methods" --seeds "$seeds" --workers 1 --out "$out/$dataset"
  echo "[full_runs] $(date -u +%FT%TZ) stage $n: exit $?"
  keep save
}

keeper() {  # every $1 seconds, keep the runs that learned a task since (with checkpoints)
  while sleep "$1"; do
    keep save --partial --max-mb "${CLFD_FULL_KEEP_MB:-20}" 2>&1 \
      | sed "s/^/[full_runs keeper $(date -u +%FT%TZ)] /"
  done
}

keep() {  # keep save [full_keep.py save's options]|restore
  [ "$keep_dir" = none ] && return 0
  local what="$1"; shift
  if [ "$what" = save ]; then python "$repo/eval/full_keep.py" save "$@" "$out" "$keep_dir"
  else python "$repo/eval/full_keep.py" restore "$keep_dir" "$out"; fi
}

main() {
  repo="$(cd "$(dirname "$0")/.." && pwd)"
  out="${1:-$repo/results/full}"
  methods="${CLFD_FULL_METHODS:-hn,chn,rep,sg,ft,si,mas}"
  stages="${CLFD_FULL_STAGES:-1 2 3 4 5 6}"
  profile="${CLFD_FULL_PROFILE:-full}"
  keep_dir="${CLFD_FULL_KEEP:-$repo/docs/studies/full-runs}"
  export PYTHONPATH="$repo${PYTHONPATH:+:$PYTHONPATH}"
  export CLFD_NO_PROGRESS=1 MUJOCO_GL="${MUJOCO_GL:-egl}"
  # `nice` alone does not yield to the rest of the machine when this script leads its own
  # session (setsid, as above) on a kernel with autogroup scheduling: each session is its own
  # group, groups share the CPUs equally whatever their processes' nice, and on 2 cores these
  # runs took 2/3 of the CPU from a test suite (2026-12-07). So the session's group is niced
  # too, only when this script leads it (never the caller's terminal session). The grid's
  # training workers lead sessions of their own and take this group's nice from the grid
  # (clfd_bench.procs.keep_parent_priority; before that they ran at group nice 0, 2026-12-07).
  if [ "$(ps -o sid= -p $$ | tr -d ' ')" = "$$" ] && [ -w /proc/self/autogroup ]; then
    echo 10 > /proc/self/autogroup 2>/dev/null || true
  fi

  mkdir -p "$out"
  exec 9>"$out/.full_runs.lock"
  if ! flock -n 9; then
    echo "[full_runs] another full_runs.sh holds $out/.full_runs.lock; not starting" >&2
    return 3
  fi

  echo "[full_runs] $(date -u +%FT%TZ) start, profile $profile: $repo" \
    "($(git -C "$repo" rev-parse --short HEAD 2>/dev/null)), out $out, kept runs $keep_dir"
  keep restore || { echo "[full_runs] the kept runs cannot be restored; not starting" >&2
                    return 2; }
  local every="${CLFD_FULL_KEEP_EVERY:-1800}"
  if [ "$keep_dir" != none ] && [ "$every" != 0 ]; then
    keeper "$every" &
    keeper_pid=$!  # global: the EXIT trap runs after main returns
    trap 'pkill -P "$keeper_pid" 2>/dev/null; kill "$keeper_pid" 2>/dev/null' EXIT
  fi
  stage 1 helloworld 0
  stage 2 robotasks 0
  stage 5 robotasks9 0
  stage 6 lasa 0
  stage 3 helloworld 0,1,2
  stage 4 robotasks 0,1,2
  echo "[full_runs] $(date -u +%FT%TZ) all stages done"
}

main "$@"; exit $?
