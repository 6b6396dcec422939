#!/usr/bin/env bash
# Fuzz smoke, for CI (`make fuzz-smoke`; .ci/run runs it after `make test`).
# Builds the libFuzzer targets (cargo-fuzz on the stable toolchain with
# RUSTC_BOOTSTRAP=1, no sanitizer: see README.md), then, for every target:
#   1. replay: every committed input of the target, regressions/ and
#      seeds/, runs once (libFuzzer -runs=0); any crash fails the smoke;
#   2. fuzz: SMOKE_SECONDS (default 20) of fuzzing from those inputs,
#      with a fixed random seed (SMOKE_SEED, default 1), so that a run on
#      the same commit explores the same inputs in the same order (how far
#      it gets in the time still depends on the machine).
# Targets run side by side, one a core (libFuzzer uses one each).
# The committed inputs are read only: libFuzzer writes new inputs to the
# first folder it is given only, here a scratch corpus under target/, and
# the script fails if anything under seeds/ or regressions/ changed.
#
#   fuzz/smoke.sh                                   # every target
#   SMOKE_SECONDS=5 fuzz/smoke.sh rules_compile error_render
#
# Environment: SMOKE_SECONDS; SMOKE_SEED; SMOKE_JOBS (targets at a time, default
# nproc); SMOKE_DIR (scratch: corpus/, artifacts/, logs/; default
# $CARGO_TARGET_DIR/fuzz-smoke, else target/fuzz-smoke; emptied first);
# FUZZ_TARGET_DIR (cargo target dir of the fuzz crate, default fuzz/target,
# shared with fuzz.sh); FUZZ_NICE (niceness of the fuzzers, default 19;
# empty for none); FUZZ_ARGS (more libFuzzer flags, fuzz phase only).
# Exits 1 when a target crashed, timed out (> 10 s for one input) or needed
# more than 2 GiB, the input in SMOKE_DIR/artifacts/TARGET/; prints a line
# per target and phase (inputs or executions, exec/s, cov, ft, peak RSS)
# and the time of each phase.
set -euo pipefail
start_dir=$PWD
fuzz_dir=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$fuzz_dir")
cd "$fuzz_dir"
# shellcheck source-path=SCRIPTDIR source=targets.sh
. ./targets.sh

