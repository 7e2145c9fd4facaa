"""CPU time of the thermal detector with the shipped settings and with ``--set`` overrides,
both fed the same crowd frames alternately in one process (so the machine's load is shared
by both): median CPU ms per full-frame pass and per tracking frame, and the mean per frame.
Not a test: nothing is asserted.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 nice -n 10 \\
        .venv/bin/python benchmarks/compare_detector_time.py --people 15 --seeds 101 201 \\
        --set body_extent.join_stacked=true
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from setting_values import setting_changes  # noqa: E402

from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, nargs="+", default=[15])
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--seeds", type=int, nargs="+", default=[101])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--set", nargs="+", required=True, metavar="NAME=VALUE",
                        help="detector parameters of the variant (YAML values)")
    args = parser.parse_args(argv)
    base = load_pipeline_config().detector
    variant = updated(base, setting_changes(args.set))
    width, height = (int(v) for v in args.size.split("x"))
    print("| people | seed | settings | full pass ms (n) | tracking frame ms (n) | mean ms/frame |")
    print("|---:|---:|---|---:|---:|---:|")
    for people in args.people:
        for seed in args.seeds:
            scene = build_preset("crowd", seed=seed, people=people, frames=args.frames,
                                 width=width, height=height)
            frames = [scene.frame(i) for i in range(len(scene))]
            detectors = {"shipped": ThermalDetector(base),
                         " ".join(args.set): ThermalDetector(variant)}
            for d in detectors.values():       # compile (numba) outside the timed runs
                ThermalDetector(d.config).process(frames[0].thermal, frames[0].stamp)
            times = {name: {} for name in detectors}
            for fr in frames:
                for name, d in detectors.items():
                    t0 = time.thread_time()
                    d.process(fr.thermal, fr.stamp)
                    mode = "full" if d.last_mode in ("startup", "reconfiguration") else \
                        d.last_mode
                    times[name].setdefault(mode, []).append(1e3 * (time.thread_time() - t0))
            for name, t in times.items():
                every = [v for m, vs in t.items() if m != "warming_up" for v in vs]
                print(f"| {people} | {seed} | {name} | {np.median(t.get('full', [np.nan])):.1f} "
                      f"({len(t.get('full', []))}) | "
                      f"{np.median(t.get('tracking', [np.nan])):.1f} "
                      f"({len(t.get('tracking', []))}) | {np.mean(every):.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
