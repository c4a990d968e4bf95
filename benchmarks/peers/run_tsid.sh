#!/usr/bin/env bash
# TSID peer of benchmarks/bench_wbc.py, in its own environment (.venv-peers), never in .venv.
#
# The tsid 1.10 binary wheel crashes with pin 4.1 (a binding build mismatch); built from its
# source distribution against the installed pin it works (about 2 minutes of compilation).
# Usage: bash benchmarks/peers/run_tsid.sh [--ticks 3000]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
VENV="$ROOT/.venv-peers"
PY="${PYTHON:-python3}"
if [ ! -x "$VENV/bin/python" ]; then
  "$PY" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q "pin==4.1.0" "example-robot-data>=5" "numpy>=2"
if ! "$VENV/bin/python" -c "import tsid" >/dev/null 2>&1; then
  echo "building tsid from its source distribution against pin 4.1 (a few minutes)..."
  if ! "$VENV/bin/python" -m pip install -q --no-binary tsid "tsid==1.10.*"; then
    echo "tsid could not be built here; the TSID column of the benchmark is unavailable" >&2
    exit 3
  fi
fi
exec "$VENV/bin/python" "$ROOT/benchmarks/peers/tsid_tick.py" "$@"
