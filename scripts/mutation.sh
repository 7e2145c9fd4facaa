#!/usr/bin/env bash
# Mutation testing of the core math modules with mutmut (make mutation).  A maintainers'
# habit, not part of make test; results and the list of equivalent mutants: docs/mutation.md.
#
# Usage: bash scripts/mutation.sh [MODULE...]
#   MODULE: boxes kalman association kernel_histograms search_region sparse_factorization
#   (default: all)
# Environment: MUTATION_JOBS (parallel mutant runs, default 2);
#   MUTATION_RERUN=1: keep build/mutation/MODULE from an earlier run and run only the
#   mutants that its results.txt does not list as killed, against the current test files
#   (adding tests cannot revive a killed mutant, as long as mk_tracker/ is unchanged: the
#   script refuses when the module's source differs from the copy in that folder);
#   MUTATION_RERUN_SKIP=REGEX (with MUTATION_RERUN=1): mutants whose names match the
#   extended regular expression keep their earlier status and are not rerun (e.g. those
#   docs/mutation.md argues equivalent, which only cost time).
#
# Each module is mutated alone, with only its own test file(s), in a fresh copy of the
# package and the tests under build/mutation/MODULE/ (mutmut reads its settings from a
# setup.cfg in the folder it runs in, and the repository's setup.cfg is not for that).
# Every run sets MK_TRACKER_NO_NUMBA=1: mutmut replaces each function by a dispatcher that
# numba cannot compile, so the numba-compiled loops run as plain Python, through the tests
# that call them directly (their results are compared with the numpy reference paths).
# mutmut comes from requirements/mutation.txt, installed into .venv-mutation, which sees
# .venv's packages through a .pth file; .venv is not changed.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
MVENV="$ROOT/.venv-mutation"
REQ="$ROOT/requirements/mutation.txt"
WORK="$ROOT/build/mutation"
CACHE="${XDG_CACHE_HOME:-$HOME/.cache}/mk_tracker"
WHEELHOUSE="$CACHE/wheelhouse"
PYTHON_BIN="${MK_PYTHON:-python3.11}"
JOBS="${MUTATION_JOBS:-2}"

say() { printf '[mutation] %s\n' "$*"; }
fail() { printf '[mutation] ERROR: %s\n' "$*" >&2; exit 1; }

# module -> source file and test files
declare -A SOURCE=(
  [boxes]=mk_tracker/boxes.py
  [kalman]=mk_tracker/kalman.py
  [association]=mk_tracker/tracking/association.py
  [kernel_histograms]=mk_tracker/tracking/kernel_histograms.py
  [search_region]=mk_tracker/tracking/search_region.py
  [sparse_factorization]=mk_tracker/detection/sparse_factorization.py
)
declare -A TESTS=(
  [boxes]="test/test_boxes.py"
  [kalman]="test/test_kalman.py"
  [association]="test/tracking/test_association.py"
  [kernel_histograms]="test/tracking/test_kernel_histograms.py"
  [search_region]="test/tracking/test_kernel_histograms.py"
  [sparse_factorization]="test/detection/test_sparse_factorization.py"
)
ORDER=(boxes kalman association kernel_histograms search_region sparse_factorization)

MODULES=("$@")
[ "${#MODULES[@]}" -gt 0 ] || MODULES=("${ORDER[@]}")
for m in "${MODULES[@]}"; do
  [ -n "${SOURCE[$m]:-}" ] || fail "unknown module '$m' (known: ${ORDER[*]})"
done
[ -x "$VENV/bin/python" ] || fail "$VENV is missing; run make env first"

# ---- the mutation environment ----------------------------------------------------------
SITE="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
KEY="$( { cat "$REQ"; printf '%s\n' "$SITE"; } | sha256sum | cut -c1-16)"
STAMP="$MVENV/.mk_tracker_mutation_stamp"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$KEY" ] || [ ! -x "$MVENV/bin/mutmut" ]; then
  say "preparing $MVENV (mutmut from requirements/mutation.txt)"
  [ -x "$MVENV/bin/python" ] || "$PYTHON_BIN" -m venv "$MVENV"
  rm -f "$STAMP"
  MSITE="$("$MVENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  # .venv's packages (and its .pth files: the editable mk_tracker, the ROS wheels) after
  # this environment's own
  printf 'import site; site.addsitedir(%s)\n' "'$SITE'" > "$MSITE/zz_mk_tracker_venv.pth"
  mkdir -p "$WHEELHOUSE"
  if ! "$MVENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
       --no-index --find-links "$WHEELHOUSE" -r "$REQ" >/dev/null 2>&1; then
    say "downloading the pinned wheels of requirements/mutation.txt into $WHEELHOUSE (once)"
    "$MVENV/bin/python" -m pip download --quiet --disable-pip-version-check --no-deps \
        --dest "$WHEELHOUSE" -r "$REQ" 2>&1 | grep -v 'is ignored: it is neither' || true
    "$MVENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
        --no-index --find-links "$WHEELHOUSE" -r "$REQ" \
      || fail "installing requirements/mutation.txt into $MVENV failed"
  fi
  echo "$KEY" > "$STAMP"
fi

