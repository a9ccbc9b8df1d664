#!/usr/bin/env bash
# Build a YARP release from its source archive into a prefix of its own, for
# the tests' YARP matrix (PyPI has only YARP 3.5). Built once per machine and
# cached; a second run with the same archive takes milliseconds.
#
#   scripts/build_yarp.sh VERSION [ARCHIVE]
#
# ARCHIVE defaults to $YBG_YARP_SOURCES/yarp-VERSION.tar.xz, where
# YBG_YARP_SOURCES defaults to ../shared/vendor beside the repository. The
# prefix is $YBG_CACHE/yarp-VERSION (YBG_CACHE: ~/.cache/ybgc); it holds
# bin/ (yarpserver, yarp, yarprun, ...), lib/cmake/YARP (CMake config) and
# lib/python3.X/site-packages (the Python bindings, for the venv's Python).
# A prefix is complete when its stamp file .ybg-built names the archive's
# checksum and this recipe's version; anything else there is rebuilt.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
version=${1:?usage: scripts/build_yarp.sh VERSION [ARCHIVE]}
sources=${YBG_YARP_SOURCES:-$root/../shared/vendor}
archive=${2:-$sources/yarp-$version.tar.xz}
cache=${YBG_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/ybgc}
prefix=$cache/yarp-$version
venv=${YBG_VENV:-$root/.venv}
vpy=$venv/bin/python
jobs=${YBG_BUILD_JOBS:-$(nproc)}
# bump when the build settings below change: every cached prefix is rebuilt
recipe=4

log() { printf '\033[1m[yarp %s]\033[0m %s\n' "$version" "$*" >&2; }
die() { printf 'error: %s\n' "$*" >&2; exit 1; }

[ -f "$archive" ] || die "no source archive $archive (set YBG_YARP_SOURCES to the folder holding yarp-$version.tar.xz)"
[ -x "$vpy" ] || die "no $vpy: run scripts/setup.sh first (the bindings are built for the venv's Python)"

