"""Where the default thermal detector spends its time on the real BU-TIV-lab clip (512x512
mono8, counter masked as in ``bench_real_thermal.py``): thread time per frame by pass kind
(full-frame passes every T_c frames, tracking passes), a cProfile by own time, and the
split of the compiled block loop (``block_support._support_loops``) into its stages,
measured by re-running each of its calls with copies of the loop cut after a stage
(gather + skip rule; + kernel variances; + covariance (3.5); the whole loop adds
Algorithm 1).  Not a test: nothing is asserted.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 nice -n 10 \\
        .venv/bin/python benchmarks/profile_real_thermal.py

Frames come from ``compare_detector_versions.py``'s cache (decoded on first use).
"""

from __future__ import annotations

import argparse
import cProfile
import inspect
import io
import pstats
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from compare_detector_versions import COUNTER_REGION, clip_frames  # noqa: E402

from mk_tracker.detection import block_support  # noqa: E402
from mk_tracker.frame_processing import build_detector  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402


def run(data, profiler=None, spy=None):
    cfg = load_pipeline_config()
    det = build_detector(cfg.method, cfg.detector, cfg.threshold, COUNTER_REGION)
    times, modes = [], []
    for frame, stamp in zip(data["frames"], data["stamps"]):
        if profiler:
            profiler.enable()
        t0 = time.thread_time()
        det.process(frame, stamp * 1e-9, encoding=str(data["encoding"]))
        times.append(time.thread_time() - t0)
        if profiler:
            profiler.disable()
        modes.append(det.last_mode)
    return np.array(times) * 1e3, np.array(modes)


def cut_loops():
    """Compiled copies of the block loop that stop after each stage (``name -> kernel``)."""
    import numba
    src = inspect.getsource(block_support._support_loops)
    cuts = {"gather + skip rule": ("            _levels_block_variance(x, table, var)",
                                   "            factored += 1\n            continue"),
            "+ kernel variances": ("            factored += 1\n            if lockstep:",
                                   "            factored += 1\n            continue\n"
                                   "            if lockstep:"),
            "+ covariance (3.5)": ("                _levels_block_covariance(x, table, same, "
                                   "cross, sigmas[waiting])\n",
                                   "                _levels_block_covariance(x, table, same, "
                                   "cross, sigmas[waiting])\n                continue\n")}
    out = {}
    for k, (name, (old, new)) in enumerate(cuts.items()):
        if old not in src:
            raise SystemExit(f"cannot cut the loop at {name!r}: its source changed")
        ns = dict(block_support.__dict__)
        exec(src.replace("def _support_loops", f"def _cut{k}").replace(old, new, 1), ns)
        out[name] = numba.njit(nogil=True)(ns[f"_cut{k}"])
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir())
                        / "mk_tracker_butiv_frames.npz")
    parser.add_argument("--stage-frames", type=int, default=200,
                        help="frames whose block-loop calls are split into stages")
    args = parser.parse_args(argv)
    if not args.cache.exists():
        clip_frames(args.cache)
    data = dict(np.load(args.cache))
    run(data)                                          # numba caches loaded
    ms, modes = run(data)
    print("| pass | frames | thread ms median | p90 | mean |\n|---|---|---|---|---|")
    for kind in ("startup", "reconfiguration", "tracking"):
        x = ms[modes == kind]
        if x.size:
            print(f"| {kind} | {x.size} | {np.median(x):.2f} | {np.percentile(x, 90):.2f} | "
                  f"{x.mean():.2f} |")
    print(f"| all (from frame 10) | {ms[10:].size} | {np.median(ms[10:]):.2f} | "
          f"{np.percentile(ms[10:], 90):.2f} | {ms[10:].mean():.2f} |\n")
    prof = cProfile.Profile()
    run(data, prof)
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).strip_dirs().sort_stats("tottime").print_stats(12)
    print("```\n" + buf.getvalue().strip() + "\n```\n")
    fused = block_support._fused_kernel()
    calls = []

    def spy(*a):
        calls.append([v.copy() if isinstance(v, np.ndarray) else v for v in a])
        return fused(*a)

    block_support._FUSED[0] = spy
    try:
        sub = {k: v[:args.stage_frames] for k, v in data.items() if k != "encoding"}
        sub["encoding"] = data["encoding"]
        run(sub)
    finally:
        block_support._FUSED[0] = fused
    kernels = {**cut_loops(), "whole loop (+ Algorithm 1)": fused}
    best = {name: [] for name in kernels}
    for a in calls:
        for name, kernel in kernels.items():
            b = list(a)
            ts = []
            for _ in range(4):                  # first call compiles / warms the caches
                b[-2], b[-1] = np.zeros_like(a[-2]), np.zeros_like(a[-1])
                t0 = time.thread_time()
                kernel(*b)
                ts.append(time.thread_time() - t0)
            best[name].append(min(ts[1:]) * 1e3)
    print(f"block loop, {len(calls)} calls of the first {args.stage_frames} frames, "
          "median thread ms of the fastest of 3 runs per call:\n")
    print("| loop cut after | ms per call |\n|---|---|")
    for name, v in best.items():
        print(f"| {name} | {np.median(v):.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
