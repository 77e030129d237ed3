#!/usr/bin/env bash
# One entry point for a fresh machine: ./run.sh demo | test [fast] | bench | sim [ROS args...]
# Each command creates .venv (if needed), installs requirements.txt into it, writes
# setup.py's executables into .venv/bin (running this checkout), keeps ROS discovery on
# this host, then runs.
set -euo pipefail
cd "$(dirname "$0")"

export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export PYTHONUNBUFFERED=1
VENV=.venv
PY="$VENV/bin/python"

# The installed requirements are kept for the next checkout in the user's cache, as hard
# links (no copy): a new clone's .venv is linked from it in seconds instead of installed
# again (about 2 min with pip's cache full). Keyed by requirements.txt and the Python.
VENV_CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/r2d2_sim"

venv_key() { { cat requirements.txt; python3 --version; } | sha256sum | cut -c1-16; }

venv_from_cache() {
  local cached; cached="$VENV_CACHE/venv-$(venv_key)"
  [ -f "$cached/.origin" ] || return 1
  local origin; origin="$(cat "$cached/.origin")"
  rm -rf "$VENV.new"
  cp -al "$cached" "$VENV.new" 2>/dev/null || { rm -rf "$VENV.new"; return 1; }
  # Its scripts name their interpreter by absolute path: this venv's, not the cached one's
  # (written anew, so the cached files keep theirs).
  local script
  for script in $(grep -lIF "$origin" "$VENV.new"/bin/* 2>/dev/null); do
    sed "s|$origin|$PWD/$VENV|g" "$script" > "$script.new"
    chmod --reference="$script" "$script.new" && mv "$script.new" "$script"
  done
  rm -f "$VENV.new/.origin" "$VENV.new/.installed" && touch "$VENV.new/.installed"
  mv -T "$VENV.new" "$VENV"
}

venv_to_cache() {
  local cached; cached="$VENV_CACHE/venv-$(venv_key)"
  [ -d "$cached" ] && return 0
  mkdir -p "$VENV_CACHE" && rm -rf "$cached.$$"
  if cp -al "$VENV" "$cached.$$" 2>/dev/null && echo "$PWD/$VENV" > "$cached.$$/.origin"; then
    mv -T "$cached.$$" "$cached" 2>/dev/null || rm -rf "$cached.$$"
    local old  # the venvs of other requirements go (checkouts keep their own links)
    for old in "$VENV_CACHE"/venv-*; do [ "$old" = "$cached" ] || rm -rf "$old"; done
  else
    rm -rf "$cached.$$"
  fi
}

setup_venv() {
  if [ ! -x "$PY" ]; then
    venv_from_cache || python3 -m venv "$VENV"
  fi
  if [ ! -f "$VENV/.installed" ] || [ requirements.txt -nt "$VENV/.installed" ]; then
    "$PY" -m pip install --quiet --disable-pip-version-check -r requirements.txt
    touch "$VENV/.installed"
    venv_to_cache
  fi
  # setup.py's executables (sim_node, sim_conformance, demo, drive, replay) as small
  # wrappers in .venv/bin that run this checkout, where `pip install .` would put them.
  "$PY" -S tools/console_scripts.py "$VENV"
  export PATH="$PWD/$VENV/bin:$PATH"
  export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
}

setup() {
  setup_venv
  # Interface packages that are not on PyPI (tf2_msgs, simulation_interfaces)
  # for pip-only installs: built once, then cached; ~0.5 s when installed.
  if ! tools/build_interfaces.sh "$VENV"; then
    if [ -n "${R2D2_SIM_CI:-}" ]; then  # CI tests everything: a missing part is a failure
      echo "run.sh: error: the interface packages did not build; CI needs them" >&2
      exit 1
    fi
    tools/build_interfaces.sh --check "$VENV" tf2_msgs \
      || echo "run.sh: tf2_msgs unavailable, TF off" >&2
    tools/build_interfaces.sh --check "$VENV" simulation_interfaces \
      || echo "run.sh: simulation_interfaces unavailable, the simulation_interfaces services are off" >&2
  fi
}

need_xvfb() {
  # The GUI test opens PyBullet's window on a virtual display.
  if ! command -v Xvfb >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
      apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq xvfb >/dev/null
    else
      echo "run.sh: Xvfb is missing; install Debian's xvfb package for the GUI test" >&2
    fi
  fi
}

cmd="${1:-demo}"
shift || true
case "$cmd" in
  demo)  setup; exec "$PY" -m r2d2_sim.apps.demo "$@" ;;
  sim)   setup; exec "$PY" -m r2d2_sim "$@" ;;
  # Three workers on two cores (much of the suite waits on processes and ROS, not the
  # CPU): every ROS test leases a domain of its own. Paths given replace test/.
  # 'test fast': the tiers without ROS (test/model, physics, sim, gym) and the lint checks
  # that run no ROS here (layering, types, mixins, old names, the version), in seconds:
  # only the venv, no interface build; two workers were faster. Tests marked slow
  # (long statistics, soaks) run in the full tier.
  test)  if [ "${1:-}" = fast ]; then
           shift; setup_venv
           exec "$PY" -m pytest -q -p no:cacheprovider -n 2 -m 'not slow' test/model \
             test/physics test/sim test/gym test/lint/test_layers.py test/lint/test_types.py \
             test/lint/test_mixins.py test/lint/test_deprecations.py \
             test/lint/test_changelog.py "$@"
         fi
         setup; need_xvfb
         paths=(test); for arg in "$@"; do [ -e "${arg%%::*}" ] && paths=(); done
         # -rs: every skip says why (under R2D2_SIM_CI, conftest makes a skip a failure).
         # worksteal: an idle worker takes tests queued on the busy one, so a long test
         # queued late does not leave a core idle (clean clones: 8:56 against 9:45). A
         # third worker: 7:58 against 9:47 (the suite used 68 % of two cores on two).
         exec "$PY" -m pytest -q -rs -p no:cacheprovider -n 3 --dist worksteal "${paths[@]}" "$@" ;;
  # The main bench, then several robots in one world, then the test harness's speed.
  bench) setup; "$PY" bench/run.py "$@"; "$PY" bench/fleet.py "$@"
         exec "$PY" bench/lockstep.py "$@" ;;
  *) echo "usage: ./run.sh demo|test [fast]|bench|sim [args...]" >&2; exit 2 ;;
esac
