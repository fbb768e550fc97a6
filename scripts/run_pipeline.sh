#!/usr/bin/env bash
# Run the live pipeline for a while and record it:
#   skeleton_source -> angle_extractor -> arm_predictor -> delay_compensator -> nao_sim
# plus, unless --no-baseline, an uncompensated delay_compensator (mode none) + nao_sim pair in the
# NS/uncompensated namespace (/uncompensated without --namespace) fed by the same angles, and a
# bag_recorder started first.
#
# usage: scripts/run_pipeline.sh [--seconds N] [--out DIR] [--params-dir DIR] [--scenario YAML]
#                                [--checkpoint FILE] [--predictor NAME] [--no-baseline] [--render]
#                                [--namespace NS] [--tf]
#   --seconds N        how long the source runs (default 60)
#   --out DIR          run folder: bag/, model.npz, one log per node, ros_log/ (default results/run_<time>)
#   --params-dir DIR   folder with <node>.yaml (default config/)
#   --scenario YAML    extra params file applied to every node after its own (e.g. config/scenario_*.yaml)
#   --checkpoint FILE  start the learner from this model (copied to DIR/model.npz, which it then updates)
#   --predictor NAME   the learner's model (arm_predictor's `predictor` parameter), after the params files
#   --no-baseline      no uncompensated robot
#   --render           the compensated robot writes PNG pictures to DIR/frames/
#   --namespace NS     run every node in namespace NS (e.g. robot1: /robot1/arm_angles, /robot1/uncompensated/...);
#                      pipelines in different namespaces share one ROS domain without crossing
#   --tf               also start the TF that RViz needs to draw the robots (a robot_state_publisher per robot,
#                      the camera and baseline transforms, on NS/tf): needs robot_state_publisher and tf2_ros
#                      from a ROS 2 install (checked at start). Without it nothing publishes TF: the PyPI
#                      wheels have no tf2_msgs. Foxglove needs no TF (robot_description + joint_states).
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=env.sh
source "$HERE/env.sh"
# shellcheck source=lib.sh
source "$HERE/lib.sh"

seconds=60
out=""
params_dir="$GWR_ROOT/config"
scenario=""
checkpoint=""
predictor=""
baseline=1
render=0
namespace=""
tf=0
while [ $# -gt 0 ]; do
    case "$1" in
        --seconds) seconds="$(gwr_value "$@")"; shift 2 ;;
        --out) out="$(gwr_value "$@")"; shift 2 ;;
        --params-dir) params_dir="$(gwr_value "$@")"; shift 2 ;;
        --scenario) scenario="$(gwr_value "$@")"; shift 2 ;;
        --checkpoint) checkpoint="$(gwr_value "$@")"; shift 2 ;;
        --predictor) predictor="$(gwr_value "$@")"; shift 2 ;;
        --no-baseline) baseline=0; shift ;;
        --render) render=1; shift ;;
        --namespace) namespace="$(gwr_value "$@")"; shift 2 ;;
        --tf) tf=1; shift ;;
        -h|--help) gwr_usage "$0"; exit 0 ;;
        *) gwr_die "unknown argument $1 (see --help)" ;;
    esac
done
[[ "$seconds" =~ ^[0-9]+$ ]] || gwr_die "--seconds must be a whole number, got $seconds"
[ -d "$params_dir" ] || gwr_die "--params-dir $params_dir is not a folder"
[ -z "$scenario" ] || [ -f "$scenario" ] || gwr_die "--scenario $scenario not found"
[ -z "$checkpoint" ] || [ -f "$checkpoint" ] || gwr_die "--checkpoint $checkpoint not found"
namespace="$(gwr_namespace "$namespace")" || exit 1
if [ "$tf" = 1 ]; then gwr_tf_check; fi
out="$(gwr_run_folder "$out" run)"
[ ! -e "$out/bag" ] || gwr_die "$out/bag exists already: choose another --out"
export ROS_LOG_DIR="$out/ros_log"
if [ -n "$checkpoint" ]; then
    cp "$checkpoint" "$out/model.npz"
fi

trap 'gwr_stop_all' EXIT
trap 'gwr_log "interrupted"; exit 130' INT TERM

args() { gwr_node_args "$1" "$params_dir" "$scenario"; }
start_node() {  # start_node LABEL NODE [extra ROS args...]
    local label="$1" node="$2"
    shift 2
    local a
    mapfile -t a < <(args "$node")
    gwr_start "$label" "$out" "$node" "${a[@]}" "$@"
}

gwr_log "run folder $out (ROS_DOMAIN_ID=$ROS_DOMAIN_ID, namespace ${namespace:-/})"
# every node runs in the pipeline's namespace (none: the root)
here=()
[ -z "$namespace" ] || here+=(-r "__ns:=$namespace")
start_node bag_recorder bag_recorder "${here[@]}" -p "path:=$out/bag"
gwr_wait_ready bag_recorder 60
frames=()
if [ "$render" = 1 ]; then frames=(-p "render_dir:=$out/frames"); fi
start_node nao_sim nao_sim "${here[@]}" "${frames[@]}"
start_node delay_compensator delay_compensator "${here[@]}"
if [ "$baseline" = 1 ]; then
    # the uncompensated pair reads the pipeline's shared topics, not its own namespace's
    ns=(-r "__ns:=$namespace/uncompensated" -r "arm_angles:=$namespace/arm_angles" -r "predictions:=$namespace/predictions")
    start_node nao_sim_uncompensated nao_sim "${ns[@]}"
    start_node delay_compensator_uncompensated delay_compensator "${ns[@]}" -p mode:=none
fi
if [ "$tf" = 1 ]; then
    gwr_start_tf "$out" "$namespace" "$baseline"
else
    gwr_log "no TF: RViz cannot draw the robots without it (--tf starts it on a ROS 2 install; Foxglove needs none)"
fi
learner=(-p "checkpoint:=$out/model.npz")
[ -z "$predictor" ] || learner+=(-p "predictor:=$predictor")
start_node arm_predictor arm_predictor "${here[@]}" "${learner[@]}"
start_node angle_extractor angle_extractor "${here[@]}"
for n in nao_sim delay_compensator arm_predictor angle_extractor; do gwr_wait_ready "$n" 60; done
if [ "$baseline" = 1 ]; then
    gwr_wait_ready nao_sim_uncompensated 60
    gwr_wait_ready delay_compensator_uncompensated 60
fi
# the recorder hears every publisher of the pipeline's streams, then the first frame goes out once
# angle_extractor and the recorder are matched on the skeleton
baseline_commands="$namespace/uncompensated/joint_commands"
[ "$baseline" = 1 ] || baseline_commands=""
gwr_wait_matched bag_recorder 30 "$namespace/arm_angles" "$namespace/predictions" "$namespace/joint_commands" \
    $baseline_commands
start_node skeleton_source skeleton_source "${here[@]}" -p wait_for_subscribers:=2
gwr_wait_ready skeleton_source 60
gwr_log "pipeline running for $seconds s"
status=0
gwr_wait_seconds "$seconds" || status=1
gwr_stop_all
trap - EXIT
gwr_log "results in $out: bag/ (recording), model.npz (learner), *.log (one per node)"
if [ "$status" != 0 ]; then
    gwr_log "a node stopped early: see the logs above"
fi
exit "$status"
