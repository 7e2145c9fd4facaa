#!/usr/bin/env bash
# Creates or updates the project environment .venv (Python 3.11) in the repository:
#   1. installs the pinned requirements/ from a wheelhouse in the user's cache
#      (downloaded once, when a pinned wheel is missing there),
#   2. installs mk_tracker itself in editable mode,
#   3. builds vision_msgs (interfaces/vision_msgs, definitions from
#      mk_tracker/messages/definitions/vision_msgs) with the rosidl generators of the
#      ros-jazzy-* wheels in a separate build environment, packs it as a wheel that is
#      cached by the hash of its inputs, and installs that wheel into .venv.
# Idempotent: a stamp holding the hash of every input makes a repeated run a no-op.
#
# Usage: bash scripts/setup_env.sh [--force]
# Environment: MK_PYTHON (default python3.11), XDG_CACHE_HOME (cache in
#   ${XDG_CACHE_HOME:-$HOME/.cache}/mk_tracker), MK_BUILD_JOBS (default: nproc).
# Prerequisites: python3.11 with venv; cmake >= 3.21 and a C/C++ compiler (only when
#   vision_msgs is not in the cache yet).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
PYTHON_BIN="${MK_PYTHON:-python3.11}"
CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/mk_tracker"
WHEELHOUSE="$CACHE/wheelhouse"
BUILD_VENV="$CACHE/build-venv"
REQ="$ROOT/requirements"
MSG_DIR="$ROOT/mk_tracker/messages/definitions/vision_msgs"
IFACE_DIR="$ROOT/interfaces/vision_msgs"
STAMP="$VENV/.mk_tracker_setup_stamp"
VISION_MSGS_VERSION="4.1.1"
FORCE=0

say() { printf '[setup_env] %s\n' "$*"; }
fail() { printf '[setup_env] ERROR: %s\n' "$*" >&2; exit 1; }

for arg in "$@"; do
  case "$arg" in
    --force) FORCE=1 ;;
    -h|--help) sed -n '2,18p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) fail "unknown argument '$arg' (usage: bash scripts/setup_env.sh [--force])" ;;
  esac
done

# pip on some machines is configured with extra index folders that do not exist;
# its warnings about them are noise, everything else is shown.
pip_quiet() {
  local output status=0
  output="$("$@" 2>&1)" || status=$?
  if [ -n "$output" ]; then
    printf '%s\n' "$output" | grep -v -e 'is ignored: it is neither a file nor a directory' || true
  fi
  return "$status"
}

# Hash of the given files (names and contents) plus the interpreter version.
hash_inputs() {
  {
    printf '%s\n' "$PY_VERSION"
    for f in "$@"; do
      printf '%s\n' "${f#"$ROOT"/}"
      cat "$f"
    done
  } | sha256sum | cut -c1-16
}

# ---- prerequisites -------------------------------------------------------------
command -v "$PYTHON_BIN" >/dev/null 2>&1 \
  || fail "$PYTHON_BIN not found. Install Python 3.11 (Ubuntu: apt install python3.11 python3.11-venv; or pyenv install 3.11) or point MK_PYTHON at it."
PY_VERSION="$("$PYTHON_BIN" -c 'import sys; print(sys.version.split()[0])' 2>/dev/null || true)"
case "$PY_VERSION" in
  3.11.*) ;;
  *) fail "$PYTHON_BIN is Python '${PY_VERSION:-unknown}', but the ros-jazzy-* wheels need Python 3.11." ;;
esac
command -v sha256sum >/dev/null 2>&1 || fail "sha256sum (coreutils) not found."

mkdir -p "$CACHE"
# One setup at a time per user cache (the wheelhouse and build environment are shared).
if command -v flock >/dev/null 2>&1; then
  exec 9>"$CACHE/setup.lock"
  flock 9
fi

