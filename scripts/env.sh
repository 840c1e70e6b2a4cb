#!/usr/bin/env bash
# Run a command inside the project's environment: the venv plus the built workspace,
# the way `ros2 run` sees it on a full ROS 2 install.
#
#   scripts/env.sh python scripts/evaluate.py --help
#   scripts/env.sh python -m swarm_agent.agent_node --ros-args -p agent_id:=3
#
# Run `make bootstrap` once first (make test / make demo do it for you).
set -eo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
WS="$ROOT/ros2_ws"

if [ ! -x "$VENV/bin/python" ] || [ ! -f "$WS/install/local_setup.sh" ]; then
  echo "env.sh: the environment is not built yet; run: make bootstrap" >&2
  exit 1
fi
if [ $# -eq 0 ]; then
  echo "usage: scripts/env.sh CMD [ARGS...]" >&2
  exit 2
fi

# shellcheck disable=SC1091
source "$VENV/bin/activate"
if [ -z "${ROS_DISTRO:-}" ]; then
  # PyPI-wheel mode: the venv is the underlay.
  export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
  export ROS_DISTRO=jazzy
fi
# colcon's setup scripts read unset variables.
set +u
# shellcheck disable=SC1091
source "$WS/install/local_setup.sh"
export PYTHONPATH="$ROOT/scripts${PYTHONPATH:+:$PYTHONPATH}"
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
exec "$@"