sum=$(sha256sum "$archive" | cut -d' ' -f1)
pyver=$("$vpy" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
want="archive=$sum recipe=$recipe python=$pyver"
if [ -f "$prefix/.ybg-built" ] && [ "$(cat "$prefix/.ybg-built")" = "$want" ]; then
  log "cached in $prefix"
  exit 0
fi

need_apt=()
for p in cmake g++ make swig python3-dev libace-dev libsqlite3-dev libtinyxml-dev \
         libeigen3-dev libedit-dev libjpeg-dev xz-utils; do
  [ "$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null)" = "install ok installed" ] || need_apt+=("$p")
done
if [ ${#need_apt[@]} -gt 0 ]; then
  log "apt-get install ${need_apt[*]}"
  sudo_cmd=""; [ "$(id -u)" -ne 0 ] && sudo_cmd=sudo
  export DEBIAN_FRONTEND=noninteractive
  $sudo_cmd apt-get update -qq
  $sudo_cmd apt-get install -y -qq --no-install-recommends "${need_apt[@]}" >/dev/null
fi

# YCM: YARP 4 needs >= 0.18 (PyPI's ycm_cmake_modules is 0.15, enough for 3.x
# only), so it is built from its archive beside YARP's when there is one.
mkdir -p "$cache"
ycm_prefix=""
ycm_archive=$(ls "$(dirname "$archive")"/ycm-*.tar.xz 2>/dev/null | sort -V | tail -n1 || true)
if [ -n "$ycm_archive" ]; then
  ycm_version=$(basename "$ycm_archive" .tar.xz); ycm_version=${ycm_version#ycm-}
  ycm_prefix=$cache/ycm-$ycm_version
  ycm_sum=$(sha256sum "$ycm_archive" | cut -d' ' -f1)
  if [ ! -f "$ycm_prefix/.ybg-built" ] || [ "$(cat "$ycm_prefix/.ybg-built")" != "$ycm_sum" ]; then
    log "building YCM $ycm_version"
    rm -rf "$ycm_prefix"
    work=$(mktemp -d "$cache/.ycm-build.XXXXXX")
    tar -xJf "$ycm_archive" -C "$work"
    cmake -S "$work/ycm-$ycm_version" -B "$work/build" -DCMAKE_INSTALL_PREFIX="$ycm_prefix" >"$work/log" 2>&1 \
      && cmake --build "$work/build" >>"$work/log" 2>&1 \
      && cmake --install "$work/build" >>"$work/log" 2>&1 \
      || { tail -n 40 "$work/log" >&2; die "YCM $ycm_version did not build"; }
    echo "$ycm_sum" >"$ycm_prefix/.ybg-built"
    rm -rf "$work"
  fi
fi

mkdir -p "$cache"
rm -rf "$prefix"
work=$(mktemp -d "$cache/.yarp-$version-build.XXXXXX")
trap 'rm -rf "$work"' EXIT
log "building from $(basename "$archive") into $prefix ($jobs jobs)"
t0=$(date +%s)
tar -xJf "$archive" -C "$work"
src=$(find "$work" -mindepth 1 -maxdepth 1 -type d | head -n1)
prefix_path="$ycm_prefix"
if [ -z "$prefix_path" ]; then
  prefix_path=$("$vpy" -c 'import ycm_cmake_modules, os; print(os.path.dirname(ycm_cmake_modules.__file__))' 2>/dev/null || true)
fi
# What the tests never load is left out: the device and port-monitor plugins
# (a bridge reads and writes ports; it opens no device) but the fake robot's
# (fakeMotionControl behind controlBoard_nws_yarp, fakeFrameGrabber behind
# frameGrabber_nws_yarp, each pair joined by deviceBundler: `yarpdev` runs them
# for tests/test_init.py), YARP_math,
# robotinterface and the tools built on them. A plugin is turned off by its
# ENABLE_ option only where its CMakeLists honours it (some test another
# name, and configure then fails on their missing files): those few stay.
# The libraries, carriers, yarpserver, yarp, yarprun, yarpmanager-console and
# the Python bindings are built, at -O1: these builds serve the tests' YARP
# matrix, where compile time counts and the modules' speed is measured on
# PyPI's YARP (bench/). About half the time of the full Release build.
kept=(deviceBundler fakeMotionControl fakeFrameGrabber frameGrabber_nws_yarp controlBoard_nws_yarp)
skipped=()
for n in "${kept[@]}"; do skipped+=("-DENABLE_yarpmod_$n=ON"); done
for kind in devices:yarpmod portmonitors:yarppm; do
  while IFS= read -r f; do
    for n in $(grep -hoE "yarp_prepare_plugin\(\s*[A-Za-z0-9_]+" "$f" | sed -E 's/yarp_prepare_plugin\(\s*//'); do
      [[ " ${kept[*]} " == *" $n "* ]] && continue
      grep -q "SKIP_$n\b" "$f" && skipped+=("-DENABLE_${kind#*:}_$n=OFF")
    done
  done < <(grep -rlE "yarp_prepare_plugin\(" "$src/src/${kind%%:*}" --include=CMakeLists.txt)
done
for o in libYARP_math libYARP_robotinterface yarprobotinterface yarpdatadumper yarpActionsPlayer \
         yarpAudioPlayer yarpRobotDescriptionInfo yarpconnectionsinfo RobotTestingFramework_ADDONS; do
  skipped+=("-DYARP_COMPILE_$o=OFF")
done
step() {  # step NAME COMMAND...: run, log its time; on failure the log's tail
  local name=$1 t=$(date +%s); shift
  "$@" >>"$work/build.log" 2>&1 || { tail -n 60 "$work/build.log" >&2; rm -rf "$prefix"; die "YARP $version did not build: $name failed (log above)"; }
  log "$name: $(( $(date +%s) - t )) s"
}
step configure cmake -S "$src" -B "$work/build" \
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DCMAKE_C_FLAGS_RELEASE="-O1 -DNDEBUG" \
    -DCMAKE_INSTALL_PREFIX="$prefix" -DCMAKE_PREFIX_PATH="$prefix_path" \
    -DYARP_COMPILE_GUIS=OFF -DYARP_COMPILE_TESTS=OFF -DYARP_COMPILE_EXAMPLES=OFF \
    -DYARP_COMPILE_BINDINGS=ON -DCREATE_PYTHON=ON -DPython3_EXECUTABLE="$vpy" \
    "${skipped[@]}"
step build cmake --build "$work/build" -j "$jobs"
step install cmake --install "$work/build"

site=$(ls -d "$prefix"/lib/python3*/site-packages 2>/dev/null | head -n1)
[ -n "$site" ] && [ -x "$prefix/bin/yarpserver" ] && [ -x "$prefix/bin/yarprun" ] && [ -x "$prefix/bin/yarpmanager-console" ] && [ -f "$prefix/lib/cmake/YARP/YARPConfig.cmake" ] \
  || die "YARP $version installed without its tools (yarpserver, yarprun, yarpmanager-console), CMake config or Python bindings in $prefix"
for n in "${kept[@]}"; do
  [ -f "$prefix/lib/yarp/yarp_$n.so" ] || die "YARP $version installed without its $n device ($prefix/lib/yarp/yarp_$n.so)"
done
PYTHONPATH="$site" "$vpy" -c 'import yarp' \
  || die "the Python bindings of YARP $version in $site do not import"
echo "$want" >"$prefix/.ybg-built"
log "built in $(( $(date +%s) - t0 )) s"