shopt -s nullglob
MSG_FILES=("$MSG_DIR"/*.msg)
[ "${#MSG_FILES[@]}" -gt 0 ] || fail "no .msg files in $MSG_DIR"
REQ_KEY="$(hash_inputs "$REQ/runtime.txt" "$REQ/build.txt" "$REQ/constraints.txt")"
VISION_KEY="$(hash_inputs "${MSG_FILES[@]}" "$IFACE_DIR/CMakeLists.txt" "$IFACE_DIR/package.xml" \
  "$REQ/build.txt" "$REQ/constraints.txt" "$ROOT/scripts/vision_msgs_wheel.py")"
ENV_KEY="$(hash_inputs "$REQ/runtime.txt" "$REQ/constraints.txt" "$ROOT/setup.py" "$ROOT/setup.cfg" \
  "$ROOT/package.xml" "$ROOT/scripts/setup_env.sh")-$VISION_KEY"

# The build of vision_msgs (only when it is not cached) needs cmake and C/C++ compilers;
# checked before anything is installed so that a missing tool is reported at once.
check_build_tools() {
  command -v cmake >/dev/null 2>&1 \
    || fail "cmake not found; it is needed once to build vision_msgs (Ubuntu: apt install cmake)."
  "$PYTHON_BIN" - "$(cmake --version | head -n1)" <<'EOF' \
    || fail "cmake >= 3.21 is needed to build vision_msgs (found: $(cmake --version | head -n1))."
import re, sys
found = tuple(int(x) for x in re.search(r"(\d+)\.(\d+)", sys.argv[1]).groups())
sys.exit(found < (3, 21))
EOF
  CXX_BIN="${CXX:-}"
  [ -n "$CXX_BIN" ] || CXX_BIN="$(command -v c++ || command -v g++ || command -v clang++ || true)"
  [ -n "$CXX_BIN" ] || fail "no C++ compiler found; one is needed once to build vision_msgs (Ubuntu: apt install g++)."
  CC_BIN="${CC:-}"
  [ -n "$CC_BIN" ] || CC_BIN="$(command -v cc || command -v gcc || command -v clang || true)"
  [ -n "$CC_BIN" ] || fail "no C compiler found; one is needed once to build vision_msgs (Ubuntu: apt install gcc)."
}

# ---- fast path -------------------------------------------------------------------
if [ "$FORCE" = 0 ] && [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$ENV_KEY" ] \
   && [ -x "$VENV/bin/python" ]; then
  say "environment up to date ($VENV)"
  exit 0
fi

VISION_CACHE="$CACHE/vision_msgs/$VISION_KEY"
VISION_VERSION="$VISION_MSGS_VERSION+mk$VISION_KEY"
VISION_WHEELS=("$VISION_CACHE"/mk_tracker_vision_msgs-*.whl)
if [ "$FORCE" = 1 ] || [ "${#VISION_WHEELS[@]}" -eq 0 ]; then
  check_build_tools
fi

# ---- 1. the virtual environment ------------------------------------------------------
if [ -x "$VENV/bin/python" ]; then
  "$VENV/bin/python" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
    || fail "$VENV exists but is not a Python 3.11 environment; remove it and run again."
  say "updating $VENV"
else
  say "creating $VENV with Python $PY_VERSION"
  "$PYTHON_BIN" -c 'import venv, ensurepip' >/dev/null 2>&1 \
    || fail "$PYTHON_BIN lacks the venv/ensurepip modules (Ubuntu: apt install python3.11-venv)."
  "$PYTHON_BIN" -m venv "$VENV"
fi
rm -f "$STAMP"

# ---- 2. requirements, installed from a wheelhouse in the user's cache ----------------
OFFLINE_PIP=(--no-index --find-links "$WHEELHOUSE" --disable-pip-version-check)

# install_pinned PYTHON REQUIREMENT-FILE...: install without network from the
# wheelhouse; when a wheel is missing there, download the pinned set once and retry.
install_pinned() {
  local python="$1"; shift
  local reqs=() f
  for f in "$@"; do reqs+=(-r "$f"); done
  mkdir -p "$WHEELHOUSE"
  if "$python" -m pip install --quiet "${OFFLINE_PIP[@]}" "${reqs[@]}" \
       -c "$REQ/constraints.txt" >/dev/null 2>&1; then
    return 0
  fi
  say "downloading the pinned wheels into $WHEELHOUSE (network; once per requirements change)"
  pip_quiet "$python" -m pip wheel --quiet --wheel-dir "$WHEELHOUSE" --find-links "$WHEELHOUSE" \
      -r "$REQ/runtime.txt" -r "$REQ/build.txt" -c "$REQ/constraints.txt" \
    || fail "could not download the pinned wheels (is PyPI reachable?)"
  pip_quiet "$python" -m pip install --quiet "${OFFLINE_PIP[@]}" "${reqs[@]}" \
      -c "$REQ/constraints.txt"
}

say "installing requirements/runtime.txt into $VENV"
install_pinned "$VENV/bin/python" "$REQ/runtime.txt" \
  || fail "installing requirements/runtime.txt failed"

say "installing mk_tracker (editable) from $ROOT"
pip_quiet "$VENV/bin/python" -m pip install --quiet "${OFFLINE_PIP[@]}" \
    --no-deps --no-build-isolation --editable "$ROOT" \
  || fail "installing mk_tracker in editable mode failed"

# ---- 3. vision_msgs ---------------------------------------------------------------
if [ "$FORCE" = 1 ] || [ "${#VISION_WHEELS[@]}" -eq 0 ]; then

  BUILD_STAMP="$BUILD_VENV/.mk_tracker_build_stamp"
  if [ ! -f "$BUILD_STAMP" ] || [ "$(cat "$BUILD_STAMP")" != "$REQ_KEY" ]; then
    say "preparing the vision_msgs build environment $BUILD_VENV"
    [ -x "$BUILD_VENV/bin/python" ] || "$PYTHON_BIN" -m venv "$BUILD_VENV"
    install_pinned "$BUILD_VENV/bin/python" "$REQ/runtime.txt" "$REQ/build.txt" \
      || fail "installing requirements/build.txt into $BUILD_VENV failed"
    echo "$REQ_KEY" > "$BUILD_STAMP"
  fi

  WORK="$(mktemp -d "$CACHE/vision_msgs-build.XXXXXX")"
  LOG="$WORK/build.log"
  JOBS="${MK_BUILD_JOBS:-$(nproc 2>/dev/null || echo 2)}"
  say "building vision_msgs $VISION_MSGS_VERSION (cmake + rosidl, $JOBS jobs, about a minute; log: $LOG)"
  start=$SECONDS
  if ! (
      export AMENT_PREFIX_PATH="$BUILD_VENV" CMAKE_PREFIX_PATH="$BUILD_VENV" \
             PATH="$BUILD_VENV/bin:$PATH" CC="$CC_BIN" CXX="$CXX_BIN"
      cmake -S "$IFACE_DIR" -B "$WORK/build" \
            -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
            -DCMAKE_INSTALL_PREFIX="$WORK/stage" \
            -DPython3_EXECUTABLE="$BUILD_VENV/bin/python" \
            -DMK_MESSAGE_DIR="$MSG_DIR" \
        && cmake --build "$WORK/build" --parallel "$JOBS" \
        && cmake --install "$WORK/build"
    ) >"$LOG" 2>&1; then
    tail -n 40 "$LOG" >&2
    fail "building vision_msgs failed; full log: $LOG"
  fi
  mkdir -p "$VISION_CACHE"
  "$BUILD_VENV/bin/python" "$ROOT/scripts/vision_msgs_wheel.py" \
      --prefix "$WORK/stage" --out "$VISION_CACHE" --version "$VISION_VERSION" >/dev/null
  rm -rf "$WORK"
  say "built vision_msgs in $((SECONDS - start)) s; cached in $VISION_CACHE"
  VISION_WHEELS=("$VISION_CACHE"/mk_tracker_vision_msgs-*.whl)
else
  say "vision_msgs found in the cache ($VISION_CACHE)"
fi
[ "${#VISION_WHEELS[@]}" -eq 1 ] || fail "expected one vision_msgs wheel in $VISION_CACHE"

INSTALLED_VISION="$("$VENV/bin/python" -c \
  'import importlib.metadata as m; print(m.version("mk_tracker_vision_msgs"))' 2>/dev/null || true)"
if [ "$FORCE" = 0 ] && [ "$INSTALLED_VISION" = "$VISION_VERSION" ]; then
  say "vision_msgs $VISION_VERSION already installed in $VENV"
else
  say "installing vision_msgs into $VENV"
  pip_quiet "$VENV/bin/python" -m pip install --quiet "${OFFLINE_PIP[@]}" \
      --no-deps --force-reinstall "${VISION_WHEELS[0]}" \
    || fail "installing the vision_msgs wheel failed"
fi

# ---- check and stamp ------------------------------------------------------------------
(cd "$ROOT" && "$VENV/bin/python" -c 'import mk_tracker, rclpy; from vision_msgs.msg import Detection2DArray') \
  || fail "the environment was installed but mk_tracker / rclpy / vision_msgs do not import"
echo "$ENV_KEY" > "$STAMP"
say "environment ready: $VENV (run: .venv/bin/python -m pytest -q test)"
