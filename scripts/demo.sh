#!/usr/bin/env bash
# Run the thesis' Rviz demonstration end to end (after scripts/setup.sh):
# the C++ module for ROS 1 through YARP, then the rclpy node for ROS 2.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
exec "$root/.venv/bin/python" "$root/scripts/demo.py" "$@"
