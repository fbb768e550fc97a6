# Shared shell functions of the orchestration scripts (source me after scripts/env.sh).
# Nodes run as background processes, one log file each; they are stopped in reverse start order
# with SIGINT, then SIGTERM, then SIGKILL after timeouts (then Fast DDS shared memory is cleaned).
# shellcheck shell=bash

GWR_PIDS=()
GWR_NAMES=()
GWR_LOGS=()
GWR_NEED_SHM_CLEAN=0

gwr_log() { echo "[gwr_predictor] $*" >&2; }

gwr_die() { gwr_log "error: $*"; exit 1; }

# gwr_usage SCRIPT: print the script's header comment (the lines after the shebang that start
# with '#'), without the '# ', so that --help shows the usage text and never code.
gwr_usage() {
    sed -n '2,/^[^#]/{/^#/!q;s/^# \{0,1\}//;p}' "$1"
}

# gwr_value OPTION [VALUE]: VALUE, or a clear error when the option was given without one
# (e.g. `--seconds` last on the line), instead of bash's "unbound variable".
gwr_value() {
    [ $# -ge 2 ] && [ -n "$2" ] && [[ "$2" != --* ]] || gwr_die "$1 needs a value (see --help)"
    printf '%s' "$2"
}

# gwr_run_folder DIR KIND: the absolute path of the run folder DIR (empty: results/KIND_<time>), created.
gwr_run_folder() {
    local dir="${1:-$GWR_ROOT/results/${2}_$(date +%Y%m%d_%H%M%S)}"
    mkdir -p "$dir" || gwr_die "cannot create the run folder $dir"
    (cd "$dir" && pwd)
}

# gwr_start NAME LOGDIR COMMAND [ARGS...]: start COMMAND in the background, output in LOGDIR/NAME.log.
# The child gets its own bootstrap of the ROS wheels (guard variable unset) and the caller's
# ROS_DOMAIN_ID / ROS_LOG_DIR / discovery range.
gwr_start() {
    local name="$1" logdir="$2"
    shift 2
    mkdir -p "$logdir"
    local log="$logdir/$name.log"
    env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE PYTHONUNBUFFERED=1 RCUTILS_COLORIZED_OUTPUT=0 \
        "$@" >"$log" 2>&1 </dev/null &
    GWR_PIDS+=("$!")
    GWR_NAMES+=("$name")
    GWR_LOGS+=("$log")
    gwr_log "started $name (pid $!, log $log)"
}

# gwr_wait_ready NAME TIMEOUT_S: wait for the node's "ready" log line; fail if it exits first.
gwr_wait_ready() {
    local name="$1" timeout="${2:-60}" i
    for i in "${!GWR_NAMES[@]}"; do
        [ "${GWR_NAMES[$i]}" = "$name" ] || continue
        local deadline=$((SECONDS + timeout))
        while ! grep -q "\]: ready" "${GWR_LOGS[$i]}" 2>/dev/null; do
            if ! kill -0 "${GWR_PIDS[$i]}" 2>/dev/null; then
                gwr_log "$name exited during start-up; its log (${GWR_LOGS[$i]}):"
                tail -n 20 "${GWR_LOGS[$i]}" >&2
                return 1
            fi
            if [ "$SECONDS" -ge "$deadline" ]; then
                gwr_log "$name not ready after ${timeout} s (log ${GWR_LOGS[$i]})"
                return 1
            fi
            sleep 0.2
        done
        return 0
    done
    gwr_log "gwr_wait_ready: no process named $name"
    return 1
}

# gwr_alive: 0 if every started process still runs, else names the first dead one.
gwr_alive() {
    local i
    for i in "${!GWR_PIDS[@]}"; do
        [ -n "${GWR_PIDS[$i]}" ] || continue
        if ! kill -0 "${GWR_PIDS[$i]}" 2>/dev/null; then
            gwr_log "${GWR_NAMES[$i]} has exited (log ${GWR_LOGS[$i]})"
            return 1
        fi
    done
    return 0
}

_gwr_wait_pid() {  # _gwr_wait_pid PID TIMEOUT_S: 0 if it exited in time
    local pid="$1" deadline=$((SECONDS + $2))
    while kill -0 "$pid" 2>/dev/null; do
        [ "$SECONDS" -ge "$deadline" ] && return 1
        sleep 0.1
    done
    return 0
}

# gwr_stop INDEX [TIMEOUT_S]: SIGINT, wait; SIGTERM, wait; SIGKILL. Prints the exit code.
gwr_stop() {
    local i="$1" timeout="${2:-10}"
    local pid="${GWR_PIDS[$i]}" name="${GWR_NAMES[$i]}"
    [ -n "$pid" ] || return 0
    if kill -0 "$pid" 2>/dev/null; then
        kill -INT "$pid" 2>/dev/null
        if ! _gwr_wait_pid "$pid" "$timeout"; then
            gwr_log "$name ignored SIGINT for ${timeout} s: SIGTERM"
            kill -TERM "$pid" 2>/dev/null
            if ! _gwr_wait_pid "$pid" 5; then
                gwr_log "$name ignored SIGTERM: SIGKILL"
                kill -KILL "$pid" 2>/dev/null
                GWR_NEED_SHM_CLEAN=1
            fi
        fi
    fi
    local code=0
    wait "$pid" 2>/dev/null || code=$?
    gwr_log "stopped $name (exit code $code)"
    GWR_PIDS[$i]=""
    return 0
}

# gwr_stop_all: stop every process in reverse start order; clean Fast DDS shm if one was killed.
gwr_stop_all() {
    local i
    for ((i = ${#GWR_PIDS[@]} - 1; i >= 0; i--)); do
        gwr_stop "$i"
    done
    if [ "$GWR_NEED_SHM_CLEAN" = 1 ]; then
        gwr_shm_clean
    fi
}

gwr_shm_clean() {
    if command -v fastdds >/dev/null 2>&1; then
        fastdds shm clean >/dev/null 2>&1 || true
        gwr_log "cleaned Fast DDS shared memory segments"
    fi
}

# gwr_wait_seconds N: sleep N seconds in short steps, returning early (1) if a process died.
gwr_wait_seconds() {
    local deadline=$((SECONDS + $1))
    while [ "$SECONDS" -lt "$deadline" ]; do
        gwr_alive || return 1
        sleep 0.5
    done
    return 0
}

# gwr_node_args NODE PARAMS_DIR [SCENARIO_YAML]: the --ros-args with the node's params file(s).
gwr_node_args() {
    local node="$1" dir="$2" scenario="${3:-}"
    printf '%s\n' --ros-args --params-file "$dir/$node.yaml"
    if [ -n "$scenario" ]; then
        printf '%s\n' --params-file "$scenario"
    fi
}

# gwr_wait_exit NAME [TIMEOUT_S]: wait until the named process exits on its own (0 if it did).
gwr_wait_exit() {
    local name="$1" timeout="${2:-86400}" i
    for i in "${!GWR_NAMES[@]}"; do
        [ "${GWR_NAMES[$i]}" = "$name" ] || continue
        _gwr_wait_pid "${GWR_PIDS[$i]}" "$timeout" || return 1
        local code=0
        wait "${GWR_PIDS[$i]}" 2>/dev/null || code=$?
        gwr_log "$name finished (exit code $code)"
        GWR_PIDS[$i]=""
        return "$code"
    done
    return 1
}

# gwr_namespace NS: NS as an absolute ROS namespace without a trailing slash ("" for the root), or a
# clear error for a name ROS would refuse (tokens of letters, digits and _, not starting with a digit).
gwr_namespace() {
    local ns="${1#/}"
    ns="${ns%/}"
    [ -n "$ns" ] || return 0
    [[ "$ns" =~ ^[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$ ]] \
        || gwr_die "--namespace $1 is not a ROS namespace (tokens of letters, digits and _, separated by /)"
    printf '/%s' "$ns"
}

# gwr_wait_matched NAME TIMEOUT_S TOPIC...: wait until the recorder NAME has logged `matched TOPIC` for each
# topic (its subscription hears the topic's publisher), so that nothing they publish from now on is lost
# to it (discovery can take seconds under load); after TIMEOUT_S a warning, and on (0 all the same).
gwr_wait_matched() {
    local name="$1" timeout="$2" i topic
    shift 2
    for i in "${!GWR_NAMES[@]}"; do
        [ "${GWR_NAMES[$i]}" = "$name" ] || continue
        local deadline=$((SECONDS + timeout))
        for topic in "$@"; do
            while ! grep -q "\]: matched $topic\$" "${GWR_LOGS[$i]}" 2>/dev/null; do
                if [ "$SECONDS" -ge "$deadline" ]; then
                    gwr_log "warning: $name has not matched a publisher of $topic after ${timeout} s: its first messages may be missing from the bag"
                    return 0
                fi
                sleep 0.1
            done
        done
        return 0
    done
    gwr_log "gwr_wait_matched: no process named $name"
    return 1
}

# gwr_tf_check: the tf2 nodes of --tf come from a ROS 2 install (tf2_msgs has no PyPI wheel, so the package's
# own nodes publish no TF); stop with a clear error at start when they are missing.
gwr_tf_check() {
    command -v ros2 >/dev/null 2>&1 \
        || gwr_die "--tf needs robot_state_publisher and tf2_ros from a ROS 2 Jazzy install, and there is no ros2 command (source /opt/ros/jazzy/setup.bash first); the PyPI wheels have no tf2_msgs, so the package's nodes cannot publish TF themselves"
    local pkg
    for pkg in robot_state_publisher tf2_ros; do
        ros2 pkg prefix "$pkg" >/dev/null 2>&1 || gwr_die "--tf needs the ROS 2 package $pkg (apt: ros-jazzy-${pkg//_/-})"
    done
}

# gwr_start_tf OUT NAMESPACE BASELINE: start the pipeline's tf2 nodes (gwr_predictor.pipeline.tf_plan: a
# robot_state_publisher per simulated Nao, the camera and baseline transforms, on NAMESPACE/tf) with ros2 run.
gwr_start_tf() {
    local out="$1" namespace="$2" baseline="$3" plan label command
    local options=(--namespace "${namespace:-/}" --out "$out/tf")
    [ "$baseline" = 1 ] || options+=(--no-baseline)
    plan="$(python -m gwr_predictor.pipeline.tf_plan "${options[@]}")" || gwr_die "cannot plan the TF nodes"
    while read -r label command; do
        eval "local argv=($command)"
        gwr_start "$label" "$out" "${argv[@]}"
    done <<< "$plan"
}
