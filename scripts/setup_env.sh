#!/usr/bin/env bash
# Creates or updates the project environment .venv (Python 3.11) in the repository:
#   1. installs the pinned requirements/ from a wheelhouse in the user's cache
#      (downloaded once, when a pinned wheel is missing there),
#   2. installs mk_tracker itself in editable mode,
#   3. builds the interface packages of interfaces/ -- vision_msgs (definitions from
#      mk_tracker/messages/definitions/vision_msgs), then mk_tracker_msgs (which uses
#      vision_msgs) -- with the rosidl generators of the ros-jazzy-* wheels in a separate
#      build environment, packs each as a wheel (scripts/interface_wheel.py) cached by
#      the hash of its inputs, and installs the wheels into .venv.
# Idempotent: a stamp holding the hash of every input makes a repeated run a no-op.
#
# Usage: bash scripts/setup_env.sh [--force]
# Environment: MK_PYTHON (default python3.11), XDG_CACHE_HOME (cache in
#   ${XDG_CACHE_HOME:-$HOME/.cache}/mk_tracker), MK_BUILD_JOBS (default: nproc).
# Prerequisites: python3.11 with venv; cmake >= 3.21 and a C/C++ compiler (only when
#   an interface package is not in the cache yet).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
PYTHON_BIN="${MK_PYTHON:-python3.11}"
CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/mk_tracker"
WHEELHOUSE="$CACHE/wheelhouse"
BUILD_VENV="$CACHE/build-venv"
REQ="$ROOT/requirements"
MSG_DIR="$ROOT/mk_tracker/messages/definitions/vision_msgs"
VISION_DIR="$ROOT/interfaces/vision_msgs"
MSGS_DIR="$ROOT/interfaces/mk_tracker_msgs"
WHEEL_SCRIPT="$ROOT/scripts/interface_wheel.py"
STAMP="$VENV/.mk_tracker_setup_stamp"
VISION_MSGS_VERSION="4.1.1"
FORCE=0

say() { printf '[setup_env] %s\n' "$*"; }
fail() { printf '[setup_env] ERROR: %s\n' "$*" >&2; exit 1; }

