# graftal — common tasks. `make example` and `make test` are the two
# commands the README promises on a fresh machine.

CARGO ?= cargo
OUT ?= out
# Where cargo puts binaries (respects CARGO_TARGET_DIR).
TARGET_DIR ?= $(or $(CARGO_TARGET_DIR),target)
GLTF_VALIDATOR_DIR ?= $(CURDIR)/target/gltf-validator
THREE_DIR ?= $(CURDIR)/target/three

.PHONY: example test unit doc-test examples validate-gltf lint bench bench-peers bench-scaling contact-sheet test-slurm test-blender test-qhull test-boolean test-compressed-gltf fuzz fuzz-smoke clean

## Run the main job on the bundled chair example: writes out/chair.glb and out/chair.json.
example:
	mkdir -p $(OUT)
	$(CARGO) run --release --quiet -- run rules/chair.toml -o $(OUT)/chair.glb --stats $(OUT)/chair.json
	@echo "example written to $(OUT)/chair.glb (stats: $(OUT)/chair.json)"

## The whole test suite: unit + integration tests, doc tests, every example
## rule file through the Khronos glTF validator and three.js's GLTFLoader.
test: unit doc-test validate-gltf

unit:
	$(CARGO) nextest run --all-targets --no-fail-fast

doc-test:
	$(CARGO) test --doc --quiet

