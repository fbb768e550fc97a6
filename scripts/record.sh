#!/usr/bin/env bash
# Record the pipeline topics (and the /uncompensated robot's) until Ctrl-C or --seconds, e.g. while
# your own tracker and nodes run on this ROS_DOMAIN_ID.
#
# usage: scripts/record.sh [--out BAG_DIR] [--seconds N] [--params-dir DIR] [--namespace NS] [--hri]
#   --out BAG_DIR     the bag to create (default results/recording_<time>)
#   --seconds N       stop after N s (default: at Ctrl-C)
#   --params-dir DIR  folder with bag_recorder.yaml (default config/)
#   --namespace NS    record the pipeline that runs in NS (run_pipeline.sh --namespace NS): /NS/arm_angles, ...
#   --hri             also record the ROS4HRI input: every topic below /humans/bodies as it appears (each
#                     tracked body's joint_states and position), so that scripts/replay.sh --hri replays it
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=env.sh
source "$HERE/env.sh"
# shellcheck source=lib.sh
source "$HERE/lib.sh"

out=""
seconds=""
params_dir="$GWR_ROOT/config"
namespace=""
extra=()
while [ $# -gt 0 ]; do
    case "$1" in
        --out) out="$(gwr_value "$@")"; shift 2 ;;
        --seconds) seconds="$(gwr_value "$@")"; shift 2 ;;
        --params-dir) params_dir="$(gwr_value "$@")"; shift 2 ;;
        --namespace) namespace="$(gwr_value "$@")"; shift 2 ;;
        --hri) extra+=(-p "record_below:=[/humans/bodies]"); shift ;;
        -h|--help) gwr_usage "$0"; exit 0 ;;
        *) gwr_die "unknown argument $1 (see --help)" ;;
    esac
done
[ -z "$seconds" ] || [[ "$seconds" =~ ^[0-9]+$ ]] || gwr_die "--seconds must be a whole number, got $seconds"
namespace="$(gwr_namespace "$namespace")" || exit 1
[ -z "$namespace" ] || extra+=(-r "__ns:=$namespace")
out="${out:-$GWR_ROOT/results/recording_$(date +%Y%m%d_%H%M%S)}"
[ ! -e "$out" ] || gwr_die "$out exists already"
mkdir -p "$(dirname "$out")"
out="$(cd "$(dirname "$out")" && pwd)/$(basename "$out")"
logdir="$out.logs"
export ROS_LOG_DIR="$logdir/ros_log"
trap 'gwr_stop_all' EXIT
trap 'gwr_log "stopping"; exit 0' INT TERM
mapfile -t a < <(gwr_node_args bag_recorder "$params_dir")
gwr_start bag_recorder "$logdir" bag_recorder "${a[@]}" -p "path:=$out" "${extra[@]}"
gwr_wait_ready bag_recorder 60
if [ -n "$seconds" ]; then
    gwr_log "recording for $seconds s into $out"
    gwr_wait_seconds "$seconds" || true
else
    gwr_log "recording into $out; Ctrl-C to stop"
    while gwr_alive; do sleep 0.5; done
fi
gwr_stop_all
trap - EXIT
gwr_log "bag: $out (log: $logdir/bag_recorder.log)"
