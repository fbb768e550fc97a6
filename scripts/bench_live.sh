#!/usr/bin/env bash
# Benchmark the live pipeline: run it (scripts/run_pipeline.sh, 10 Hz angle frames from 30 fps
# skeletons, everything recorded) for N minutes, then measure from the bag alone
# (`gwr-predictor latency`): latency percentiles per hop (p50/p90/p99/max, from the frame's source
# stamp to the recorder's receive time) and messages published vs recorded vs consumed per topic,
# from every node's final /diagnostics counters. Exits 3 if more than --max-lost messages were lost
# (reliable QoS with keep-last queues: the allowed loss is 0 unless a queue overflowed).
#
# usage: scripts/bench_live.sh [--minutes N] [--seconds N] [--out DIR] [--checkpoint FILE]
#                              [--max-lost N] [--no-baseline]
#   --minutes N        run length in minutes (default 10)
#   --seconds N        run length in seconds instead (for a quick check)
#   --out DIR          run folder (default results/bench_live_<time>); latency.json and report.json go there
#   --checkpoint FILE  start the learner from this model (default: a fresh one that grows during the run)
#   --max-lost N       allowed lost messages (default 0)
#   --no-baseline      no uncompensated robot pair
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# a domain of its own unless one is set, so that a benchmark never mixes with another run on this machine
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(($$ % 19 + 1))}"
# shellcheck source=env.sh
source "$HERE/env.sh"
# shellcheck source=lib.sh
source "$HERE/lib.sh"

seconds=600
out=""
max_lost=0
extra=()
while [ $# -gt 0 ]; do
    case "$1" in
        --minutes) [[ "${2:-}" =~ ^[0-9]+$ ]] || gwr_die "--minutes needs a whole number, got '${2:-}'"; seconds=$(($2 * 60)); shift 2 ;;
        --seconds) [[ "${2:-}" =~ ^[0-9]+$ ]] || gwr_die "--seconds needs a whole number, got '${2:-}'"; seconds="$2"; shift 2 ;;
        --out) out="$(gwr_value "$@")"; shift 2 ;;
        --checkpoint) extra+=(--checkpoint "$(gwr_value "$@")"); shift 2 ;;
        --max-lost) [[ "${2:-}" =~ ^[0-9]+$ ]] || gwr_die "--max-lost needs a whole number, got '${2:-}'"; max_lost="$2"; shift 2 ;;
        --no-baseline) extra+=(--no-baseline); shift ;;
        -h|--help) gwr_usage "$0"; exit 0 ;;
        *) gwr_die "unknown argument $1 (see --help)" ;;
    esac
done
out="$(gwr_run_folder "$out" bench_live)"
start=$SECONDS
gwr_log "live benchmark: $seconds s into $out"
status=0
"$HERE/run_pipeline.sh" --seconds "$seconds" --out "$out" "${extra[@]}" || status=$?
[ "$status" = 0 ] || gwr_log "the pipeline run failed (exit code $status): measuring what was recorded"
gwr_log "pipeline finished after $((SECONDS - start)) s; measuring"
lat=0
gwr-predictor latency "$out" --max-lost "$max_lost" || lat=$?
gwr-predictor report "$out" >/dev/null 2>&1 || gwr_log "report failed (see gwr-predictor report $out)"
[ "$status" = 0 ] || exit "$status"
exit "$lat"
