#!/usr/bin/env bash
# Create the peer environments for `wbmp bench --peers`, next to (never inside) the project's .venv:
#
#   .venv-crocoddyl  crocoddyl 3.2.1 + pin 4.0.0 (the crocoddyl wheel segfaults with pin 4.1)
#   .venv-tsid       pin 4.1.0 (the project's) + tsid 1.10.0 built from source: libtsid has no
#                    binary wheel, and the tsid binding wheel crashes with pin 4.1, so both are
#                    compiled here against the installed pin (long: ~40 min on 2 busy cores)
#   .venv-mink       mink 1.3.0 + the daqp QP solver + MuJoCo 4.0.0 (the project's), for the
#                    per-frame IK retargeter of benchmarks/bench_retarget.py (MINK_VENV=DIR puts
#                    it elsewhere; binary wheels only, about a minute)
#
# The two cannot share one environment: crocoddyl needs pin 4.0, and TSID should tick on the
# same pin 4.1 as wbmp's controller for a fair comparison.
#
# Usage: bash benchmarks/peers/setup.sh [crocoddyl|tsid|mink|all]   (default: all)
# Idempotent: an environment whose imports already work is left alone. CMEEL_JOBS sets the
# number of compile jobs (default 2); the C++ unit tests are not built (CMEEL_RUN_TESTS=OFF). Exit code 3 when an environment cannot be made.
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
PY="${PYTHON:-$(command -v python3.11 || command -v python3)}"
WHAT="${1:-all}"
export CMEEL_JOBS="${CMEEL_JOBS:-2}"
export CMEEL_RUN_TESTS="${CMEEL_RUN_TESTS:-OFF}"  # skip building and running the C++ unit tests
export PIP_DISABLE_PIP_VERSION_CHECK=1
status=0

pipq() { "$1/bin/python" -m pip install --quiet "${@:2}" 2>&1 | grep -v "^WARNING: Location" || true; }

make_venv() {
  if [ ! -x "$1/bin/python" ]; then
    echo "creating $1"
    "$PY" -m venv "$1" || return 1
  fi
}

setup_crocoddyl() {
  local V="$ROOT/.venv-crocoddyl"
  if "$V/bin/python" -c "import crocoddyl, example_robot_data" >/dev/null 2>&1; then
    echo "crocoddyl: $V ready"; return 0
  fi
  make_venv "$V" || return 1
  echo "crocoddyl: installing crocoddyl 3.2.1 with pin 4.0.0 into $V"
  pipq "$V" "pin==4.0.0" "libpinocchio==4.0.0" "crocoddyl==3.2.1" "example-robot-data-loaders"
  "$V/bin/python" -c "import crocoddyl, pinocchio, example_robot_data
assert pinocchio.__version__.startswith('4.0'), pinocchio.__version__
print('crocoddyl', crocoddyl.__version__, 'with pin', pinocchio.__version__)"
}

setup_tsid() {
  local V="$ROOT/.venv-tsid"
  if "$V/bin/python" -c "import tsid, example_robot_data" >/dev/null 2>&1; then
    echo "tsid: $V ready"
  else
    make_venv "$V" || return 1
    echo "tsid: installing pin 4.1.0 and the build requirements into $V"
    pipq "$V" "pin==4.1.0" "libpinocchio[build]==4.1.0" "eigenpy[build]" "eiquadprog[build]" \
      "cmeel[build]" "example-robot-data-loaders"
    if ! "$V/bin/python" -m pip show libtsid >/dev/null 2>&1; then
      echo "tsid: compiling libtsid 1.10.0 from its source distribution (CMEEL_JOBS=$CMEEL_JOBS; long)"
      "$V/bin/python" -m pip install --quiet --no-build-isolation --no-deps "libtsid==1.10.0" \
        2>&1 | grep -v "^WARNING: Location" || true
    fi
    echo "tsid: compiling the tsid 1.10.0 bindings against pin 4.1.0"
    "$V/bin/python" -m pip install --quiet --no-build-isolation --no-deps --no-binary tsid "tsid==1.10.0" \
      2>&1 | grep -v "^WARNING: Location" || true
    "$V/bin/python" -c "import tsid, pinocchio; print('tsid built against pin', pinocchio.__version__)" || return 1
  fi
}

setup_mink() {
  local V="${MINK_VENV:-$ROOT/.venv-mink}"
  if "$V/bin/python" -c "import mink, daqp, mujoco" >/dev/null 2>&1; then
    echo "mink: $V ready"; return 0
  fi
  make_venv "$V" || return 1
  echo "mink: installing mink 1.3.0, daqp and mujoco 4.0.0 into $V"
  pipq "$V" "mink==1.3.0" "daqp" "mujoco==4.0.0"
  "$V/bin/python" -c "import mink, mujoco, qpsolvers
assert 'daqp' in qpsolvers.available_solvers, qpsolvers.available_solvers
print('mink ready with mujoco', mujoco.__version__)"
}

case "$WHAT" in
  crocoddyl) setup_crocoddyl || status=3 ;;
  tsid) setup_tsid || status=3 ;;
  mink) setup_mink || status=3 ;;
  all)
    setup_crocoddyl || { echo "crocoddyl environment failed" >&2; status=3; }
    setup_tsid || { echo "tsid environment failed" >&2; status=3; }
    setup_mink || { echo "mink environment failed" >&2; status=3; }
    ;;
  *) echo "usage: $0 [crocoddyl|tsid|mink|all]" >&2; exit 2 ;;
esac
exit $status
