"""How much slower the nodes' numpy fallback is than numba's compiled paths.

The figure behind the start-up warning of a node without numba
(:func:`mk_tracker.numba_support.fallback_warning`).  Each variant runs in its own process
(the compiled paths are chosen once per process), after the nodes' own warm-up:

* detector: :class:`~mk_tracker.detection.thermal_detector.ThermalDetector` (defaults) over
  the first 60 frames of the paper's synthetic scene, wall ms per frame;
* tracker: :meth:`~mk_tracker.tracking.multi_kernel.MultiKernelTracker.refine` (defaults, 2
  kernels) of the warm-up's 120x160 target, 200 times, wall ms per refine.

Usage (writes the report with the command and the machine load)::

    nice -n 10 .venv/bin/python benchmarks/numba_fallback.py --output docs/numba_fallback.md
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def measure() -> dict[str, float]:
    from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig
    from mk_tracker.synthetic.presets import paper_scene
    from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
    from mk_tracker.warm_up import _person_image, warm_up_detector, warm_up_tracker

    warm_up_detector()
    warm_up_tracker()
    scene = paper_scene()
    detector = ThermalDetector(ThermalDetectorConfig())
    frames = min(len(scene), 60)
    t0 = time.perf_counter()
    for i in range(frames):
        frame = scene.frame(i)
        detector.process(frame.thermal, frame.stamp, encoding="mono8")
    detector_ms = (time.perf_counter() - t0) / frames * 1e3
    tracker = MultiKernelTracker(MultiKernelConfig())
    state = tracker.start(_person_image(0), (60.0, 20.0, 24.0, 80.0))
    t0 = time.perf_counter()
    for k in range(200):
        tracker.refine(_person_image(k % 5), state)
    refine_ms = (time.perf_counter() - t0) / 200 * 1e3
    return {"detector_ms": detector_ms, "refine_ms": refine_ms}


def run_variant(no_numba: bool) -> dict[str, float]:
    env = dict(os.environ)
    env.pop("MK_TRACKER_NO_NUMBA", None)
    if no_numba:
        env["MK_TRACKER_NO_NUMBA"] = "1"
    out = subprocess.run([sys.executable, __file__, "--measure"], env=env, cwd=str(REPO),
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--output", type=Path, default=REPO / "docs" / "numba_fallback.md")
    args = parser.parse_args()
    if args.measure:
        print(json.dumps(measure()))
        return 0
    load_start = os.getloadavg()[0]
    rows = []
    for r in range(args.repeats):
        compiled, fallback = run_variant(False), run_variant(True)
        rows.append((r + 1, compiled, fallback))
        print(f"run {r + 1}: detector {compiled['detector_ms']:.2f} -> "
              f"{fallback['detector_ms']:.2f} ms/frame, refine {compiled['refine_ms']:.3f} -> "
              f"{fallback['refine_ms']:.3f} ms")
    lines = ["# numpy fallback vs numba's compiled paths", "",
             f"    nice -n 10 .venv/bin/python benchmarks/numba_fallback.py --repeats "
             f"{args.repeats}", "",
             f"Machine: {os.cpu_count()} cores, Python {platform.python_version()}, load average "
             f"(1 min) {load_start:.2f} at the start and {os.getloadavg()[0]:.2f} at the end.",
             "", "| run | detector ms/frame compiled | numpy | ratio | refine ms compiled | "
             "numpy | ratio |", "|---|---|---|---|---|---|---|"]
    for run, c, f in rows:
        lines.append(f"| {run} | {c['detector_ms']:.2f} | {f['detector_ms']:.2f} | "
                     f"{f['detector_ms'] / c['detector_ms']:.1f}x | {c['refine_ms']:.3f} | "
                     f"{f['refine_ms']:.3f} | {f['refine_ms'] / c['refine_ms']:.1f}x |")
    lines += ["", "A node without numba logs this once at start-up "
              "(mk_tracker/numba_support.py)."]
    args.output.write_text("\n".join(lines) + "\n")
    print(f"report: {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
