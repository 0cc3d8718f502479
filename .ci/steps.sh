# Step timing for CI and tests/setup.sh (sourced, not run).
#
#   step NAME COMMAND...    runs COMMAND, appends "NAME<TAB>SECONDS<TAB>EXIT" to $RELIEF_STEP_LOG
#                           (when set) and returns COMMAND's exit status
#   step_tests NAME COMMAND...
#                           runs COMMAND (one that ends in a `cargo test`) in a session of its
#                           own, passes its output through, names and kills the processes
#                           COMMAND leaves running, and logs what comes before the first test binary (the
#                           build) as "NAME (build)" and each test binary's run as
#                           "NAME: BINARY"
#   step_table T0           prints the logged steps as a table with their sum and the wall time
#                           since T0
#
# Without RELIEF_STEP_LOG nothing is logged and the commands run as they would without this file.
# Call `step` at the top level of a `set -e` script when COMMAND is a shell function: inside the
# left operand of `||` bash ignores `set -e` in the function body too.

step() {
    local name=$1 t0 rc=0
    shift
    t0=$EPOCHREALTIME
    # In the background, so that `set -e` still holds inside a shell function COMMAND (it does
    # not in the left operand of `||`).
    "$@" &
    wait "$!" || rc=$?
    _step_log "$name" "$t0" "$EPOCHREALTIME" "$rc"
    return "$rc"
}

_step_log() {
    [[ -n ${RELIEF_STEP_LOG:-} ]] || return 0
    awk -v n="$1" -v a="$2" -v b="$3" -v rc="$4" \
        'BEGIN { printf "%s\t%.1f\t%s\n", n, b - a, rc }' >>"$RELIEF_STEP_LOG"
}

# Each output line is stamped with the time it arrived, so that the build (up to the first
# "Running" line) and each test binary (up to the next one) get their own wall time.
step_tests() {
    local name=$1 t0 stamped fifo reader pid rc=0
    shift
    t0=$EPOCHREALTIME
    stamped=$(mktemp)
    fifo=$(mktemp -u)
    mkfifo "$fifo"
    while IFS= read -r line; do
        printf '%s\n' "$line"
        printf '%s\t%s\n' "$EPOCHREALTIME" "$line" >>"$stamped"
    done <"$fifo" &
    reader=$!
    # COMMAND runs in a session of its own, so that a process its tests leave running (one a
    # failed test never stopped) is found when COMMAND ends, named and killed: it would hold
    # the output pipe open, and the reader would wait for it, and the run with it, forever.
    # (A background job of a script is no group leader, so setsid starts the session in the
    # process itself and its pid names the session.)
    setsid "$@" >"$fifo" 2>&1 &
    pid=$!
    trap 'pkill -KILL -s "$pid"; exit 130' INT TERM
    wait "$pid" || rc=$?
    if pgrep -s "$pid" >/dev/null; then
        echo "step $name left these running; killed:"
        ps -o pid=,args= -s "$pid"
        pkill -KILL -s "$pid" || true
    fi
    trap - INT TERM
    wait "$reader" || true
    rm -f "$fifo"
    # `cargo test` names a binary in its "Running" line (unit tests by source file, the
    # integration tests by target) and a crate's doctests in its "Doc-tests" line.
    if [[ -n ${RELIEF_STEP_LOG:-} ]]; then
        awk -F '\t' -v n="$name" -v t0="$t0" -v end="$EPOCHREALTIME" -v rc="$rc" '
            function close_one(t) {
                if (cur != "") printf "%s: %s\t%.1f\t\n", n, cur, t - since
            }
            {
                line = $2
                sub(/^[ \t]+/, "", line)
                if (line ~ /^Running / || line ~ /^Doc-tests /) {
                    if (cur == "") printf "%s (build)\t%.1f\t\n", n, $1 - t0
                    close_one($1)
                    cur = line
                    sub(/^Running /, "", cur)
                    # Unit tests are named by source file alone: add the crate, from the binary.
                    if (cur ~ /^unittests / && match(line, /deps\/[A-Za-z0-9_]+-/))
                        cur = substr(line, RSTART + 5, RLENGTH - 6) " " cur
                    sub(/ \(.*\)$/, "", cur)
                    since = $1
                }
            }
            END {
                if (cur == "") printf "%s (build)\t%.1f\t%s\n", n, end - t0, rc
                else close_one(end)
                printf "%s (all)\t%.1f\t%s\n", n, end - t0, rc
            }' "$stamped" >>"$RELIEF_STEP_LOG"
    fi
    rm -f "$stamped"
    return "$rc"
}

# Prints the table; its last line is the wall time since T0 (seconds since the epoch, as
# $EPOCHREALTIME gives them), which is less than the steps' sum where steps overlapped.
step_table() {
    local t0=$1
    [[ -n ${RELIEF_STEP_LOG:-} && -s $RELIEF_STEP_LOG ]] || return 0
    echo
    echo "CI steps (wall time; exit status where not 0; '(all)' rows sum the rows above them):"
    awk -F '\t' -v t0="$t0" -v now="$EPOCHREALTIME" '
        function row(name, s, note) {
            printf "  %-60s %8.1f s %7s  %s\n", name, s, sprintf("%d:%02d", s / 60, s % 60), note
        }
        { row($1, $2, ($3 != "" && $3 != 0) ? "exit " $3 : "") }
        $1 !~ /: / && $1 !~ /\(build\)$/ { total += $2 }
        END {
            row("sum of the steps", total, "")
            row("wall, start to end", now - t0, "")
        }
    ' "$RELIEF_STEP_LOG"
}
