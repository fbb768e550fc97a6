#!/usr/bin/env bash
# Run the test suite (sets up .venv on first use). Extra arguments go to pytest.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/env.sh"
cd "$GWR_ROOT"
export ROS_LOG_DIR="${ROS_LOG_DIR:-$GWR_ROOT/.test-logs/ros}"
ruff check .
python -m mypy  # the library, as configured in pyproject.toml
exec python -m pytest "$@"
