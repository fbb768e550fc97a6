#!/usr/bin/env bash
# Record the pipeline topics (and the /uncompensated robot's) until Ctrl-C or --seconds, e.g. while
# your own tracker and nodes run on this ROS_DOMAIN_ID.
#
# usage: scripts/record.sh [--out BAG_DIR] [--seconds N] [--params-dir DIR]
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=env.sh
source "$HERE/env.sh"
# shellcheck source=lib.sh
source "$HERE/lib.sh"

out=""
seconds=""
params_dir="$GWR_ROOT/config"
while [ $# -gt 0 ]; do
    case "$1" in
        --out) out="$2"; shift 2 ;;
        --seconds) seconds="$2"; shift 2 ;;
        --params-dir) params_dir="$2"; shift 2 ;;
        -h|--help) sed -n '2,5p' "$0"; exit 0 ;;
        *) gwr_die "unknown argument $1 (see --help)" ;;
    esac
done
out="${out:-$GWR_ROOT/results/recording_$(date +%Y%m%d_%H%M%S)}"
[ ! -e "$out" ] || gwr_die "$out exists already"
mkdir -p "$(dirname "$out")"
out="$(cd "$(dirname "$out")" && pwd)/$(basename "$out")"
logdir="$out.logs"
export ROS_LOG_DIR="$logdir/ros_log"
trap 'gwr_stop_all' EXIT
trap 'gwr_log "stopping"; exit 0' INT TERM
mapfile -t a < <(gwr_node_args bag_recorder "$params_dir")
gwr_start bag_recorder "$logdir" bag_recorder "${a[@]}" -p "path:=$out"
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
