#!/usr/bin/env bash
# Test the README's Slurm recipe against a real single-node Slurm on this host.
#
#   tests/slurm/run.sh                      # the whole test (root, Debian 12)
#   tests/slurm/run.sh --extract NAME FILE  # print the recipe block NAME of FILE
#
# The recipe is read from RECIPE_FILE (README.md by default), so the doc and
# the test cannot drift. A recipe is a fenced code block directly preceded by
# a line `<!-- recipe: NAME -->`. A recipe whose name looks like a file
# (`chairs.sbatch`) is saved under that name in the job's working directory;
# the others (`slurm-submit`, `slurm-retry`) are run there with `sh -e`.
#
# What it does: installs slurm-wlm and munge with apt-get when missing, starts
# a private munged, slurmctld and slurmd whose config, key, sockets, logs and
# state all live in one temporary directory (no /etc/slurm, no /etc/munge, no
# cgroups), then
#   1. runs the submit recipe (shard array + dependent merge) and checks that
#      the merged manifest and every mesh are byte-identical to an unsharded
#      run of the same command;
#   2. submits again, cancels one array task before it runs, checks that
#      Slurm cancels the merge (rather than leaving it pending forever), runs
#      the retry recipe and checks byte identity again.
# Every daemon is stopped by its PID on exit, also on failure.
#
# Environment (defaults in brackets):
#   GRAFTAL        graftal binary to test [REPO/target/release/graftal]
#   RECIPE_FILE    Markdown file holding the recipe blocks [REPO/README.md]
#   SHARD_RECIPE, MERGE_RECIPE  batch-script recipes [chairs.sbatch, merge.sbatch]
#   SUBMIT_RECIPE, RETRY_RECIPE shell recipes [slurm-submit, slurm-retry]
#   FAIL_TASK      array task to cancel; must be the one the retry recipe reruns [1]
#   OUT_DIR        output directory the recipe writes, compared with the
#                  reference [out]; the merged manifest is OUT_DIR/manifest.json
#   REF_CMD        unsharded reference command [the recipe's `graftal run`
#                  line without --shard and -j]
#   JOB_TIMEOUT    seconds to wait for each group of jobs [180]
#   START_TIMEOUT  seconds to wait for the daemons [60]
#   KEEP_STATE=1   keep the temporary directory (configs, logs, outputs)
set -euo pipefail

