#!/usr/bin/env bash
# graftal's `convex_hull` against qhull (scipy.spatial.ConvexHull), the
# reference implementation (`make test-qhull`; CI runs it after `make
# test`). Makes a Python virtual environment with numpy and scipy from
# PyPI under the target folder the first time (~30 s), then runs hull.py
# with the graftal binary given in $GRAFTAL. Work files go to a temporary
# folder, removed afterwards unless KEEP_STATE=1. Exits 1 on a mismatch.
#
#   GRAFTAL=target/release/graftal tests/qhull/run.sh
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$(dirname "$here")")
GRAFTAL=$(realpath "${GRAFTAL:?set GRAFTAL to the graftal binary}")
venv=${QHULL_VENV:-${CARGO_TARGET_DIR:-$root/target}/qhull-venv}
work=$(mktemp -d "${TMPDIR:-/tmp}/graftal-qhull.XXXXXX")
[ "${KEEP_STATE:-0}" = 1 ] || trap 'rm -rf "$work"' EXIT

if ! "$venv/bin/python" -c "import scipy, numpy" 2>/dev/null; then
    echo "== making $venv (numpy, scipy from PyPI)"
    python3 -m venv "$venv" >"$work/venv.log" 2>&1 ||
        { cat "$work/venv.log" >&2; echo "python3 -m venv failed (apt-get install python3-venv)" >&2; exit 1; }
    "$venv/bin/pip" install --quiet numpy==2.2.6 scipy==1.15.3 >>"$work/venv.log" 2>&1 ||
        { cat "$work/venv.log" >&2; echo "pip install numpy scipy failed" >&2; exit 1; }
fi
"$venv/bin/python" "$here/hull.py" "$GRAFTAL" "$work"
