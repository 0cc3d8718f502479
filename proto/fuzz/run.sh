#!/usr/bin/env bash
# Runs every fuzz target of relief-proto for SECONDS seconds each (default 60), as many side by
# side as there are cores, from the committed seeds (seeds/TARGET) plus what earlier runs kept
# (corpus/TARGET).
# Prints each target's executions and whether it crashed; exits non-zero if any crashed.
# Without a nightly toolchain it prints "skipped" and exits 0. Works from any directory.
#
#   proto/fuzz/run.sh [SECONDS]
#
# Crash inputs land in proto/fuzz/artifacts/TARGET/; full libFuzzer logs in
# proto/fuzz/target/run-logs/TARGET.log. See README.md.
set -euo pipefail

# The cargo-fuzz this crate was set up and checked with.
CARGO_FUZZ_VERSION=0.13.2

secs=${1:-60}
if ! [[ $secs =~ ^[1-9][0-9]*$ ]]; then
    echo "usage: $0 [SECONDS]" >&2
    exit 2
fi
cd "$(dirname "${BASH_SOURCE[0]}")"

if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "fuzz: skipped: no nightly toolchain (cargo +nightly)"
    exit 0
fi
if [[ $(cargo fuzz --version 2>/dev/null) != "cargo-fuzz $CARGO_FUZZ_VERSION" ]]; then
    echo "fuzz: installing cargo-fuzz $CARGO_FUZZ_VERSION"
    nice -n 10 cargo install cargo-fuzz --version "$CARGO_FUZZ_VERSION" --locked
fi

# The longest input worth trying per target: a tile body with a full 256-cell tile needs about
# 8 KiB; the other decoders reach every path well below 4 KiB.
max_len() {
    case $1 in
        tile_body) echo 16384 ;;
        *) echo 4096 ;;
    esac
}

start=$(date +%s)
nice -n 10 cargo +nightly fuzz build
echo "fuzz: built in $(($(date +%s) - start)) s"

mkdir -p target/run-logs
targets=$(cargo +nightly fuzz list)

# One target's run; prints its one-line verdict, then its crash lines where it crashed, and
# exits non-zero on a crash.
run_one() {
    local t=$1 log=target/run-logs/$1.log status=0 runs
    mkdir -p "corpus/$t" "seeds/$t"
    # -malloc_limit_mb: any single allocation over 64 MiB is a failure (the decoders' inputs are
    # at most 16 KiB); -timeout: one input taking over 10 s is a hang.
    nice -n 10 cargo +nightly fuzz run "$t" "corpus/$t" "seeds/$t" -- \
        -max_total_time="$secs" -max_len="$(max_len "$t")" -rss_limit_mb=2048 \
        -malloc_limit_mb=64 -timeout=10 -print_final_stats=1 >"$log" 2>&1 || status=$?
    runs=$(grep -oE '^Done [0-9]+ runs' "$log" | tail -n 1 | grep -oE '[0-9]+' || true)
    if [[ $status -eq 0 && -n $runs ]]; then
        echo "fuzz $t: $runs runs in $secs s, no crash"
        return 0
    fi
    runs=$(grep -oE '^#[0-9]+' "$log" | tail -n 1 | tr -d '#' || true)
    echo "fuzz $t: CRASHED (exit $status) after about ${runs:-0} runs (0: on a seed or" \
        "corpus input); input in proto/fuzz/artifacts/$t/, log in proto/fuzz/$log:"
    grep -E 'panicked at|ERROR: libFuzzer|^SUMMARY|Test unit written|^error' "$log" |
        head -n 12 | sed 's/^/    /' || true
    return 1
}

# Each libFuzzer run uses one core: as many targets run side by side as there are cores
# (FUZZ_JOBS overrides), each for its full SECONDS, so the wall time is about
# SECONDS x targets / cores. Verdicts print in the targets' order.
jobs=${FUZZ_JOBS:-$(nproc)}
failed=0
passed=0
batch=()
finish_batch() {
    local t
    for t in "${batch[@]}"; do
        if wait "${pids[$t]}"; then
            passed=$((passed + 1))
        else
            failed=$((failed + 1))
        fi
        cat "target/run-logs/$t.verdict"
    done
    batch=()
}
declare -A pids
for t in $targets; do
    run_one "$t" >"target/run-logs/$t.verdict" &
    pids[$t]=$!
    batch+=("$t")
    if ((${#batch[@]} >= jobs)); then
        finish_batch
    fi
done
((${#batch[@]} == 0)) || finish_batch
echo "fuzz: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