# Print the body of the fenced block directly after `<!-- recipe: NAME -->`.
# Exit 1 when there is no such block, 2 when NAME names two blocks.
extract_recipe() {
    local name=$1 file=$2
    awk -v name="$name" -v file="$file" '
        BEGIN { found = 0; armed = 0; fence = "" }
        fence != "" {
            line = $0
            sub(/^[ \t]+/, "", line)
            if (index(line, fence) == 1 && line ~ /^(`+|~+)[ \t]*$/ && length(line) >= length(fence)) {
                fence = ""
                next
            }
            # Drop the fence line indentation, as Markdown does.
            if (indent > 0 && substr($0, 1, indent) ~ /^ *$/) print substr($0, indent + 1)
            else print
            next
        }
        armed {
            armed = 0
            if (match($0, /^ *(```+|~~~+)/)) {
                opener = substr($0, RSTART, RLENGTH)
                indent = opener; sub(/[`~]+$/, "", indent); indent = length(indent)
                fence = substr(opener, indent + 1)
                if (++found > 1) { printf "%s: recipe %s appears twice\n", file, name > "/dev/stderr"; exit 2 }
                next
            }
        }
        /^[ \t]*<!--[ \t]*recipe:/ {
            s = $0
            sub(/^[ \t]*<!--[ \t]*recipe:[ \t]*/, "", s)
            sub(/[ \t]*-->[ \t]*$/, "", s)
            armed = (s == name)
        }
        END {
            if (found > 1) exit 2
            if (found == 0) { printf "%s: no recipe %s (a fenced block right after <!-- recipe: %s -->)\n", file, name, name > "/dev/stderr"; exit 1 }
        }
    ' "$file"
}

case ${1:-} in
--extract)
    [[ $# -eq 3 ]] || { echo "usage: $0 --extract NAME FILE" >&2; exit 2; }
    extract_recipe "$2" "$3"
    exit
    ;;
-h | --help)
    sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "$0"
    exit
    ;;
"") ;;
*)
    echo "usage: $0 [--extract NAME FILE]" >&2
    exit 2
    ;;
esac

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
GRAFTAL=${GRAFTAL:-$REPO/target/release/graftal}
RECIPE_FILE=${RECIPE_FILE:-$REPO/README.md}
SHARD_RECIPE=${SHARD_RECIPE:-chairs.sbatch}
MERGE_RECIPE=${MERGE_RECIPE:-merge.sbatch}
SUBMIT_RECIPE=${SUBMIT_RECIPE:-slurm-submit}
RETRY_RECIPE=${RETRY_RECIPE:-slurm-retry}
FAIL_TASK=${FAIL_TASK:-1}
OUT_DIR=${OUT_DIR:-out}
JOB_TIMEOUT=${JOB_TIMEOUT:-180}
START_TIMEOUT=${START_TIMEOUT:-60}
KEEP_STATE=${KEEP_STATE:-0}
# The daemons live in sbin, which a non-login root shell may not have.
PATH=$PATH:/usr/sbin:/sbin
# Inside a real Slurm job (or a shell with SBATCH_* defaults) these would
# steer our sbatch calls and jobs; only SLURM_CONF, set below, may pass.
while read -r var; do
    unset "$var"
done < <(compgen -e | grep -E '^(SLURM|SBATCH|SALLOC|SRUN)_' || true)

log() { printf '[%3ds] %s\n' "$SECONDS" "$*"; }
indent() { sed 's/^/    /'; }
die() {
    printf '[%3ds] FAIL: %s\n' "$SECONDS" "$*" >&2
    exit 1
}

[[ $(id -u) -eq 0 ]] || die "run as root: slurmd must start jobs and apt-get may have to install Slurm"
[[ -x $GRAFTAL ]] || die "no graftal binary at $GRAFTAL (set GRAFTAL)"
[[ -r $RECIPE_FILE ]] || die "no recipe file $RECIPE_FILE (set RECIPE_FILE)"
GRAFTAL=$(cd "$(dirname "$GRAFTAL")" && pwd)/$(basename "$GRAFTAL")
RECIPE_FILE=$(cd "$(dirname "$RECIPE_FILE")" && pwd)/$(basename "$RECIPE_FILE")

# Read every recipe up front: a missing block should fail before any daemon starts.
shard_script=$(extract_recipe "$SHARD_RECIPE" "$RECIPE_FILE")
merge_script=$(extract_recipe "$MERGE_RECIPE" "$RECIPE_FILE")
submit_script=$(extract_recipe "$SUBMIT_RECIPE" "$RECIPE_FILE")
retry_script=$(extract_recipe "$RETRY_RECIPE" "$RECIPE_FILE")
if [[ -z ${REF_CMD:-} ]]; then
    # The unsharded equivalent of the shard script's `graftal run` line: the
    # same batch and output template, so the manifest must come out the same.
    REF_CMD=$(grep -m1 -E '(^|[[:space:];])graftal[[:space:]]+run[[:space:]]' <<<"$shard_script" |
        sed -E -e 's/^[[:space:]]*(exec|srun)[[:space:]]+//' \
            -e "s/[[:space:]]--shard(=|[[:space:]]+)(\"[^\"]*\"|'[^']*'|[^[:space:]]+)//" \
            -e "s/[[:space:]](-j|--jobs)(=|[[:space:]]+)(\"[^\"]*\"|'[^']*'|[^[:space:]]+)//") ||
        die "no 'graftal run' line in recipe $SHARD_RECIPE (set REF_CMD)"
fi

STATE=$(mktemp -d "${TMPDIR:-/tmp}/graftal-slurm.XXXX")
# munged refuses a socket unless every directory on its path is searchable
# by all ("Socket is inaccessible"); mktemp -d makes 0700.
chmod 0755 "$STATE"
MUNGED_PID='' CTLD_PID='' SLURMD_PID=''

# Stop a daemon we started: TERM, up to 10 s, then KILL.
stop_pid() {
    local name=$1 pid=$2 i
    [[ -n $pid ]] && kill -0 "$pid" 2>/dev/null || return 0
    kill -TERM "$pid" 2>/dev/null || true
    for ((i = 0; i < 20; i++)); do
        kill -0 "$pid" 2>/dev/null || break
        sleep 0.5
    done
    if kill -0 "$pid" 2>/dev/null; then
        log "$name (pid $pid) ignored SIGTERM; killing it"
        kill -KILL "$pid" 2>/dev/null || true
    fi
    wait "$pid" 2>/dev/null || true
}

cleanup() {
    local rc=$? ids f i
    set +e
    trap - EXIT INT TERM
    if [[ -n $CTLD_PID ]] && kill -0 "$CTLD_PID" 2>/dev/null; then
        # Jobs run under slurmstepd, which slurmd does not own: cancel them
        # through Slurm so nothing outlives the test. The cluster is ours alone.
        ids=$(squeue -h -o %A 2>/dev/null)
        if [[ -n $ids ]]; then
            # shellcheck disable=SC2086 # one argument per job id
            scancel $ids 2>/dev/null
            for ((i = 0; i < 20; i++)); do
                [[ -z $(squeue -h -o %A 2>/dev/null) ]] && break
                sleep 0.5
            done
        fi
    fi
    stop_pid slurmd "$SLURMD_PID"
    stop_pid slurmctld "$CTLD_PID"
    stop_pid munged "$MUNGED_PID"
    if [[ $rc -ne 0 ]]; then
        for f in "$STATE"/*.log "$STATE"/*.stderr "$STATE"/work*/slurm-*.out; do
            [[ -s $f ]] || continue
            # A daemon's stderr repeats its log, unless it died before opening it.
            [[ $f == *.stderr && -s ${f%.stderr}.log ]] && continue
            echo "----- last lines of $f" >&2
            tail -n 25 "$f" >&2
        done
    fi
    if [[ $KEEP_STATE == 1 ]]; then
        log "state kept in $STATE"
    else
        rm -rf "$STATE"
    fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# ---------------------------------------------------------------- install
t0=$SECONDS
missing=0
for cmd in munged slurmctld slurmd sbatch; do
    command -v "$cmd" >/dev/null || missing=1
done
if [[ $missing -eq 1 ]]; then
    log "installing slurm-wlm and munge with apt-get"
    export DEBIAN_FRONTEND=noninteractive
    apt_install() {
        apt-get install -y -qq --no-install-recommends slurm-wlm munge >>"$STATE/apt.log" 2>&1
    }
    # Only refresh the package lists when the cached ones are too old to install from.
    apt_install || { apt-get update -qq >>"$STATE/apt.log" 2>&1 && apt_install; } ||
        { cat "$STATE/apt.log" >&2; die "apt-get install slurm-wlm munge failed"; }
fi
INSTALL_SECS=$((SECONDS - t0))
log "$(slurmctld -V), $(munged -V | awk '{print $1}') (install step ${INSTALL_SECS}s)"

# ---------------------------------------------------------------- daemons
# All three run in the foreground (-D, --foreground) as children of this
# script, so $! is the PID to stop. In the foreground munged logs to stderr
# (it ignores --log-file); slurmctld and slurmd write their LogFile and copy
# it to stderr, which only matters when they die before opening the log.
t_start=$SECONDS
port_in_use() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }
pick_port() {
    local p i
    for ((i = 0; i < 200; i++)); do
        p=$((20000 + RANDOM % 20000))
        [[ $p != "${1:-}" ]] && ! port_in_use "$p" && { echo "$p"; return; }
    done
    die "no free TCP port found"
}
# Wait up to SECS for COMMAND to succeed, failing early if daemon PID died.
wait_until() {
    local secs=$1 what=$2 pid=$3 deadline=$((SECONDS + $1))
    shift 3
    until "$@" >/dev/null 2>&1; do
        [[ -z $pid ]] || kill -0 "$pid" 2>/dev/null || die "$what: the daemon (pid $pid) exited"
        ((SECONDS < deadline)) || die "$what: not within ${secs}s"
        sleep 0.5
    done
}

mkdir -m 0755 "$STATE/munge"
MUNGE_SOCKET=$STATE/munge/munge.socket
if command -v mungekey >/dev/null; then
    mungekey --create --keyfile="$STATE/munge/munge.key"
else
    dd if=/dev/urandom of="$STATE/munge/munge.key" bs=1024 count=1 status=none
fi
chmod 0400 "$STATE/munge/munge.key"
munged --foreground --key-file="$STATE/munge/munge.key" --socket="$MUNGE_SOCKET" \
    --pid-file="$STATE/munge/munged.pid" --seed-file="$STATE/munge/munged.seed" \
    >"$STATE/munged.log" 2>&1 </dev/null &
MUNGED_PID=$!
munge_roundtrip() { munge --socket="$MUNGE_SOCKET" -n | unmunge --socket="$MUNGE_SOCKET"; }
wait_until "$START_TIMEOUT" "munged answering on $MUNGE_SOCKET" "$MUNGED_PID" munge_roundtrip
log "munged up (pid $MUNGED_PID, socket $MUNGE_SOCKET)"

# slurmctld refuses to start unless SlurmctldHost is this host's short name
# ("This host (vm/vm) not a valid controller"; the literal localhost is also
# accepted), and slurmd looks its node up by the same name (also given by -N).
NODE=$(hostname -s 2>/dev/null || hostname)
CPUS=$(nproc)
# A little below the real memory: slurmd drains a node that has less than configured.
MEM_MB=$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)
CTLD_PORT=$(pick_port)
SLURMD_PORT=$(pick_port "$CTLD_PORT")
mkdir -p "$STATE/slurmctld" "$STATE/slurmd"
export SLURM_CONF=$STATE/slurm.conf
sed -e "s|@STATE@|$STATE|g" -e "s|@NODE@|$NODE|g" -e "s|@CPUS@|$CPUS|g" \
    -e "s|@MEM_MB@|$MEM_MB|g" -e "s|@CTLD_PORT@|$CTLD_PORT|g" \
    -e "s|@SLURMD_PORT@|$SLURMD_PORT|g" "$HERE/slurm.conf.in" >"$SLURM_CONF"
! grep -n '@[A-Z_]*@' "$SLURM_CONF" || die "unfilled field in $SLURM_CONF"

slurmctld -D -i -f "$SLURM_CONF" >"$STATE/slurmctld.stderr" 2>&1 </dev/null &
CTLD_PID=$!
wait_until "$START_TIMEOUT" "slurmctld answering on port $CTLD_PORT" "$CTLD_PID" sinfo -h
slurmd -D -N "$NODE" -f "$SLURM_CONF" >"$STATE/slurmd.stderr" 2>&1 </dev/null &
SLURMD_PID=$!
node_idle() { [[ $(sinfo -h -N -n "$NODE" -o %T) == idle ]]; }
wait_until "$START_TIMEOUT" "node $NODE idle" "$SLURMD_PID" node_idle
kill -0 "$CTLD_PID" 2>/dev/null || die "slurmctld exited"
START_SECS=$((SECONDS - t_start))
log "slurmctld (pid $CTLD_PID, port $CTLD_PORT) and slurmd (pid $SLURMD_PID, port $SLURMD_PORT) up; node $NODE idle with $CPUS CPUs, ${MEM_MB} MB (${START_SECS}s)"

# ---------------------------------------------------------------- helpers
PARTITION=debug # as in slurm.conf.in
# The jobs reach graftal through PATH; a copy keeps a rebuild from changing it mid-test.
mkdir "$STATE/bin"
cp "$GRAFTAL" "$STATE/bin/graftal"
export PATH=$STATE/bin:$PATH
unset GRAFTAL_SHARD

# One line per job record Slurm still knows: ID STATE REASON NAME, where ID is
# ARRAYJOB_TASK for array tasks. Only jobs numbered above $1 (a phase's own).
jobs_after() {
    scontrol -o show job | awk -v after="$1" '
        /^JobId=/ {
            split("", f)
            for (i = 1; i <= NF; i++) {
                k = $i; sub(/=.*/, "", k); v = $i; sub(/^[^=]*=/, "", v)
                if (!(k in f)) f[k] = v
            }
            if (f["JobId"] + 0 <= after + 0) next
            id = ("ArrayJobId" in f) ? f["ArrayJobId"] "_" f["ArrayTaskId"] : f["JobId"]
            print id, f["JobState"], f["Reason"], f["JobName"]
        }' | sort -V
}
last_job_id() {
    scontrol -o show job 2>/dev/null | awk -F'[= ]' '/^JobId=/ && $2 + 0 > max { max = $2 + 0 } END { print max + 0 }'
}
# Wait until no job above $1 is pending or running. A job whose dependency
# can never be satisfied pends forever unless Slurm cancels it: give Slurm a
# few seconds to do so (it checks every sched_interval), then fail.
wait_jobs() {
    local after=$1 deadline=$((SECONDS + JOB_TIMEOUT)) stuck_since='' table
    while :; do
        table=$(jobs_after "$after")
        awk '$2 ~ /^(PENDING|RUNNING|CONFIGURING|COMPLETING|SUSPENDED|REQUEUED|RESIZING|SIGNALING|STAGE_OUT)/ { busy = 1 }
             END { exit !busy }' <<<"$table" || return 0
        if awk '$2 == "PENDING" && $3 == "DependencyNeverSatisfied" { found = 1 } END { exit !found }' <<<"$table"; then
            stuck_since=${stuck_since:-$SECONDS}
            if ((SECONDS - stuck_since >= 10)); then
                indent <<<"$table" >&2
                die "a job pends forever on a dependency that can never be satisfied (no --kill-on-invalid-dep=yes?)"
            fi
        fi
        if ((SECONDS >= deadline)); then
            indent <<<"$table" >&2
            die "jobs still pending or running after ${JOB_TIMEOUT}s"
        fi
        sleep 1
    done
}
show_jobs() { jobs_after "$1" | indent; }
# Check that the job line for ID ($2, exact, or "merge" for every non-array
# job) is in state $3.
expect_state() {
    local after=$1 id=$2 want=$3
    jobs_after "$after" | awk -v id="$id" -v want="$want" '
        (id == "merge" ? $1 !~ /_/ : $1 == id) { seen = 1; if ($2 != want) bad = 1 }
        END { exit !(seen && !bad) }' || {
        show_jobs "$after" >&2
        die "expected $id to be $want"
    }
}

new_workdir() {
    local dir=$STATE/$1
    mkdir "$dir"
    cp -r "$REPO/rules" "$dir/rules"
    printf '%s\n' "$shard_script" >"$dir/$SHARD_RECIPE"
    printf '%s\n' "$merge_script" >"$dir/$MERGE_RECIPE"
    echo "$dir"
}
# Run a shell recipe in a working directory, its output indented.
run_recipe() {
    local dir=$1 name=$2 body=$3
    log "recipe $name in ${dir#"$STATE"/}:"
    printf '%s\n' "$body" | sed 's/^/    $ /'
    (cd "$dir" && sh -e -c "$body") 2>&1 | sed 's/^/    > /'
}
# The merged manifest and every mesh must be byte for byte what the unsharded run wrote.
compare_with_ref() {
    local dir=$1 n
    cmp "$REF/$OUT_DIR/manifest.json" "$dir/$OUT_DIR/manifest.json" ||
        die "$dir/$OUT_DIR/manifest.json differs from the unsharded manifest"
    diff -rq -x 'manifest.shard-*' "$REF/$OUT_DIR" "$dir/$OUT_DIR" >&2 ||
        die "outputs in ${dir#"$STATE"/}/$OUT_DIR differ from the unsharded run"
    n=$(find "$REF/$OUT_DIR" -type f | wc -l)
    log "OK: manifest.json and all $n files in ${dir#"$STATE"/}/$OUT_DIR identical to the unsharded run ($(find "$dir/$OUT_DIR" -name 'manifest.shard-*' | wc -l) shard manifests beside them)"
}
show_job_output() {
    local f
    for f in "$1"/slurm-*.out; do
        [[ -s $f ]] || continue
        sed "s|^|    ${f##*/}: |" "$f"
    done
}

# ---------------------------------------------------------------- reference
t_test=$SECONDS
REF=$STATE/ref
mkdir "$REF"
cp -r "$REPO/rules" "$REF/rules"
log "reference (unsharded): $REF_CMD"
(cd "$REF" && sh -e -c "$REF_CMD") 2>&1 | sed 's/^/    > /'
[[ -f $REF/$OUT_DIR/manifest.json ]] || die "the reference run wrote no $OUT_DIR/manifest.json"

# ---------------------------------------------------------------- 1: recipe
log "== 1. submit: shard array + dependent merge"
work=$(new_workdir work1)
before=$(last_job_id)
run_recipe "$work" "$SUBMIT_RECIPE" "$submit_script"
wait_jobs "$before"
show_jobs "$before"
expect_state "$before" merge COMPLETED
jobs_after "$before" | awk '$2 != "COMPLETED" { exit 1 }' || die "a job did not complete"
show_job_output "$work"
compare_with_ref "$work"

# ---------------------------------------------------------------- 2: retry
log "== 2. cancel task $FAIL_TASK before it runs: the merge must be cancelled, then retry"
work=$(new_workdir work2)
before=$(last_job_id)
# With the partition down the jobs queue but cannot start, so the task is
# cancelled before it runs however fast the other shards are.
scontrol update PartitionName="$PARTITION" State=DOWN
run_recipe "$work" "$SUBMIT_RECIPE" "$submit_script"
array=$(jobs_after "$before" | awk '$1 ~ /_/ { sub(/_.*/, "", $1); print $1; exit }')
[[ -n $array ]] || die "the submit recipe made no job array"
log "scancel ${array}_$FAIL_TASK, then bring the partition up"
# A task cancelled inside the pending array leaves no job record; holding it
# first splits it into its own record, so its CANCELLED state can be checked.
scontrol hold "${array}_$FAIL_TASK"
scancel "${array}_$FAIL_TASK"
scontrol update PartitionName="$PARTITION" State=UP
wait_jobs "$before"
show_jobs "$before"
expect_state "$before" "${array}_$FAIL_TASK" CANCELLED
expect_state "$before" merge CANCELLED
jobs_after "$before" | awk -v t="${array}_$FAIL_TASK" '$1 ~ /_/ && $1 != t && $2 != "COMPLETED" { exit 1 }' ||
    die "an array task other than $FAIL_TASK did not complete"
[[ ! -e $work/$OUT_DIR/manifest.json ]] || die "a merged manifest exists although the merge was cancelled"
log "OK: task $FAIL_TASK cancelled, the merge cancelled with it (--kill-on-invalid-dep), the other tasks completed"

before=$(last_job_id)
run_recipe "$work" "$RETRY_RECIPE" "$retry_script"
wait_jobs "$before"
show_jobs "$before"
jobs_after "$before" | awk '$2 != "COMPLETED" { exit 1 }' || die "a retry job did not complete"
expect_state "$before" merge COMPLETED
show_job_output "$work"
compare_with_ref "$work"

TEST_SECS=$((SECONDS - t_test))
log "PASS (install ${INSTALL_SECS}s, daemons ${START_SECS}s, jobs and checks ${TEST_SECS}s, total ${SECONDS}s before shutdown)"
