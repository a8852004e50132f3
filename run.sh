#!/usr/bin/env bash
# clfd-bench's two set-up commands (see README):
#   bash run.sh main   # set up, then run the main job (writes results/)
#   bash run.sh test   # set up, then run the test suite
# Set-up: a virtual environment in .venv (or $CLFD_VENV) with torch 2.13.0 and the project
# installed in editable mode; reused on later runs. Offline machines: set CLFD_DATA_DIR and
# MENAGERIE_ROOT once, for this command (docs/data.md, "Downloads, cache and offline use");
# ../shared is used when it is beside the repo. Either is then remembered in the venv
# (clfd_bench/settings.py).
set -euo pipefail
cd "$(dirname "$0")"
what="${1:-}"
case "$what" in
  main|test|setup) ;;
  *) echo "usage: bash run.sh main|test|setup" >&2; exit 2 ;;
esac

venv="${CLFD_VENV:-.venv}"
if [ ! -x "$venv/bin/python" ]; then
  echo "[run.sh] creating virtual environment $venv" >&2
  python3 -m venv "$venv"
fi
# shellcheck disable=SC1091
. "$venv/bin/activate"
stamp="$venv/.clfd-installed"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "[run.sh] installing clfd-bench and its dependencies into $venv" >&2
  python -m pip install --quiet --upgrade pip
  if ! python -c "import torch" 2>/dev/null; then
    # CLFD_TORCH_INDEX (e.g. https://download.pytorch.org/whl/cpu) picks a CPU-only build.
    python -m pip install --quiet "torch==2.13.0" ${CLFD_TORCH_INDEX:+--index-url "$CLFD_TORCH_INDEX"}
  fi
  python -m pip install --quiet -e ".[dev,dist,dm]"
  touch "$stamp"
fi

# Where the data and the robot model are: an exported CLFD_DATA_DIR / MENAGERIE_ROOT, else the
# venv's settings file, else the offline copies beside the checkout (CI, this project's
# machines). What is found is recorded in the venv's settings file (clfd_bench/settings.py), so
# every later shell that uses the venv finds them without exports.
settings="$venv/clfd-bench.toml"
if [ -z "${CLFD_DATA_DIR:-}" ] && [ -d ../shared/datasets ] \
    && ! grep -q '^CLFD_DATA_DIR' "$settings" 2>/dev/null; then
  export CLFD_DATA_DIR="$(cd ../shared/datasets && pwd)"
fi
if [ -z "${MENAGERIE_ROOT:-}" ] && [ -d ../shared/menagerie ] \
    && ! grep -q '^MENAGERIE_ROOT' "$settings" 2>/dev/null; then
  export MENAGERIE_ROOT="$(cd ../shared/menagerie && pwd)"
fi
if [ -n "${CLFD_DATA_DIR:-}${MENAGERIE_ROOT:-}" ]; then
  clfd-bench settings ${CLFD_DATA_DIR:+"CLFD_DATA_DIR=$CLFD_DATA_DIR"} \
    ${MENAGERIE_ROOT:+"MENAGERIE_ROOT=$MENAGERIE_ROOT"} >&2
fi
export MUJOCO_GL="${MUJOCO_GL:-egl}"

case "$what" in
  setup) echo "[run.sh] ready: . $venv/bin/activate" >&2 ;;
  # One pytest-xdist worker per core; the tests that share a module's fixture stay together
  # (tests/conftest.py: FixtureScopeScheduling). More arguments go to pytest, e.g.
  # `bash run.sh test tests/test_data.py`.
  test) exec python -m pytest -q -n auto --dist loadscope "${@:2}" ;;
  main) exec python eval/main_job.py "${@:2}" ;;
esac
