#!/usr/bin/env bash
# graftal's modelling operators against Blender 3.4 run in the background
# (`make test-blender`; CI runs it after `make test`): installs Blender from
# Debian with apt-get when it is missing, then runs each oracle script of
# tests/blender/ (not _common.py, which they import) inside `blender -b`
# with the graftal binary given in
# $GRAFTAL. Work files go to a temporary folder, removed afterwards unless
# KEEP_STATE=1. Exits 1 when any script reports a mismatch.
#
#   GRAFTAL=target/release/graftal tests/blender/run.sh
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
GRAFTAL=$(realpath "${GRAFTAL:?set GRAFTAL to the graftal binary}")
work=$(mktemp -d "${TMPDIR:-/tmp}/graftal-blender.XXXXXX")
[ "${KEEP_STATE:-0}" = 1 ] || trap 'rm -rf "$work"' EXIT

if ! command -v blender >/dev/null; then
    echo "== installing Blender (apt-get install blender)"
    sudo=$([ "$(id -u)" -eq 0 ] && echo "" || echo sudo)
    install() { $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq blender >"$work/apt.log" 2>&1; }
    install || { $sudo apt-get update -qq >>"$work/apt.log" 2>&1 && install; } ||
        { cat "$work/apt.log" >&2; echo "apt-get install blender failed" >&2; exit 1; }
fi
blender --version | head -1

status=0
for script in "$here"/[!_]*.py; do
    name=$(basename "$script" .py)
    echo "== $name (Blender oracle)"
    # Blender prints its own banner and "Blender quit"; the script's lines
    # are the ones that matter.
    if ! blender -b --factory-startup --python-exit-code 1 --python "$script" -- \
        "$GRAFTAL" "$work/$name" >"$work/$name.log" 2>&1; then
        status=1
    fi
    grep -vE '^(Blender [0-9]|Read prefs|Blender quit|$)' "$work/$name.log" || true
done
exit $status
