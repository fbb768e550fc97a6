# Source me: makes sure the repo's .venv exists with the pinned requirements, then sets the
# environment every gwr_predictor process needs. Safe to source repeatedly.
# shellcheck shell=bash

GWR_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export GWR_ROOT
GWR_VENV="$GWR_ROOT/.venv"

_gwr_stamp="$(cat "$GWR_ROOT/requirements.txt" "$GWR_ROOT/setup.py" | sha256sum | cut -c1-16)"
if [ ! -x "$GWR_VENV/bin/python" ] || [ "$(cat "$GWR_VENV/.gwr-stamp" 2>/dev/null)" != "$_gwr_stamp" ]; then
    echo "[gwr_predictor] setting up $GWR_VENV (pinned requirements, first use only; about a minute)" >&2
    _py="${GWR_PYTHON:-$(command -v python3.11 || command -v python3.12 || command -v python3.10 || command -v python3)}"
    "$_py" -m venv "$GWR_VENV" || return 1 2>/dev/null || exit 1
    "$GWR_VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$GWR_ROOT/requirements.txt" \
        || { echo "[gwr_predictor] pip install failed" >&2; return 1 2>/dev/null || exit 1; }
    "$GWR_VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$GWR_ROOT" \
        || { echo "[gwr_predictor] installing the package failed" >&2; return 1 2>/dev/null || exit 1; }
    echo "$_gwr_stamp" > "$GWR_VENV/.gwr-stamp"
fi
unset _gwr_stamp _py

export VIRTUAL_ENV="$GWR_VENV"
# This checkout's code first: a .venv shared between checkouts (git worktrees) holds an editable
# install of only one of them, and console scripts do not put the working directory on sys.path.
export PYTHONPATH="$GWR_ROOT${PYTHONPATH:+:$PYTHONPATH}"
export PATH="$GWR_VENV/bin:$PATH"
# Discovery stays on this machine unless the user widens it on purpose (see README).
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-42}"
export AMENT_PREFIX_PATH="${AMENT_PREFIX_PATH:-$GWR_VENV}"
# Single-threaded BLAS: the learner's vectors are small, and threads fight on 2-core machines.
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
export MPLBACKEND=Agg
