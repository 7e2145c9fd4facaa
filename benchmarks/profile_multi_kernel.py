"""Where the multiple-kernel tracker spends its time, and before/after comparisons.

Runs :class:`mk_tracker.tracking.multi_kernel.MultiKernelTracker` (1, 2 and 4 kernels, defaults
otherwise) on the sequences of ``benchmarks/bench_single_target.py`` -- every TUD-Campus
person, OTB Crossing and the synthetic 640x480 occlusion scenes -- with the frames decoded
once beforehand, and prints per group the median CPU milliseconds per ``refine`` (which
includes the HSV conversion of the search region), the mean number of iterations of
Algorithm 1 and the mean centre error.

Implementations compared in the same process on the same frames:

* ``compiled``: this working tree, numba kernels (the default when numba is installed);
* ``numpy``: this working tree with the numpy reference path (``backend="numpy"``);
* ``REV`` (with ``--baseline REV``): ``mk_tracker/tracking/kernel_histograms.py``,
  ``search_region.py`` (where it exists) and ``multi_kernel.py`` as they were at git revision ``REV``, loaded under other
  module names (everything else is shared).

With ``--opencv CSRT`` OpenCV's CSRT tracker is timed on the same frames (needs
opencv-contrib: run from the benchmark venv of ``benchmarks/requirements.txt``).  Then a
cProfile of the ``compiled`` 2-kernel tracker over the same frames (``--profile``).  Writes a
markdown report (``--output``) with the command and the machine load.  Example::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 PYTHONPATH=. \\
        /tmp/bench_venv/bin/python benchmarks/profile_multi_kernel.py --baseline 612b333 \\
        --opencv CSRT --jitter 3 --profile --output docs/profile_multi_kernel.md
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
             "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import cProfile  # noqa: E402
import importlib.util  # noqa: E402
import io  # noqa: E402
import pstats  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from bench_single_target import (otb_sequences, synthetic_sequences,  # noqa: E402
                                 tud_sequences)
from mk_tracker.boxes import clip_box  # noqa: E402
from mk_tracker.tracking import multi_kernel  # noqa: E402
from mk_tracker.evaluation.metrics import single_target_metrics  # noqa: E402

KERNEL_COUNTS = (2, 1, 4)


def load_baseline(rev: str, workdir: Path):
    """``multi_kernel`` module of git revision ``rev`` with its own appearance-model modules
    (``kernel_histograms``, and ``search_region`` and ``multi_kernel_config`` where the
    revision has them), loaded under
    other names; the rest of the package is shared with this working tree."""
    names = {}
    stems = ("kernel_histograms", "search_region", "multi_kernel_config",
             "multi_kernel")                                  # dependency order
    for stem in stems:
        text = None
        for path in (f"mk_tracker/tracking/{stem}.py", f"mk_tracker/{stem}.py"):
            shown = subprocess.run(["git", "-C", str(REPO), "show", f"{rev}:{path}"],
                                   capture_output=True, text=True)
            if shown.returncode == 0:
                text = shown.stdout
                break
        if text is None:
            if stem in ("search_region", "multi_kernel_config"):   # before the splits
                continue
            raise SystemExit(f"{stem}.py not found at revision {rev}")
        for other in stems:
            for package in ("mk_tracker.tracking", "mk_tracker"):
                text = text.replace(f"from {package}.{other} import",
                                    f"from baseline_{other} import")
        alias = f"baseline_{stem}"
        path = workdir / f"{alias}.py"
        path.write_text(text, encoding="utf-8")
        spec = importlib.util.spec_from_file_location(alias, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[alias] = module
        spec.loader.exec_module(module)
        names[stem] = module
    return names["multi_kernel"]


def _numba_version() -> str:
    try:
        import numba
    except ImportError:
        return "not installed"
    return numba.__version__


def load_sequences(only: str):
    seqs = synthetic_sequences() + otb_sequences() + tud_sequences()
    seqs = [s for s in seqs if only.lower() in s.name.lower()]
    out = []
    for s in seqs:
        frames = [np.ascontiguousarray(f) for f in s.frames()]
        out.append((s, frames))
    return out


def group_of(name: str) -> str:
    if "TUD" in name:
        return "TUD-Campus persons"
    if "OTB" in name:
        return "OTB Crossing"
    return "synthetic 640x480"


def make_tracker(module, n_kernels: int, backend: str | None):
    config = module.MultiKernelConfig(num_kernels=n_kernels)
    if backend is None:
        return module.MultiKernelTracker(config)
    return module.MultiKernelTracker(config, backend=backend)


def run_one(module, backend, n_kernels, seq, frames, jitter=0.0):
    """(per-frame CPU seconds, iterations, metrics, boxes) of one tracker on one sequence,
    started from the first box moved by ``jitter`` px."""
    tracker = make_tracker(module, n_kernels, backend)
    state = tracker.start(frames[0], tuple(v + jitter for v in seq.init_box))
    times, iters, boxes = [], [], [seq.init_box]
    for frame in frames[1:]:
        t0 = time.process_time()
        res = tracker.refine(frame, state)
        times.append(time.process_time() - t0)
        iters.append(res.iterations)
        boxes.append(state.box if res.lost else res.box)
    metrics = single_target_metrics(boxes[1:], seq.truth[1:len(boxes)])
    return times, iters, metrics, boxes


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default="", help="git revision to compare against")
    parser.add_argument("--only", default="", help="substring filter on sequence names")
    parser.add_argument("--kernels", default="2,1,4", help="kernel counts, comma separated")
    parser.add_argument("--repeats", type=int, default=3,
                        help="passes over the sequences; the per-frame minimum is kept")
    parser.add_argument("--jitter", type=int, default=0,
                        help="also run every tracker N more times from first boxes moved by "
                             "k * 1e-9 px (k = 1..N): the spread of the centre errors shows "
                             "how far rounding-level changes move the results")
    parser.add_argument("--no-numpy", action="store_true", help="skip the numpy backend")
    parser.add_argument("--profile", action="store_true", help="cProfile the 2-kernel run")
    parser.add_argument("--opencv", default="",
                        help="comma-separated OpenCV trackers (e.g. CSRT,KCF) timed on the same "
                             "frames for comparison; needs opencv-contrib (the benchmark venv)")
    parser.add_argument("--output", default="", help="markdown report to write")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    load0 = os.getloadavg()
    seqs = load_sequences(args.only)
    kernels = [int(k) for k in args.kernels.split(",")]

    impls = [("compiled", multi_kernel, "auto")]
    if not args.no_numpy:
        impls.append(("numpy", multi_kernel, "numpy"))
    tmp = tempfile.TemporaryDirectory()
    if args.baseline:
        impls.append((args.baseline, load_baseline(args.baseline, Path(tmp.name)), None))

    # warm-up: compile (or load from numba's cache) before anything is timed
    s0, f0 = seqs[0]
    for _, module, backend in impls:
        for nk in kernels:
            run_one(module, backend, nk, s0, f0[:3])

    # results[impl][nk][seq] = (times (min over repeats), iterations, metrics, boxes)
    results: dict = {name: {nk: {} for nk in kernels} for name, _, _ in impls}
    passes: dict = {}       # (impl, kernels, sequence) -> per-frame times of every pass
    for rep in range(args.repeats):
        for seq, frames in seqs:
            for nk in kernels:
                order = impls if rep % 2 == 0 else impls[::-1]
                for name, module, backend in order:
                    t, it, m, boxes = run_one(module, backend, nk, seq, frames)
                    passes.setdefault((name, nk, seq.name), []).append(t)
                    prev = results[name][nk].get(seq.name)
                    if prev is not None:
                        t = list(np.minimum(prev[0], t))
                    results[name][nk][seq.name] = (t, it, m, boxes)
    # OpenCV trackers on the same frames (median CPU ms of update, as bench_single_target.py)
    cv_results: dict = {}
    for name in [n for n in args.opencv.split(",") if n]:
        owners = [o for o in (cv2, getattr(cv2, "legacy", None))
                  if o is not None and hasattr(o, f"Tracker{name}_create")]
        if not owners:
            print(f"OpenCV {name} is not available here", file=sys.stderr)
            continue
        for seq, frames in seqs:
            tracker = getattr(owners[0], f"Tracker{name}_create")()
            box = clip_box(seq.init_box, frames[0].shape[1], frames[0].shape[0])
            tracker.init(frames[0], tuple(int(round(v)) for v in box))
            times = []
            for frame in frames[1:]:
                t0 = time.process_time()
                try:
                    tracker.update(frame)
                except cv2.error:
                    pass
                times.append(time.process_time() - t0)
            cv_results.setdefault(name, {})[seq.name] = times

    # errs[impl][nk][seq] = mean centre errors of the unmoved and the jittered starts
    errs = {name: {nk: {s.name: [results[name][nk][s.name][2]["mean_center_error"]]
                        for s, _ in seqs} for nk in kernels} for name, _, _ in impls}
    for j in range(1, args.jitter + 1):
        for seq, frames in seqs:
            for nk in kernels:
                for name, module, backend in impls:
                    m = run_one(module, backend, nk, seq, frames, j * 1e-9)[2]
                    errs[name][nk][seq.name].append(m["mean_center_error"])
    load1 = os.getloadavg()

    groups = sorted({group_of(s.name) for s, _ in seqs})
    lines = []
    header = ("| kernels | implementation | " +
              " | ".join(f"{g}: ms (per-frame min) / iterations / centre error" for g in groups)
            + " |")
    lines += [header, "|---|---|" + "---|" * len(groups)]
    for nk in kernels:
        for name, _, _ in impls:
            cells = []
            for g in groups:
                names = [s.name for s, _ in seqs if group_of(s.name) == g]
                rs = [results[name][nk][n] for n in names]
                ms_min = float(np.median(np.concatenate([r[0] for r in rs]))) * 1e3
                # the median of each pass over the group's frames, then their median
                ms = float(np.median([np.median(np.concatenate(
                    [passes[(name, nk, n)][k] for n in names])) for k in range(args.repeats)]))
                ms *= 1e3
                its = float(np.mean(np.concatenate([r[1] for r in rs])))
                # group mean centre error of each start (unmoved, jittered ...)
                means = np.mean([errs[name][nk][n] for n in names], axis=0)
                err = f"{means[0]:.2f}"
                if len(means) > 1:
                    err += f" ({means.min():.2f}-{means.max():.2f})"
                cells.append(f"{ms:.2f} ({ms_min:.2f}) / {its:.2f} / {err}")
            lines.append(f"| {nk} | {name} | " + " | ".join(cells) + " |")
    for name, per_seq in cv_results.items():
        cells = []
        for g in groups:
            names = [s.name for s, _ in seqs if group_of(s.name) == g]
            ms = float(np.median(np.concatenate([per_seq[n] for n in names]))) * 1e3
            cells.append(f"{ms:.2f} / - / -")
        lines.append(f"| - | OpenCV {name} | " + " | ".join(cells) + " |")
    # how long each implementation's boxes stay with the first one's, per kernel count
    diffs = []
    for nk in kernels:
        for name, _, _ in impls[1:]:
            worst = 0.0
            agree = []      # frames before the boxes first differ by more than 0.01 px
            for s, _ in seqs:
                a = np.array(results[impls[0][0]][nk][s.name][3][1:], dtype=float)
                b = np.array(results[name][nk][s.name][3][1:], dtype=float)
                gap = np.max(np.abs(a - b), axis=1) if a.size else np.zeros(0)
                worst = max(worst, float(gap.max()) if gap.size else 0.0)
                off = np.flatnonzero(gap > 0.01)
                agree.append(int(off[0]) if off.size else len(gap))
            n_same = sum(n_ok == len(results[name][nk][seq.name][3]) - 1
                         for n_ok, (seq, _) in zip(agree, seqs))
            diffs.append(f"{nk} kernels, {impls[0][0]} vs {name}: boxes within 0.01 px for "
                         f"the first {min(agree)}-{max(agree)} frames (median "
                         f"{int(np.median(agree))}) of a sequence; {n_same} "
                         f"of {len(seqs)} sequences throughout; largest difference {worst:.1f} px")
    table = "\n".join(lines)
    print(table)
    print("\n".join(diffs))

    prof_text = ""
    if args.profile:
        prof = cProfile.Profile()
        for seq, frames in seqs:
            tracker = make_tracker(multi_kernel, 2, "auto")
            state = tracker.start(frames[0], seq.init_box)
            prof.enable()
            for frame in frames[1:]:
                tracker.refine(frame, state)
            prof.disable()
        buf = io.StringIO()
        pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(18)
        prof_text = buf.getvalue()
        print(prof_text)

    if args.output:
        python = sys.executable if "bench_venv" in sys.executable else ".venv/bin/python"
        cmd = "OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 PYTHONPATH=. " \
              f"{python} benchmarks/profile_multi_kernel.py " + \
              " ".join(argv if argv is not None else sys.argv[1:])
        n_frames = sum(len(f) - 1 for _, f in seqs)
        doc = ["# Multiple-kernel tracker: time per target and profile", "",
               "Produced by:", "", "```", cmd.strip(), "```", "",
               f"Machine: {os.cpu_count()} cores, load average (1 min) {load0[0]:.2f} at the "
               f"start and {load1[0]:.2f} at the end; numpy {np.__version__}, OpenCV "
               f"{cv2.__version__}, numba {_numba_version()}, one thread.", "",
               f"{len(seqs)} sequences, {n_frames} refinements per tracker and pass. ms = "
               "median over all frames of a group of the process CPU time of one `refine` "
               f"(HSV conversion of the search region included), the median over {args.repeats}"
               " passes (the figure `bench_single_target.py` reports is one such pass); in "
               "brackets the median of each frame's fastest pass, the cost without "
               "interference from other processes' use of the shared cores and caches; "
               "iterations = mean iterations of Algorithm 1 per "
               "frame; centre error = mean over the group's sequences of the mean centre "
               "error in px (a lost result scores the last state box, as in "
               "`bench_single_target.py`)"
               + (f"; in brackets the range over the unmoved start and {args.jitter} starts "
                  "moved by k * 1e-9 px, k = 1.." + str(args.jitter) + " (the iteration is "
                  "sensitive to rounding: such a move changes single sequences by pixels)"
                  if args.jitter else "") + ".", "", table, "", *[f"* {d}" for d in diffs], ""]
        if prof_text:
            doc += ["## cProfile of the compiled 2-kernel tracker (all sequences, one pass)",
                    "", "```", prof_text.strip(), "```", ""]
        Path(args.output).write_text("\n".join(doc) + "\n", encoding="utf-8")
        print(f"wrote {args.output}")
    tmp.cleanup()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
