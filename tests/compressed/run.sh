#!/usr/bin/env bash
# graftal reads what common glTF tools write (issue 39): every listed
# example is written as GLB by graftal, rewritten by gltfpack (its default
# KHR_mesh_quantization; -c and -cc, EXT_meshopt_compression) and by
# gltf-pipeline -d (KHR_draco_mesh_compression), and read back by
# `graftal convert`; compare.py checks the result against the original to
# the quantisation step (`make test-compressed-gltf`; CI runs it after
# `make test`). Installs gltfpack and gltf-pipeline from npm under the
# target folder the first time (~20 s). Work files go to a temporary
# folder, removed afterwards unless KEEP_STATE=1. Exits 1 on a mismatch.
#
#   GRAFTAL=target/release/graftal tests/compressed/run.sh
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$(dirname "$here")")
GRAFTAL=$(realpath "${GRAFTAL:?set GRAFTAL to the graftal binary}")
tools=${COMPRESSED_TOOLS_DIR:-${CARGO_TARGET_DIR:-$root/target}/compressed-tools}
work=$(mktemp -d "${TMPDIR:-/tmp}/graftal-compressed.XXXXXX")
[ "${KEEP_STATE:-0}" = 1 ] || trap 'rm -rf "$work"' EXIT

if [ ! -x "$tools/node_modules/.bin/gltfpack" ] || [ ! -x "$tools/node_modules/.bin/gltf-pipeline" ]; then
    echo "== installing gltfpack and gltf-pipeline under $tools (npm)"
    npm install --silent --no-audit --no-fund --prefix "$tools" gltfpack@1.3.0 gltf-pipeline@4.3.1
fi
# Blender's glTF importer needs numpy in the Python Blender runs (Debian's
# Blender uses the system one); Blender itself is installed by
# `make test-blender`, which CI runs first. Without Blender that part is
# skipped (and said).
# (`--python-exit-code`: without it Blender exits 0 when the expression
# fails, and the check would never install anything.)
if command -v blender >/dev/null && ! blender -b --factory-startup --python-exit-code 1 --python-expr "import numpy" >/dev/null 2>&1; then
    echo "== installing python3-numpy for Blender's glTF importer (apt-get)"
    sudo=$([ "$(id -u)" -eq 0 ] && echo "" || echo sudo)
    install() { $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-numpy >"$work/apt.log" 2>&1; }
    install || { $sudo apt-get update -qq >>"$work/apt.log" 2>&1 && install; } ||
        { cat "$work/apt.log" >&2; echo "apt-get install python3-numpy failed" >&2; exit 1; }
fi
python3 "$here/compare.py" "$GRAFTAL" "$tools/node_modules/.bin" "$root/rules" "$work"
