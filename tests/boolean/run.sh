#!/usr/bin/env bash
# graftal's `boolean` against manifold3d (Manifold's mesh booleans from
# PyPI), the reference (`make test-boolean`). Makes a Python virtual
# environment with numpy and manifold3d under the target folder the first
# time (~20 s), then runs oracle.py with the graftal binary given in
# $GRAFTAL: 100 random pairs of closed meshes, 100 random pairs of boxes on a
# lattice (touching, coplanar) and hand-made touching contacts,
# union, difference and intersection. Work files go to a temporary folder,
# removed afterwards unless KEEP_STATE=1. Arguments go to oracle.py (a
# FILTER: only the cases whose name contains it). Exits 1 on a mismatch.
#
#   GRAFTAL=target/release/graftal tests/boolean/run.sh [FILTER]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$(dirname "$here")")
GRAFTAL=$(realpath "${GRAFTAL:?set GRAFTAL to the graftal binary}")
venv=${BOOLEAN_VENV:-${CARGO_TARGET_DIR:-$root/target}/boolean-venv}
work=$(mktemp -d "${TMPDIR:-/tmp}/graftal-boolean.XXXXXX")
[ "${KEEP_STATE:-0}" = 1 ] || trap 'rm -rf "$work"' EXIT

if ! "$venv/bin/python" -c "import manifold3d, numpy" 2>/dev/null; then
    echo "== making $venv (numpy, manifold3d from PyPI)"
    python3 -m venv "$venv" >"$work/venv.log" 2>&1 ||
        { cat "$work/venv.log" >&2; echo "python3 -m venv failed (apt-get install python3-venv)" >&2; exit 1; }
    "$venv/bin/pip" install --quiet numpy==2.2.6 manifold3d==3.5.4 >>"$work/venv.log" 2>&1 ||
        { cat "$work/venv.log" >&2; echo "pip install numpy manifold3d failed" >&2; exit 1; }
fi
"$venv/bin/python" "$here/oracle.py" "$GRAFTAL" "$work" "$@"