# ---- one mutmut run per module ---------------------------------------------------------
mkdir -p "$WORK"
SUMMARY="$WORK/summary.txt"
: > "$SUMMARY"
for m in "${MODULES[@]}"; do
  dir="$WORK/$m"
  if [ "${MUTATION_RERUN:-0}" = 1 ]; then
    [ -f "$dir/results.txt" ] || fail "MUTATION_RERUN=1: no earlier results in $dir"
    cmp -s "$ROOT/${SOURCE[$m]}" "$dir/${SOURCE[$m]}" \
      || fail "MUTATION_RERUN=1: ${SOURCE[$m]} changed since the run in $dir; run without it"
    for t in ${TESTS[$m]}; do
      cp "$ROOT/$t" "$dir/$t"
      [ ! -d "$dir/mutants" ] || { mkdir -p "$dir/mutants/$(dirname "$t")"; cp "$ROOT/$t" "$dir/mutants/$t"; }
    done
    mapfile -t names < <(awk -F': ' 'NF == 2 && $2 != "killed" {gsub(/^ +/, "", $1); print $1}' \
                          "$dir/results.txt" | { if [ -n "${MUTATION_RERUN_SKIP:-}" ]; then
                            grep -Ev -- "$MUTATION_RERUN_SKIP" || true; else cat; fi; })
    say "$m: rerunning the ${#names[@]} mutants not killed before (log: $dir/rerun.log)"
    start=$SECONDS
    cp "$dir/results.txt" "$dir/results.before.txt"
    if [ "${#names[@]}" -gt 0 ]; then
      (cd "$dir" && MK_TRACKER_NO_NUMBA=1 "$MVENV/bin/mutmut" run --max-children "$JOBS" \
          "${names[@]}" > rerun.log 2>&1) \
        || { tail -n 30 "$dir/rerun.log" >&2; fail "mutmut run failed for $m"; }
    fi
    (cd "$dir" && MK_TRACKER_NO_NUMBA=1 "$MVENV/bin/mutmut" results --all true \
        > results.new.txt 2>/dev/null)
    # the earlier status of each mutant, replaced by the new one for those rerun
    awk -F': ' 'NR == FNR {if (NF == 2) {gsub(/^ +/, "", $1); new[$1] = $2}; next}
                NF == 2 {gsub(/^ +/, "", $1); s = $2;
                         if ($2 != "killed" && ($1 in new) && new[$1] != "not checked") s = new[$1];
                         print "    " $1 ": " s}' \
        "$dir/results.new.txt" "$dir/results.before.txt" > "$dir/results.txt"
    counts="$(awk -F': ' 'NF == 2 {n[$2]++; t++} END {printf "%d mutants", t;
             for (k in n) printf ", %s %d", k, n[k]}' "$dir/results.txt")"
    line="$m (${SOURCE[$m]}): $counts; rerun of ${#names[@]} in $((SECONDS - start)) s"
    echo "$line" | tee -a "$SUMMARY"
    grep -v ': killed$' "$dir/results.txt" | sed 's/^ *//' >> "$SUMMARY" || true
    continue
  fi
  rm -rf "$dir"
  mkdir -p "$dir"
  (cd "$ROOT" && tar cf - --exclude=__pycache__ --exclude='*.nbi' --exclude='*.nbc' \
      mk_tracker test) | (cd "$dir" && tar xf -)
  {
    echo "[mutmut]"
    echo "source_paths = mk_tracker"
    echo "only_mutate = ${SOURCE[$m]}"
    echo "pytest_add_cli_args_test_selection ="
    for t in ${TESTS[$m]}; do echo "    $t"; done
    # workers fork from a server that only collected the tests: with the default ("fork")
    # they fork from mutmut's main process after it ran every test, and inherit its
    # module caches (lookup tables, step matrices), which hides mutants behind them
    echo "process_isolation = forkserver"
    echo "pytest_add_cli_args ="
    echo "    -p"
    echo "    no:cacheprovider"
  } > "$dir/setup.cfg"
  say "$m: mutating ${SOURCE[$m]}, tests: ${TESTS[$m]} (log: $dir/run.log)"
  start=$SECONDS
  (cd "$dir" && MK_TRACKER_NO_NUMBA=1 "$MVENV/bin/mutmut" run --max-children "$JOBS" \
      > run.log 2>&1) || { tail -n 30 "$dir/run.log" >&2; fail "mutmut run failed for $m"; }
  (cd "$dir" && MK_TRACKER_NO_NUMBA=1 "$MVENV/bin/mutmut" results --all true \
      > results.txt 2>/dev/null)
  counts="$(awk -F': ' 'NF == 2 {n[$2]++; t++} END {printf "%d mutants", t;
           for (k in n) printf ", %s %d", k, n[k]}' "$dir/results.txt")"
  line="$m (${SOURCE[$m]}): $counts; $((SECONDS - start)) s"
  echo "$line" | tee -a "$SUMMARY"
  grep -v ': killed$' "$dir/results.txt" | sed 's/^ *//' >> "$SUMMARY" || true
done
say "summary: $SUMMARY (show a mutant: cd build/mutation/MODULE && ../../../.venv-mutation/bin/mutmut show NAME)"
