#!/usr/bin/env bash
# Builds the fuzz targets and runs each for a while (libFuzzer through
# cargo-fuzz, on the stable toolchain with RUSTC_BOOTSTRAP=1). See README.md.
#
#   fuzz/fuzz.sh                     # every target, 60 s each (`make fuzz`)
#   FUZZ_SECONDS=600 fuzz/fuzz.sh rules_run mesh_ply
#
# Environment: FUZZ_SECONDS (per target, default 60), FUZZ_NICE (niceness of
# the fuzzers, default 19; empty for none), FUZZ_TARGET_DIR (cargo target
# dir, default fuzz/target), FUZZ_ARGS (more libFuzzer flags).
# Exits 1 when any target found a crash, timeout or out-of-memory input
# (written to fuzz/artifacts/TARGET/); prints one line of numbers per target.
set -euo pipefail
cd "$(dirname "$0")"

# shellcheck source-path=SCRIPTDIR source=targets.sh
. ./targets.sh
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=("${ALL_TARGETS[@]}")
seconds=${FUZZ_SECONDS:-60}
nice_level=${FUZZ_NICE-19}
target_dir=${FUZZ_TARGET_DIR:-target}

# cargo-fuzz passes -Zsanitizer/-Cpasses flags that stable rustc accepts only
# with RUSTC_BOOTSTRAP=1. graftal has no unsafe code: no sanitizer (-s none),
# but debug assertions and overflow checks stay on (cargo-fuzz's default).
export RUSTC_BOOTSTRAP=1
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
cargo fuzz build -s none --target-dir "$target_dir"

# Seeds (committed), regressions (every input that once failed: replayed
# first), and the growing corpus (not committed; libFuzzer writes only to
# the first folder it is given).
run=()
[ -z "$nice_level" ] || run=(nice -n "$nice_level")
failed=()
summary=()
for t in "${targets[@]}"; do
    s=$(seeds_of "$t")
    mkdir -p "corpus/$t" "artifacts/$t" "seeds/$s" "regressions/$s"
    log="artifacts/$t/last-run.log"
    echo "== $t: ${seconds}s"
    # shellcheck disable=SC2046,SC2086
    if "${run[@]}" cargo fuzz run -s none --target-dir "$target_dir" "$t" \
        "corpus/$t" "seeds/$s" "regressions/$s" -- \
        -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 \
        -print_final_stats=1 $(dict_of "$t") ${FUZZ_ARGS:-} >"$log" 2>&1; then
        status=ok
    else
        status=FAILED
        failed+=("$t")
        grep -E -A8 "panicked at|ERROR: libFuzzer|SUMMARY" "$log" | head -30 || true
    fi
    last=$(grep -E '^#[0-9]+' "$log" | tail -1 || true)
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
    rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")
    cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
    ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
    corp=$(find "corpus/$t" -type f | wc -l)
    line=$(printf '%-14s %-6s execs=%-10s exec/s=%-7s cov=%-6s ft=%-7s corpus=%s' \
        "$t" "$status" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" "$corp")
    echo "$line"
    summary+=("$line")
done

echo "== summary (${seconds}s per target; logs in fuzz/artifacts/TARGET/last-run.log)"
printf '%s\n' "${summary[@]}"
if [ ${#failed[@]} -gt 0 ]; then
    echo "FAILED: ${failed[*]} (inputs in fuzz/artifacts/; see fuzz/README.md to reproduce)"
    exit 1
fi
