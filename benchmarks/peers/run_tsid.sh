#!/usr/bin/env bash
# TSID peer of benchmarks/bench_wbc.py, in its own environment (.venv-tsid), never in .venv.
#
# The tsid 1.10 binary wheel crashes with pin 4.1 (a binding build mismatch); built from source
# against the installed pin it works. benchmarks/peers/setup.sh builds that environment (long);
# this script makes it if needed, then ticks TSID on the same Talos task as bench_wbc.py.
# Usage: bash benchmarks/peers/run_tsid.sh [--ticks 3000] [--json out.json]
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
VENV="$ROOT/.venv-tsid"
if ! "$VENV/bin/python" -c "import tsid" >/dev/null 2>&1; then
  bash "$HERE/setup.sh" tsid || { echo "TSID could not be installed here: the TSID column is unavailable" >&2; exit 3; }
fi
exec "$VENV/bin/python" "$HERE/tsid_tick.py" "$@"
