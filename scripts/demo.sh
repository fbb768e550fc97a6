#!/usr/bin/env bash
# THE DEMO: pretrain offline, run the live ROS 2 pipeline with and without delay compensation,
# and report. Works on a fresh machine (env.sh builds the venv on first use). A few minutes.
#
#   1. gwr-predictor pretrain   the default predictor learns the demonstrator's repetitions 1-8 (~30-60 s)
#   2. scripts/run_pipeline.sh  live pipeline on new repetitions (9-10) for --seconds (default 60),
#                               learning on, from the pretrained model, a compensated robot and an
#                               uncompensated one (namespace /uncompensated), everything recorded
#   3. gwr-predictor report     prediction error at 600 ms, robot lags, neurons, counts, plot
#   4. gwr-predictor render     video.mp4 of the last 20 s next to report.png: the person, the
#                               compensated and the uncompensated Nao side by side
#
# usage: scripts/demo.sh [--seconds N] [--out DIR] [--epochs N] [--scenario YAML] [--predictor NAME] [--render]
#                        [--no-video]
#   --predictor NAME   gwr_experts (default), gated_llm_gwr or hierarchy (the paper)
#   --no-video         skip step 4
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=env.sh
source "$HERE/env.sh"
# shellcheck source=lib.sh
source "$HERE/lib.sh"

seconds=60
out=""
epochs=5
predictor=""
scenario=""
video=1
extra=()
while [ $# -gt 0 ]; do
    case "$1" in
        --seconds) seconds="$(gwr_value "$@")"; shift 2 ;;
        --out) out="$(gwr_value "$@")"; shift 2 ;;
        --epochs) epochs="$(gwr_value "$@")"; shift 2 ;;
        --scenario) scenario="$(gwr_value "$@")"; shift 2 ;;
        --predictor) predictor="$(gwr_value "$@")"; shift 2 ;;
        --render) extra+=(--render); shift ;;
        --no-video) video=0; shift ;;
        -h|--help) gwr_usage "$0"; exit 0 ;;
        *) gwr_die "unknown argument $1 (see --help)" ;;
    esac
done
out="$(gwr_run_folder "$out" demo)"
start=$SECONDS
[ -z "$scenario" ] || extra+=(--scenario "$scenario")
pretrain_args=(--params-file "$GWR_ROOT/config/arm_predictor.yaml")
# the node and the pretraining build the same kind of model
[ -z "$predictor" ] || { pretrain_args+=(--predictor "$predictor"); extra+=(--predictor "$predictor"); }

gwr_log "step 1/4: pretraining offline (${predictor:-gwr_experts, the default})"
gwr-predictor pretrain --out "$out/pretrained.npz" "${pretrain_args[@]}" \
    --epochs "$epochs" --repetitions 8 | tee "$out/pretrain.log"

gwr_log "step 2/4: live pipeline for $seconds s (compensated + uncompensated robot)"
"$HERE/run_pipeline.sh" --seconds "$seconds" --out "$out" --checkpoint "$out/pretrained.npz" "${extra[@]}"

gwr_log "step 3/4: report"
gwr-predictor report "$out"

if [ "$video" = 1 ]; then
    gwr_log "step 4/4: video of the last 20 s"
    render_start=$SECONDS
    gwr-predictor render "$out" --seconds=-20:
    gwr_log "video rendered in $((SECONDS - render_start)) s"
fi
gwr_log "demo finished in $((SECONDS - start)) s; everything is in $out"
