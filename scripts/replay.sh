#!/usr/bin/env bash
# Replay a recorded bag's person input through the pipeline again and record the new outputs.
#   <ns>/skeleton    -> angle_extractor -> arm_predictor -> delay_compensator -> nao_sim
#   <ns>/arm_angles  ->                    arm_predictor -> delay_compensator -> nao_sim
#   /humans/bodies/* -> hri_bodies      -> arm_predictor -> delay_compensator -> nao_sim   (--hri)
# The player restamps the messages to the replay time, so the nodes see a live stream.
#
# usage: scripts/replay.sh BAG [--out DIR] [--topic T | --hri] [--namespace NS] [--rate R]
#                          [--checkpoint FILE] [--params-dir DIR] [--no-baseline] [--sim-time]
#   BAG                a bag directory (e.g. bags/demo_sample or results/<run>/bag) or a bare .mcap file
#   --out DIR          run folder for the new bag, model and logs (default results/replay_<time>)
#   --topic T          what to replay: a skeleton or arm_angles topic as recorded, e.g. /arm_angles or
#                      /robot1/skeleton (default: the bag's skeleton topic, in whatever namespace)
#   --hri              replay the ROS4HRI body topics (scripts/record.sh --hri) through hri_bodies
#   --namespace NS     run the replay's nodes in NS (default: the root), the replayed topic renamed into it
#   --rate R           replay speed (default 1.0; the robot's delay is in real time, so keep 1.0
#                      when the robot's lag matters, or use --sim-time)
#   --checkpoint FILE  learner start model (default: a fresh one)
#   --no-baseline      no uncompensated robot
#   --sim-time         run every node on the recorded time: the player publishes /clock (at --rate)
#                      instead of restamping, the nodes use_sim_time:=true (the robot's delay then
#                      runs on the replayed clock, so any --rate keeps the lag as recorded)
# Then: gwr-predictor report DIR
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=env.sh
source "$HERE/env.sh"
# shellcheck source=lib.sh
source "$HERE/lib.sh"

[ $# -ge 1 ] || { gwr_usage "$0"; exit 2; }
case "$1" in -h|--help) gwr_usage "$0"; exit 0 ;; esac
bag="$1"
shift
out=""
topic=""
hri=0
namespace=""
rate="1.0"
checkpoint=""
params_dir="$GWR_ROOT/config"
baseline=1
sim_time=0
while [ $# -gt 0 ]; do
    case "$1" in
        --out) out="$2"; shift 2 ;;
        --topic) topic="$(gwr_value "$@")"; shift 2 ;;
        --hri) hri=1; shift ;;
        --namespace) namespace="$(gwr_value "$@")"; shift 2 ;;
        --rate) rate="$2"; shift 2 ;;
        --checkpoint) checkpoint="$2"; shift 2 ;;
        --params-dir) params_dir="$2"; shift 2 ;;
        --no-baseline) baseline=0; shift ;;
        --sim-time) sim_time=1; shift ;;
        *) gwr_die "unknown argument $1 (see --help)" ;;
    esac
done
if [ -f "$bag" ] && [[ "$bag" == *.mcap ]]; then
    bag="$(cd "$(dirname "$bag")" && pwd)/$(basename "$bag")"
else
    [ -f "$bag/metadata.yaml" ] || gwr_die "$bag is neither a bag directory (no metadata.yaml) nor a .mcap file"
    bag="$(cd "$bag" && pwd)"
fi
[ "$hri" = 0 ] || [ -z "$topic" ] || gwr_die "--topic and --hri exclude each other"
namespace="$(gwr_namespace "$namespace")" || exit 1
# what to play, renamed into the replay's namespace (gwr_predictor.pipeline.replay_plan)
plan_args=(--namespace "${namespace:-/}")
[ -z "$topic" ] || plan_args+=(--topic "$topic")
[ "$hri" = 0 ] || plan_args+=(--hri)
plan="$(python -m gwr_predictor.pipeline.replay_plan "$bag" "${plan_args[@]}")" || gwr_die "nothing to replay from $bag"
input="" played=() remaps=() body=""
while read -r key value; do
    case "$key" in
        input) input="$value" ;;
        topic) played+=("$value") ;;
        remap) remaps+=("'$value'") ;;
        body) body="$value" ;;
    esac
