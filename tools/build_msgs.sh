#!/usr/bin/env bash
# Build the interface package msgs/train_dynamics_msgs (ament_cmake + rosidl) with colcon,
# from the Jazzy wheels of requirements.txt, and install it INTO the virtual environment
# (the prefix the message wheels themselves use: messages in lib/python3.X/site-packages,
# libraries in lib/, interface files in share/), so that nothing else needs setting:
# the venv's Python finds train_dynamics_msgs.msg, and the wheels' bootstrap
# (ros_wheels_bootstrapper) already puts <venv>/lib on LD_LIBRARY_PATH.
#
#   tools/build_msgs.sh [VENV]        (default .venv; run from anywhere)
#
# Needs cmake >= 3.8 and a C/C++ compiler from the system (docs/install.md).
# Idempotent: the include-path fix below changes a file only where the wheel's path is still
# there, and colcon rebuilds in a build folder of its own (build/msgs, log/msgs).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=$(cd "${1:-.venv}" && pwd -P)
VPY="$VENV/bin/python"
[ -x "$VPY" ] || { echo "build_msgs: no Python at $VPY (make venv first)" >&2; exit 2; }
command -v cmake >/dev/null || { echo "build_msgs: cmake >= 3.8 is needed (apt-get install cmake)" >&2; exit 2; }
command -v c++ >/dev/null || { echo "build_msgs: a C++ compiler is needed (apt-get install g++)" >&2; exit 2; }

# 1. The message wheels' exported CMake targets (e.g. std_msgs::std_msgs__rosidl_generator_py)
#    name the include folders of the machine that built them (/opt/python/cp3XX-cp3XX/...);
#    CMake refuses a target whose include folder does not exist. Point them at this Python's
#    and this numpy's include folders.
PYINC=$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
NPINC=$("$VPY" -c 'import numpy; print(numpy.get_include())')
WHEEL_PY='/opt/python/cp3[0-9]+-cp3[0-9]+'
fixed=0
while IFS= read -r -d '' f; do
  sed -i -E \
    -e "s#${WHEEL_PY}/lib/python3\.[0-9]+/site-packages/numpy/_core/include#${NPINC}#g" \
    -e "s#${WHEEL_PY}/include/python3\.[0-9]+#${PYINC}#g" "$f"
  fixed=$((fixed + 1))
done < <(grep -rlZE --include='*.cmake' "${WHEEL_PY}/" "$VENV/share" || true)
echo "build_msgs: include paths fixed in $fixed .cmake files of the wheels"

# 2. A previous install of the package goes first (colcon never removes a file, and a message
#    renamed or removed would stay importable).
PURELIB=$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
rm -rf "$VENV/share/train_dynamics_msgs" "$VENV/include/train_dynamics_msgs" \
  "$PURELIB"/train_dynamics_msgs "$PURELIB"/train_dynamics_msgs-*
rm -f "$VENV"/lib/libtrain_dynamics_msgs__*.so \
  "$VENV"/share/ament_index/resource_index/*/train_dynamics_msgs \
  "$VENV"/share/colcon-core/packages/train_dynamics_msgs

# 3. colcon build into the venv's prefix (merge layout: one prefix, as the wheels).
export PATH="$VENV/bin:$PATH"
export CMAKE_PREFIX_PATH="$VENV${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
start=$(date +%s)
"$VENV/bin/colcon" --log-base log/msgs build --base-paths msgs \
  --packages-select train_dynamics_msgs --build-base build/msgs \
  --install-base "$VENV" --merge-install --event-handlers console_cohesion+ \
  --cmake-args -DPython3_EXECUTABLE="$VPY" -DBUILD_TESTING=OFF
"$VPY" -c 'from train_dynamics_msgs.msg import TrainState; TrainState()'
echo "build_msgs: train_dynamics_msgs installed into $VENV in $(( $(date +%s) - start )) s"
