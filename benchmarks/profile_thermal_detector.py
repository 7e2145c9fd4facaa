"""Where a thermal detector frame spends its time: per-mode CPU medians and a cProfile.

Feeds a synthetic crowd (:func:`mk_tracker.synthetic.crowd_scene`, as the benchmark builds
it) to :class:`mk_tracker.thermal_detector.ThermalDetector`, reports the median CPU time
(``time.process_time``) of full-frame passes and tracking frames, and prints the top
functions of a cProfile run over the same frames, split by mode.  Not a test; run it with
one thread::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 \\
        .venv/bin/python benchmarks/profile_thermal_detector.py --people 5 --frames 100
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import time

import numpy as np

from mk_tracker.synthetic import crowd_scene, paper_scene
from mk_tracker.thermal_detector import ThermalDetector, ThermalDetectorConfig


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--people", type=int, default=5)
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--top", type=int, default=25, help="functions listed per mode")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs (median of all)")
    parser.add_argument("--no-profile", action="store_true")
    args = parser.parse_args(argv)

    warm = ThermalDetector()
    ps = paper_scene(99)
    for i in range(10):
        warm.process(ps.frame(i).thermal, ps.frame(i).stamp)
    scene = crowd_scene(args.people, seed=args.seed, width=args.width, height=args.height,
                        frames=args.frames)
    frames = [scene.frame(i) for i in range(len(scene))]
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    times: dict[str, list[float]] = {}
    for _ in range(args.repeats):
        det = ThermalDetector(ThermalDetectorConfig())
        for fr in frames:
            c0 = time.process_time()
            det.process(fr.thermal, fr.stamp)
            times.setdefault(det.last_mode, []).append((time.process_time() - c0) * 1e3)
    for mode, ts in sorted(times.items()):
        print(f"{mode:16s} median {np.median(ts):6.2f} ms CPU  p90 {np.percentile(ts, 90):6.2f}"
              f"  (n={len(ts)})")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    if args.no_profile:
        return 0
    profiles: dict[str, pstats.Stats] = {}
    det = ThermalDetector(ThermalDetectorConfig())
    for fr in frames:
        prof = cProfile.Profile()
        prof.enable()
        det.process(fr.thermal, fr.stamp)
        prof.disable()
        mode = "full" if det.last_mode in ("startup", "reconfiguration") else det.last_mode
        if mode in profiles:
            profiles[mode].add(prof)
        else:
            profiles[mode] = pstats.Stats(prof)
    for mode in ("tracking", "full"):
        if mode not in profiles:
            continue
        print(f"\n===== {mode} (cumulative, top {args.top}) =====")
        st = profiles[mode]
        st.sort_stats("cumulative").print_stats(args.top)
        print(f"\n===== {mode} (own time, top {args.top}) =====")
        st.sort_stats("tottime").print_stats(args.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