done <<< "$plan"
[ -z "$checkpoint" ] || [ -f "$checkpoint" ] || gwr_die "--checkpoint $checkpoint not found"
out="$(gwr_run_folder "$out" replay)"
[ ! -e "$out/bag" ] || gwr_die "$out/bag exists already: choose another --out"
export ROS_LOG_DIR="$out/ros_log"
if [ -n "$checkpoint" ]; then cp "$checkpoint" "$out/model.npz"; fi

trap 'gwr_stop_all' EXIT
trap 'gwr_log "interrupted"; exit 130' INT TERM
start_node() {  # start_node LABEL NODE [extra ROS args...]
    local label="$1" node="$2"
    shift 2
    local a
    mapfile -t a < <(gwr_node_args "$node" "$params_dir")
    if [ "$sim_time" = 1 ]; then a+=(-p use_sim_time:=true); fi
    gwr_start "$label" "$out" "$node" "${a[@]}" "$@"
}

gwr_log "replaying ${played[*]} of $bag into $out (ROS_DOMAIN_ID=$ROS_DOMAIN_ID, namespace ${namespace:-/})"
here=()
[ -z "$namespace" ] || here+=(-r "__ns:=$namespace")
start_node bag_recorder bag_recorder "${here[@]}" -p "path:=$out/bag"
gwr_wait_ready bag_recorder 60
start_node nao_sim nao_sim "${here[@]}"
start_node delay_compensator delay_compensator "${here[@]}"
waiting=(nao_sim delay_compensator arm_predictor)
if [ "$baseline" = 1 ]; then
    ns=(-r "__ns:=$namespace/uncompensated" -r "arm_angles:=$namespace/arm_angles" -r "predictions:=$namespace/predictions")
    start_node nao_sim_uncompensated nao_sim "${ns[@]}"
    start_node delay_compensator_uncompensated delay_compensator "${ns[@]}" -p mode:=none
    waiting+=(nao_sim_uncompensated delay_compensator_uncompensated)
fi
start_node arm_predictor arm_predictor "${here[@]}" -p "checkpoint:=$out/model.npz"
case "$input" in
    skeleton) start_node angle_extractor angle_extractor "${here[@]}"; waiting+=(angle_extractor) ;;
    hri)
        follow=()
        [ -z "$body" ] || follow=(-p "body_id:=$body")
        start_node hri_bodies hri_bodies "${here[@]}" "${follow[@]}"
        waiting+=(hri_bodies) ;;
esac
for n in "${waiting[@]}"; do gwr_wait_ready "$n" 60; done
outputs=("$namespace/predictions" "$namespace/joint_commands")
[ "$input" = arm_angles ] || outputs+=("$namespace/arm_angles")
[ "$baseline" = 0 ] || outputs+=("$namespace/uncompensated/joint_commands")
gwr_wait_matched bag_recorder 30 "${outputs[@]}"
# start once every consumer of the replayed topic (and the recorder) is matched, so nothing is lost;
# several recorded bodies: hri_bodies finds them in the graph once the player publishes (a few seconds)
case "$input" in
    skeleton) subscribers=2; delay=1.0 ;;
    arm_angles) subscribers=$((3 + baseline)); delay=1.0 ;;
    hri) if [ -n "$body" ]; then subscribers=1; delay=1.0; else subscribers=0; delay=3.0; fi ;;
esac
if [ "$sim_time" = 1 ]; then timing=(-p clock:=true -p restamp:=false -p use_sim_time:=false); else timing=(-p restamp:=true); fi
topics="$(IFS=,; echo "${played[*]}")"
renames=()
[ "${#remaps[@]}" = 0 ] || renames=(-p "remap:=[$(IFS=,; echo "${remaps[*]}")]")
start_node bag_player bag_player "${here[@]}" -p "bag:=$bag" -p "topics:=[$topics]" "${renames[@]}" -p "rate:=$rate" \
    "${timing[@]}" -p "wait_for_subscribers:=$subscribers" -p "start_delay_s:=$delay"
status=0
gwr_wait_exit bag_player || status=$?
sleep 1.5  # the robots finish the last commands (their delay)
gwr_stop_all
trap - EXIT
gwr_log "results in $out (bag/, model.npz, *.log); summary: gwr-predictor report $out"
exit "$status"
