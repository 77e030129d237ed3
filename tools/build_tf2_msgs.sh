#!/usr/bin/env bash
# Usage: tools/build_tf2_msgs.sh VENV_DIR
#
# Makes `from tf2_msgs.msg import TFMessage` work in a pip-only ROS 2 Jazzy
# venv (tf2_msgs is not on PyPI): the same as
#   tools/build_interfaces.sh VENV_DIR tf2_msgs
# which see for how (built once with cmake from tools/interfaces/tf2_msgs,
# then cached; exits at once when TFMessage already loads). A cold build needs
# cmake, a C/C++ compiler and the Python headers (Debian: cmake g++ python3-dev).
set -euo pipefail
case "${1:-}" in
  -h|--help) sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"; exit 0 ;;
esac
if [ $# -ne 1 ] || [ "${1#-}" != "$1" ]; then
  echo "build_tf2_msgs: usage: $0 VENV_DIR (see --help)" >&2
  exit 1
fi
ME=build_tf2_msgs exec "$(dirname "${BASH_SOURCE[0]}")/build_interfaces.sh" "$1" tf2_msgs