## Run every example in rules/ to GLB and validate the files with the Khronos validator.
examples:
	$(CARGO) build --quiet
	mkdir -p $(OUT)/examples
	for f in rules/*.toml rules/*.ron; do \
		name=$$(basename $${f%.*}); \
		$(TARGET_DIR)/debug/graftal run $$f -o $(OUT)/examples/$$name.glb --stats $(OUT)/examples/$$name.json || exit 1; \
	done

validate-gltf: examples
	@test -d $(GLTF_VALIDATOR_DIR)/node_modules/gltf-validator || \
		npm install --silent --no-audit --no-fund --prefix $(GLTF_VALIDATOR_DIR) gltf-validator@2.0.0-dev.3.10
	NODE_PATH=$(GLTF_VALIDATOR_DIR)/node_modules node tests/validate_gltf.mjs --strict $(OUT)/examples/*.glb
	@test -d $(THREE_DIR)/node_modules/three || \
		npm install --silent --no-audit --no-fund --prefix $(THREE_DIR) three@0.170.0
	NODE_PATH=$(THREE_DIR)/node_modules node tests/load_three.mjs $(OUT)/examples/*.glb

lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --all-targets -- -D warnings

## The README's picture of every example (docs/examples.png): one shaded
## thumbnail per rule file, rendered by `graftal preview`.
contact-sheet:
	$(CARGO) build --release --quiet
	$(TARGET_DIR)/release/graftal preview rules/*.toml rules/*.ron -o docs/examples.png --size 160

## The README's Slurm recipe (job array + dependent merge, then a cancelled
## task and its retry) on a real single-node Slurm started on localhost;
## merged manifest and meshes compared byte for byte with an unsharded run.
## Root on Debian 12: installs slurm-wlm and munge with apt-get when missing,
## keeps every config, key, log and daemon in a temporary directory, stops
## the daemons afterwards. ~15 s (+ ~10 s the first time, for apt-get).
## Not part of `make test`; CI (`.ci/run`) runs it after. KEEP_STATE=1 keeps the directory.
test-slurm:
	$(CARGO) build --release --quiet
	GRAFTAL=$(TARGET_DIR)/release/graftal tests/slurm/run.sh

## Modelling operators against Blender 3.4 (tests/blender/run.sh): each
## tests/blender/*.py runs in `blender -b` and compares graftal's output
## with Blender's (subdivide: the subdivision-surface modifier, OpenSubdiv).
## Installs Blender with apt-get when missing (~1 min). Not part of
## `make test`; CI (`.ci/run`) runs it after.
test-blender:
	$(CARGO) build --release --quiet
	GRAFTAL=$(TARGET_DIR)/release/graftal tests/blender/run.sh

## Compressed glTF from real tools (tests/compressed/run.sh): gltfpack's
## default, -c and -cc (KHR_mesh_quantization, EXT_meshopt_compression) and
## gltf-pipeline -d (KHR_draco_mesh_compression) on seven examples, read
## back within the quantisation step. Installs both from npm under target/
## the first time (~20 s). Not part of `make test`; CI (`.ci/run`) runs it after.
test-compressed-gltf:
	$(CARGO) build --release --quiet
	GRAFTAL=$(TARGET_DIR)/release/graftal tests/compressed/run.sh

## `convex_hull` against qhull (tests/qhull/run.sh: scipy.spatial.ConvexHull
## on 10^4-10^5 random points and degenerate sets; a Python venv with numpy
## and scipy from PyPI is made under target/ the first time, ~30 s). Not
## part of `make test`; CI (`.ci/run`) runs it after.
test-qhull:
	$(CARGO) build --release --quiet
	GRAFTAL=$(TARGET_DIR)/release/graftal tests/qhull/run.sh

## `boolean` against manifold3d (tests/boolean/run.sh: union, difference and
## intersection of 100 random pairs of cubes, boxes and spheres, overlapping,
## disjoint or nested, and of coplanar cubes, which may be refused: volume to
## 1e-9, closed and edge-manifold, components and genus; a Python venv with
## numpy and manifold3d from PyPI is made under target/ the first time,
## ~20 s). Not part of `make test`; CI (`.ci/run`) runs it after.
test-boolean:
	$(CARGO) build --release --quiet
	GRAFTAL=$(TARGET_DIR)/release/graftal tests/boolean/run.sh

## Fuzz smoke (fuzz/smoke.sh): builds the libFuzzer targets (cargo-fuzz on
## stable, RUSTC_BOOTSTRAP=1), replays every committed regression and seed of
## each target, then fuzzes each SMOKE_SECONDS (default 20); fails on any
## crash, timeout or out-of-memory input. Scratch corpus, logs and failing
## inputs in $(TARGET_DIR)/fuzz-smoke. Not part of `make test`; CI (`.ci/run`)
## runs it after. ~8 min on 2 cores from a cold build, 6.5 of them building
## (see fuzz/README.md).
fuzz-smoke:
	fuzz/smoke.sh

## Longer fuzzing, not part of CI (fuzz/fuzz.sh): every target FUZZ_SECONDS
## (default 60), growing fuzz/corpus/.
fuzz:
	fuzz/fuzz.sh

## Criterion benchmarks (release).
bench:
	$(CARGO) bench

## Peer benchmarks, not part of CI: graftal beside Blender's bmesh, libigl,
## trimesh, CGAL, geomdl, splinepy and curvo on the same inputs (median table
## in target/bench-peers/results.md). Installs its peers under
## target/bench-peers (venv, apt Blender); ~10 min. Options go in
## BENCH_PEERS_ARGS, e.g. "--runs 3 --only merge,glb --with-occt" (see bench-peers/README.md).
bench-peers:
	$(CARGO) build --release --quiet
	GRAFTAL=$(TARGET_DIR)/release/graftal python3 bench-peers/run.py $(BENCH_PEERS_ARGS)

## Time per element of the kernel operators, the import weld, the merge step
## and the G³ engine at 10⁴, 10⁵ and 10⁶ elements, plus peak memory per
## primitive (table in target/bench-scaling/scaling.md); standard-library
## Python only, ~3 min. Not part of CI.
bench-scaling:
	$(CARGO) build --release --quiet
	GRAFTAL=$(TARGET_DIR)/release/graftal python3 bench-peers/scaling.py $(BENCH_SCALING_ARGS)

clean:
	rm -rf $(OUT)