# An absolute path: $1 as given, or relative to where the script started.
absolute() {
    case $1 in
        /*) echo "$1" ;;
        *) echo "$start_dir/$1" ;;
    esac
}

targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=("${ALL_TARGETS[@]}")
seconds=${SMOKE_SECONDS:-20}
seed=${SMOKE_SEED:-1}
nice_level=${FUZZ_NICE-19}
target_dir=$(absolute "${FUZZ_TARGET_DIR:-$fuzz_dir/target}")
if [ -n "${SMOKE_DIR:-}" ]; then
    scratch=$(absolute "$SMOKE_DIR")
elif [ -n "${CARGO_TARGET_DIR:-}" ]; then
    scratch=$(absolute "$CARGO_TARGET_DIR")/fuzz-smoke
else
    scratch=$root/target/fuzz-smoke
fi
rm -rf "$scratch/corpus" "$scratch/artifacts" "$scratch/logs"
mkdir -p "$scratch/corpus" "$scratch/artifacts" "$scratch/logs"

run=()
[ -z "$nice_level" ] || run=(nice -n "$nice_level")
limits=(-rss_limit_mb=2048 -timeout=10)

echo "== fuzz smoke: build (cargo fuzz build -s none)"
export RUSTC_BOOTSTRAP=1
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
began=$SECONDS
cargo fuzz build -s none --target-dir "$target_dir"
build_time=$((SECONDS - began))
bins=$(bin_dir "$target_dir")

# Nothing may write to the committed inputs: checked at the end.
stamp=$scratch/logs/started
touch "$stamp"
committed_before=$(find seeds regressions -type f | wc -l)

# The committed inputs of a target: regressions first, then seeds.
inputs_of() {
    local s d
    s=$(seeds_of "$1")
    for d in "regressions/$s" "seeds/$s"; do
        [ -d "$d" ] && echo "$d"
    done
}

# What a failed run left: the panic or libFuzzer's report, the failing
# input, and the committed file with the same content (for a replay).
explain_failure() {
    local t=$1 log=$2 artifact sha
    grep -E -A8 "panicked at|ERROR: libFuzzer|SUMMARY" "$log" | head -30 | cut -c1-300 || true
    for artifact in "$scratch/artifacts/$t"/*; do
        [ -f "$artifact" ] || continue
        case $(basename "$artifact") in slow-unit-*) continue ;; esac
        echo "   input: $artifact"
        sha=${artifact##*-}
        while read -r d; do
            find "$d" -type f -exec sha1sum {} + | awk -v s="$sha" '$1 == s { print "   = fuzz/" $2 }'
        done < <(inputs_of "$t")
    done
}

# One target, both phases; what it prints is collected and shown at once
# when it ends (targets run side by side). Files in logs/: TARGET.lines
# (the summary lines), TARGET.failed (the failed phases, if any),
# TARGET.times (seconds of replay and fuzz).
smoke_one() {
    local t=$1 inputs corpus artifacts log count began status inited cov ft
    local last execs rate rss replay_took fuzz_took=0 out lines=()
    mapfile -t inputs < <(inputs_of "$t")
    corpus=$scratch/corpus/$t
    artifacts=$scratch/artifacts/$t/
    out=$scratch/logs/$t
    mkdir -p "$corpus" "$artifacts"
    : >"$out.failed"

    # 1. Replay: each committed input once; the scratch corpus (empty)
    # first, so that it is the only folder libFuzzer could write to.
    log=$scratch/logs/$t-replay.log
    count=$(find "${inputs[@]}" -type f | wc -l)
    began=$SECONDS
    if "${run[@]}" "$bins/$t" -runs=0 "${limits[@]}" -artifact_prefix="$artifacts" \
        "$corpus" "${inputs[@]}" >"$log" 2>&1; then
        status=ok
    else
        status=FAILED
        echo "$t (replay)" >>"$out.failed"
        explain_failure "$t" "$log" >"$out.explain"
    fi
    replay_took=$((SECONDS - began))
    inited=$(grep -E '^#[0-9]+[[:space:]]+INITED' "$log" | tail -1 || true)
    cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$inited")
    ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$inited")
    lines+=("$(printf '%-14s replay %-6s inputs=%-5s time=%ss cov=%-6s ft=%s' \
        "$t" "$status" "$count" "$replay_took" "${cov:-?}" "${ft:-?}")")

    # 2. Fuzz, from the committed inputs, into the scratch corpus.
    if [ "$status" = ok ]; then
        log=$scratch/logs/$t-fuzz.log
        began=$SECONDS
        # shellcheck disable=SC2046,SC2086
        if "${run[@]}" "$bins/$t" -max_total_time="$seconds" -seed="$seed" "${limits[@]}" \
            -print_final_stats=1 -artifact_prefix="$artifacts" $(dict_of "$t") ${FUZZ_ARGS:-} \
            "$corpus" "${inputs[@]}" >"$log" 2>&1; then
            status=ok
        else
            status=FAILED
            echo "$t (fuzz)" >>"$out.failed"
            explain_failure "$t" "$log" >"$out.explain"
        fi
        fuzz_took=$((SECONDS - began))
        last=$(grep -E '^#[0-9]+' "$log" | tail -1 || true)
        execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
        rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")
        rss=$(sed -n 's/^stat::peak_rss_mb: *//p' "$log")
        cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
        ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
        lines+=("$(printf '%-14s fuzz   %-6s execs=%-9s exec/s=%-6s cov=%-6s ft=%-6s corpus=%-5s rss=%sMB' \
            "$t" "$status" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" \
            "$(find "$corpus" -type f | wc -l)" "${rss:-?}")")
    fi
    printf '%s\n' "${lines[@]}" >"$out.lines"
    echo "$replay_took $fuzz_took" >"$out.times"
    # Shown together, so that side-by-side targets do not interleave.
    cat "$out.lines" "$out.explain" 2>/dev/null || true
}

# Side by side, SMOKE_JOBS at a time (default: the number of cores).
jobs_at_once=${SMOKE_JOBS:-$(nproc)}
began=$SECONDS
for t in "${targets[@]}"; do
    while [ "$(jobs -rp | wc -l)" -ge "$jobs_at_once" ]; do
        wait -n || true
    done
    smoke_one "$t" &
done
wait
targets_time=$((SECONDS - began))

failed=()
summary=()
replay_time=0
fuzz_time=0
for t in "${targets[@]}"; do
    out=$scratch/logs/$t
    if [ ! -f "$out.times" ]; then
        failed+=("$t (did not finish)")
        continue
    fi
    mapfile -t -O "${#summary[@]}" summary <"$out.lines"
    mapfile -t -O "${#failed[@]}" failed <"$out.failed"
    read -r r f <"$out.times"
    replay_time=$((replay_time + r))
    fuzz_time=$((fuzz_time + f))
done

changed=$(find seeds regressions -type f -newer "$stamp")
if [ -n "$changed" ] || [ "$(find seeds regressions -type f | wc -l)" != "$committed_before" ]; then
    echo "the committed inputs changed during the smoke:"
    echo "${changed:-(files added or removed)}"
    failed+=("committed inputs")
fi

echo "== fuzz smoke summary: build ${build_time}s; targets ${targets_time}s," \
    "$jobs_at_once at a time (replay ${replay_time}s + fuzz ${fuzz_time}s in all," \
    "${seconds}s per target); logs and failing inputs in $scratch"
printf '%s\n' "${summary[@]}"
if [ ${#failed[@]} -gt 0 ]; then
    echo "FAILED: ${failed[*]}"
    echo "Reproduce: cd fuzz && RUSTC_BOOTSTRAP=1 cargo fuzz run -s none TARGET INPUT (see fuzz/README.md)"
    exit 1
fi
