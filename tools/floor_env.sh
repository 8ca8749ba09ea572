#!/usr/bin/env bash
# The dependency floor, repeatable: build a virtual environment with the versions of
# requirements-floor.txt (what rosdep installs on Ubuntu 24.04: numpy 1.26, scipy 1.11,
# numba 0.59, matplotlib 3.6, PyYAML 6.0.1) on Python 3.12 when there is one, every other
# package of requirements.txt at its requirements-lock.txt pin, and run the tests in it.
#
#   tools/floor_env.sh                    build (when needed), then run the floor test set
#   tools/floor_env.sh build              only build the environment
#   tools/floor_env.sh test [pytest args] only run the tests (extra arguments go to pytest)
#
# Environment:
#   FLOOR_VENV    the environment's folder (default .venv-floor in the repository root)
#   FLOOR_PYTHON  the interpreter that creates it (default python3.12, else python3)
#   FLOOR_TESTS   what pytest runs (default: the folders below; "test" for every test)
#   FLOOR_WHEELS  where a wheel built from source is kept (default the user cache)
#
# The package itself is not installed into the environment: the tests run the repository's
# code through PYTHONPATH (the subprocess nodes inherit it). matplotlib 3.6.3 has no wheel for
# Python 3.12 on the package index; it is built from its source once (a C++ compiler and the
# FreeType headers, Ubuntu's libfreetype-dev, needed; about 3 min), against the system
# FreeType as Ubuntu builds it, with the Qhull sources bundled in scipy's source archive
# (Qhull 2019.1; matplotlib's own download of Qhull 2020.2 from qhull.org is not needed).
# Measured figures and results: docs/install.md, "Versions".
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=${FLOOR_VENV:-$ROOT/.venv-floor}
PY=${FLOOR_PYTHON:-$(command -v python3.12 || command -v python3)}
WHEELS=${FLOOR_WHEELS:-${XDG_CACHE_HOME:-$HOME/.cache}/train_dynamics/floor-wheels}
TESTS=${FLOOR_TESTS:-test/physics test/kernel test/config test/recording test/cli test/ros test/testing}
INDEX=${PIP_INDEX_URL:-https://pypi.org/simple}
VPY=$VENV/bin/python
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT

pin() {  # pin NAME FILE: the version NAME is pinned to in FILE
  sed -n "s/^$1==\([^ ;#]*\).*/\1/Ip" "$2" | head -n 1
}

# matplotlib from its source archive into $WHEELS (no wheel for this Python on the index)
build_matplotlib() {
  local ver=$1 tmp=$2 src qv
  echo "floor_env: building matplotlib $ver from source (no wheel for $("$VPY" -V))"
  "$VPY" -m pip install -q "setuptools==$(pin setuptools requirements.txt)" \
    "wheel==$(pin wheel requirements.txt)" "numpy==$(pin numpy requirements-floor.txt)" \
    'setuptools_scm<8' certifi
  "$VPY" -m pip download -q --no-deps --no-binary :all: -d "$tmp" "matplotlib==$ver"
  tar xzf "$tmp/matplotlib-$ver.tar.gz" -C "$tmp"
  src=$tmp/matplotlib-$ver
  qv=$(sed -n "s/^LOCAL_QHULL_VERSION = '\(.*\)'/\1/p" "$src/setupext.py")
  # Qhull's sources, from scipy's source archive on the package index (sha256 checked)
  "$VPY" - "$INDEX" "$(pin scipy requirements-floor.txt)" "$tmp" <<'EOF'
import hashlib, re, sys, urllib.parse, urllib.request
index, ver, out = sys.argv[1:]
page = urllib.request.urlopen(f'{index.rstrip("/")}/scipy/', timeout=60).read().decode()
href = re.search(rf'href="([^"]*/scipy-{re.escape(ver)}\.tar\.gz)#sha256=([0-9a-f]+)"', page)
url = urllib.parse.urljoin(f'{index.rstrip("/")}/scipy/', href.group(1))
data = urllib.request.urlopen(url, timeout=300).read()
if hashlib.sha256(data).hexdigest() != href.group(2):
    sys.exit(f'floor_env: {url}: sha256 mismatch')
open(f'{out}/scipy-{ver}.tar.gz', 'wb').write(data)
EOF
  local sv; sv=$(pin scipy requirements-floor.txt)
  mkdir -p "$src/build/qhull-$qv/src/libqhull_r"
  tar xzf "$tmp/scipy-$sv.tar.gz" --strip-components=5 -C "$src/build/qhull-$qv/src/libqhull_r" \
    "scipy-$sv/scipy/spatial/qhull_src/src"
  tar xzf "$tmp/scipy-$sv.tar.gz" --strip-components=4 -C "$src/build/qhull-$qv" \
    "scipy-$sv/scipy/spatial/qhull_src/COPYING.txt"
  printf '[libs]\nsystem_freetype = True\n' > "$src/mplsetup.cfg"
  mkdir -p "$WHEELS"
  "$VPY" -m pip wheel -q --no-build-isolation --no-deps -w "$WHEELS" "$src"
}

build() {
  local tmp names mpl tag
  [ -x "$VPY" ] || { echo "floor_env: creating $VENV with $("$PY" -V)"; "$PY" -m venv "$VENV"; }
  touch "$VENV/COLCON_IGNORE"     # a colcon build in the repository root never crawls it
  tmp=$TMP
  # the lock's pins, minus those the floor replaces; requirements.txt minus the same
  names=$(sed -n 's/^\([A-Za-z0-9_.-]*\)==.*/\1/p' requirements-floor.txt | paste -sd '|')
  grep -v -i -E "^($names)==" requirements-lock.txt > "$tmp/constraints.txt"
  grep -v -E '^[[:space:]]*(-c|#|$)' requirements.txt | grep -v -i -E "^($names)==" \
    > "$tmp/requirements.txt"
  mpl=$(pin matplotlib requirements-floor.txt)
  tag=$("$VPY" -c 'import sys; print("cp%d%d" % sys.version_info[:2])')
  if ! ls "$WHEELS"/matplotlib-"$mpl"-"$tag"-*.whl >/dev/null 2>&1 \
     && ! "$VPY" -m pip download -q --only-binary :all: --no-deps -d "$tmp/probe" \
          "matplotlib==$mpl" >/dev/null 2>&1; then
    build_matplotlib "$mpl" "$tmp"
  fi
  "$VPY" -m pip install --find-links "$WHEELS" -r requirements-floor.txt \
    -r "$tmp/requirements.txt" -c "$tmp/constraints.txt"
  "$VPY" -m pip check || echo "floor_env: pip check reports the conflicts above (see docs/install.md)"
}

run_tests() {
  export PYTHONPATH=$ROOT${PYTHONPATH:+:$PYTHONPATH}
  export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST MPLBACKEND=Agg
  "$VPY" -c 'import sys, numpy, scipy, numba, matplotlib, yaml, rclpy
print("floor_env:", sys.version.split()[0], "numpy", numpy.__version__, "scipy", scipy.__version__,
      "numba", numba.__version__, "matplotlib", matplotlib.__version__, "PyYAML", yaml.__version__,
      "rclpy from", rclpy.__file__)'
  # every kernel variant compiled (or loaded) first, as `make test` does
  "$VPY" -m train_dynamics.cli.prebuild
  # shellcheck disable=SC2086
  "$VPY" -m pytest -p no:cacheprovider -q $TESTS "$@"
}

case "${1:-all}" in
  build) build ;;
  test) shift; run_tests "$@" ;;
  all) shift || true; build; run_tests "$@" ;;
  *) echo "usage: tools/floor_env.sh [build | test [pytest args] | all [pytest args]]" >&2; exit 2 ;;
esac
