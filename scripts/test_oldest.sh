#!/usr/bin/env bash
# Runs the test suite with the oldest supported libraries, those of Ubuntu 24.04 + ROS 2
# Jazzy from apt (requirements/oldest.txt: numpy 1.26.4, OpenCV 4.6.0, SciPy 1.11.4,
# numba 0.58.1, pandas 2.1.4), so that a colcon build there runs the code we test here.
#
# .venv-oldest holds only those packages (installed --no-deps from the wheelhouse cache,
# downloaded once) and sees .venv's other packages -- rclpy, vision_msgs, pytest, the
# editable mk_tracker -- through a .pth file, after its own; .venv is not changed.  The
# ROS wheels' shared libraries are found through .venv's LD_LIBRARY_PATH.
#
# Usage: bash scripts/test_oldest.sh [pytest arguments]   (default: the whole suite but
#   the colcon build test, which builds with .venv's interpreter anyway)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
OVENV="$ROOT/.venv-oldest"
REQ="$ROOT/requirements/oldest.txt"
CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/mk_tracker"
WHEELHOUSE="$CACHE/wheelhouse"
PYTHON_BIN="${MK_PYTHON:-python3.11}"

say() { printf '[test_oldest] %s\n' "$*"; }
fail() { printf '[test_oldest] ERROR: %s\n' "$*" >&2; exit 1; }

[ -x "$VENV/bin/python" ] || fail "$VENV is missing; run make env first"
SITE="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
KEY="$( { cat "$REQ"; printf '%s\n' "$SITE"; } | sha256sum | cut -c1-16)"
STAMP="$OVENV/.mk_tracker_oldest_stamp"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$KEY" ]; then
  say "preparing $OVENV (requirements/oldest.txt)"
  rm -rf "$OVENV"
  "$PYTHON_BIN" -m venv "$OVENV"
  OSITE="$("$OVENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  printf 'import site; site.addsitedir(%s)\n' "'$SITE'" > "$OSITE/zz_mk_tracker_venv.pth"
  mkdir -p "$WHEELHOUSE"
  if ! "$OVENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
       --no-index --find-links "$WHEELHOUSE" -r "$REQ" >/dev/null 2>&1; then
    say "downloading the wheels of requirements/oldest.txt into $WHEELHOUSE (once)"
    "$OVENV/bin/python" -m pip download --quiet --disable-pip-version-check --no-deps \
        --dest "$WHEELHOUSE" -r "$REQ" 2>&1 | grep -v 'is ignored: it is neither' || true
    "$OVENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
        --no-index --find-links "$WHEELHOUSE" -r "$REQ" \
      || fail "installing requirements/oldest.txt into $OVENV failed"
  fi
  echo "$KEY" > "$STAMP"
fi

# the library path .venv's ROS wheels set up for themselves (their bootstrapper re-executes
# Python with it; here it is taken from .venv and passed on)
LDP="$("$VENV/bin/python" -c 'import os; print(os.environ.get("LD_LIBRARY_PATH", ""))')"
export LD_LIBRARY_PATH="$LDP" _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
"$OVENV/bin/python" - <<'PY'
import cv2, numba, numpy, pandas, scipy
print(f"[test_oldest] numpy {numpy.__version__}, OpenCV {cv2.__version__}, SciPy "
      f"{scipy.__version__}, numba {numba.__version__}, pandas {pandas.__version__}")
PY
cd "$ROOT"
if [ "$#" -eq 0 ]; then
  set -- -q -rR test --deselect test/ros/test_colcon_build.py
fi
exec "$OVENV/bin/python" -m pytest -p no:cacheprovider "$@"