for arg in "$@"; do
  case "$arg" in
    --force) FORCE=1 ;;
    -h|--help) sed -n '2,17p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
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
MSGS_FILES=("$MSGS_DIR"/msg/*.msg "$MSGS_DIR"/srv/*.srv)
[ "${#MSGS_FILES[@]}" -gt 0 ] || fail "no .msg/.srv files in $MSGS_DIR"
REQ_KEY="$(hash_inputs "$REQ/runtime.txt" "$REQ/build.txt" "$REQ/constraints.txt")"
VISION_KEY="$(hash_inputs "${MSG_FILES[@]}" "$VISION_DIR/CMakeLists.txt" "$VISION_DIR/package.xml" \
  "$REQ/build.txt" "$REQ/constraints.txt" "$WHEEL_SCRIPT")"
# mk_tracker_msgs is built against this vision_msgs: its key includes vision_msgs' key
MSGS_KEY="$(hash_inputs "${MSGS_FILES[@]}" "$MSGS_DIR/CMakeLists.txt" "$MSGS_DIR/package.xml" \
  "$REQ/build.txt" "$REQ/constraints.txt" "$WHEEL_SCRIPT" | cut -c1-8)$(printf '%s' "$VISION_KEY" | cut -c1-8)"
ENV_KEY="$(hash_inputs "$REQ/runtime.txt" "$REQ/constraints.txt" "$ROOT/setup.py" "$ROOT/setup.cfg" \
  "$ROOT/package.xml" "$ROOT/scripts/setup_env.sh")-$VISION_KEY-$MSGS_KEY"

# The build of an interface package (only when it is not cached) needs cmake and C/C++ compilers;
# checked before anything is installed so that a missing tool is reported at once.
check_build_tools() {
  command -v cmake >/dev/null 2>&1 \
    || fail "cmake not found; it is needed once to build the interfaces (Ubuntu: apt install cmake)."
  "$PYTHON_BIN" - "$(cmake --version | head -n1)" <<'EOF' \
    || fail "cmake >= 3.21 is needed to build the interfaces (found: $(cmake --version | head -n1))."
import re, sys
found = tuple(int(x) for x in re.search(r"(\d+)\.(\d+)", sys.argv[1]).groups())
sys.exit(found < (3, 21))
EOF
  CXX_BIN="${CXX:-}"
  [ -n "$CXX_BIN" ] || CXX_BIN="$(command -v c++ || command -v g++ || command -v clang++ || true)"
  [ -n "$CXX_BIN" ] || fail "no C++ compiler found; one is needed once to build the interfaces (Ubuntu: apt install g++)."
  CC_BIN="${CC:-}"
  [ -n "$CC_BIN" ] || CC_BIN="$(command -v cc || command -v gcc || command -v clang || true)"
  [ -n "$CC_BIN" ] || fail "no C compiler found; one is needed once to build the interfaces (Ubuntu: apt install gcc)."
}

# ---- fast path -------------------------------------------------------------------
if [ "$FORCE" = 0 ] && [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$ENV_KEY" ] \
   && [ -x "$VENV/bin/python" ]; then
  say "environment up to date ($VENV)"
  exit 0
fi

# The interface packages, in build order: name, source folder, version, cache key,
# wheel distribution, extra cmake arguments.
MSGS_VERSION="$(sed -n 's:.*<version>\(.*\)</version>.*:\1:p' "$MSGS_DIR/package.xml" | head -n1)"
IFACE_NAMES=(vision_msgs mk_tracker_msgs)
declare -A IFACE_SRC=([vision_msgs]="$VISION_DIR" [mk_tracker_msgs]="$MSGS_DIR")
declare -A IFACE_VERSION=([vision_msgs]="$VISION_MSGS_VERSION+mk$VISION_KEY"
                          [mk_tracker_msgs]="$MSGS_VERSION+mk$MSGS_KEY")
declare -A IFACE_KEY=([vision_msgs]="$VISION_KEY" [mk_tracker_msgs]="$MSGS_KEY")
declare -A IFACE_DIST=([vision_msgs]=mk_tracker_vision_msgs [mk_tracker_msgs]=mk_tracker_msgs)
declare -A IFACE_CMAKE_ARGS=([vision_msgs]="-DMK_MESSAGE_DIR=$MSG_DIR"
                             [mk_tracker_msgs]="-DMK_PIP_BUILD=ON")

cached_wheel() {  # NAME -> path of the cached wheel, or nothing
  local wheels=("$CACHE/$1/${IFACE_KEY[$1]}/${IFACE_DIST[$1]}"-*.whl)
  [ "${#wheels[@]}" -eq 1 ] && printf '%s\n' "${wheels[0]}"
  return 0
}
NEED_BUILD=0
for name in "${IFACE_NAMES[@]}"; do
  [ -n "$(cached_wheel "$name")" ] || NEED_BUILD=1
done
[ "$FORCE" = 1 ] && NEED_BUILD=1
if [ "$NEED_BUILD" = 1 ]; then
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

# ---- 3. the interface packages ----------------------------------------------------
prepare_build_venv() {
  local build_stamp="$BUILD_VENV/.mk_tracker_build_stamp"
  if [ ! -f "$build_stamp" ] || [ "$(cat "$build_stamp")" != "$REQ_KEY" ]; then
    say "preparing the interface build environment $BUILD_VENV"
    [ -x "$BUILD_VENV/bin/python" ] || "$PYTHON_BIN" -m venv "$BUILD_VENV"
    install_pinned "$BUILD_VENV/bin/python" "$REQ/runtime.txt" "$REQ/build.txt" \
      || fail "installing requirements/build.txt into $BUILD_VENV failed"
    echo "$REQ_KEY" > "$build_stamp"
  fi
}

# build_interface NAME: cmake + rosidl build of interfaces/NAME into a wheel in the cache.
# Packages built earlier in IFACE_NAMES are found in the build environment (their wheels
# are installed there before, see below).
build_interface() {
  local name="$1" work log jobs start
  local out="$CACHE/$name/${IFACE_KEY[$name]}"
  work="$(mktemp -d "$CACHE/$name-build.XXXXXX")"
  log="$work/build.log"
  jobs="${MK_BUILD_JOBS:-$(nproc 2>/dev/null || echo 2)}"
  say "building $name ${IFACE_VERSION[$name]%%+*} (cmake + rosidl, $jobs jobs, about a minute; log: $log)"
  start=$SECONDS
  if ! (
      export AMENT_PREFIX_PATH="$BUILD_VENV" CMAKE_PREFIX_PATH="$BUILD_VENV" \
             PATH="$BUILD_VENV/bin:$PATH" CC="$CC_BIN" CXX="$CXX_BIN"
      cmake -S "${IFACE_SRC[$name]}" -B "$work/build" \
            -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
            -DCMAKE_INSTALL_PREFIX="$work/stage" \
            -DPython3_EXECUTABLE="$BUILD_VENV/bin/python" \
            "${IFACE_CMAKE_ARGS[$name]}" \
        && cmake --build "$work/build" --parallel "$jobs" \
        && cmake --install "$work/build"
    ) >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    fail "building $name failed; full log: $log"
  fi
  mkdir -p "$out"
  "$BUILD_VENV/bin/python" "$WHEEL_SCRIPT" --package "$name" --distribution "${IFACE_DIST[$name]}" \
      --prefix "$work/stage" --out "$out" --version "${IFACE_VERSION[$name]}" >/dev/null
  rm -rf "$work"
  say "built $name in $((SECONDS - start)) s; cached in $out"
}

# install_interface PYTHON NAME: install the cached wheel of NAME unless that version is in.
install_interface() {
  local python="$1" name="$2" wheel installed
  wheel="$(cached_wheel "$name")"
  [ -n "$wheel" ] || fail "expected one $name wheel in $CACHE/$name/${IFACE_KEY[$name]}"
  installed="$("$python" -c 'import importlib.metadata as m, sys; print(m.version(sys.argv[1]))' \
    "${IFACE_DIST[$name]}" 2>/dev/null || true)"
  if [ "$FORCE" = 0 ] && [ "$installed" = "${IFACE_VERSION[$name]}" ]; then
    return 0
  fi
  pip_quiet "$python" -m pip install --quiet "${OFFLINE_PIP[@]}" --no-deps --force-reinstall \
      "$wheel" || fail "installing the $name wheel into $python's environment failed"
}

[ "$NEED_BUILD" = 1 ] && prepare_build_venv
for name in "${IFACE_NAMES[@]}"; do
  if [ "$FORCE" = 1 ] || [ -z "$(cached_wheel "$name")" ]; then
    build_interface "$name"
    [ -n "$(cached_wheel "$name")" ] || fail "expected one $name wheel after the build"
  else
    say "$name found in the cache ($CACHE/$name/${IFACE_KEY[$name]})"
  fi
  # a later package may build on this one (mk_tracker_msgs on vision_msgs): while
  # anything is built, the build environment gets each package too
  if [ "$NEED_BUILD" = 1 ]; then
    install_interface "$BUILD_VENV/bin/python" "$name"
  fi
  say "installing $name ${IFACE_VERSION[$name]} into $VENV"
  install_interface "$VENV/bin/python" "$name"
done

# ---- check and stamp ------------------------------------------------------------------
(cd "$ROOT" && "$VENV/bin/python" -c 'import mk_tracker, rclpy; from vision_msgs.msg import Detection2DArray
from mk_tracker_msgs.msg import TrackedObjectArray; from mk_tracker_msgs.srv import StartTrack') \
  || fail "the environment was installed but mk_tracker / rclpy / vision_msgs / mk_tracker_msgs do not import"
echo "$ENV_KEY" > "$STAMP"
say "environment ready: $VENV (run: .venv/bin/python -m pytest -q test)"
