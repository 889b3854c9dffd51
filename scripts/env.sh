# Sourced by the scripts: repository paths, ROS environment, a catkin workspace inside
# the repository (.catkin_ws, ignored by git) whose src/ links to the package.
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# MECHANISM_SIM_WS: another workspace (parallel builds of one checkout stay apart).
WS="${MECHANISM_SIM_WS:-$REPO/.catkin_ws}"
# The ROS Python modules live under /usr/bin/python3, not a pyenv python3 earlier in PATH.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"
export ROS_HOME="${ROS_HOME:-$WS/ros_home}"
export ROS_LOG_DIR="${ROS_LOG_DIR:-$WS/log}"
export PYTHONNOUSERSITE=1
unset PYTHONPATH PYENV_VERSION

ws_setup() {
  mkdir -p "$WS/src"
  [ -L "$WS/src/mechanism_sim" ] || ln -sfn "$REPO" "$WS/src/mechanism_sim"
  # rospack crawls the repository: it must not find the package again inside a workspace
  touch "$WS/CATKIN_IGNORE" "$WS/rospack_nosubdirs"
}

ws_source() {
  # shellcheck disable=SC1091
  set +u
  source "$WS/devel/setup.bash"
  set -u
}

ws_build() {
  ws_setup
  # rosbag_storage pulls in ament_cmake (Debian), which runs the Python3 CMake finds: /usr/bin/python3
  (cd "$WS" && catkin_make -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE=/usr/bin/python3 -j2 "$@" > "$WS/build.log" 2>&1) || {
    tail -60 "$WS/build.log" >&2
    echo "build failed (full log: $WS/build.log)" >&2
    return 1
  }
}
