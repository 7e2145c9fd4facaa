"""Memory of the thermal detector library over a long stream, without ROS.

The node soak (benchmarks/soak.py, docs/soak.md) saw detector_node's RSS grow by a few MiB
per thousand frames.  This script runs :class:`mk_tracker.detection.thermal_detector.ThermalDetector`
alone on the same kind of input (640x480 crowd scene, 15 people; 300 rendered frames
replayed with continuous time stamps) and prints the process RSS and the Python heap
(tracemalloc) every ``--every`` frames, so a growth can be put on the library or on the
node/DDS layer.  Writes ``docs/detector_memory.md``::

    .venv/bin/python benchmarks/detector_memory.py --frames 3000
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tracemalloc
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from mk_tracker.synthetic.presets import crowd_scene  # noqa: E402
from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402


def rss_mib() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=3000)
    parser.add_argument("--every", type=int, default=500)
    parser.add_argument("--people", type=int, default=15)
    parser.add_argument("--out", default=str(REPO / "docs" / "detector_memory.md"))
    args = parser.parse_args(argv)

    loop = 300
    scene = crowd_scene(n_people=args.people, seed=0, frames=loop)
    frames = []
    for i in range(loop):          # keep the thermal planes only (RGB would be 270 MiB)
        f = scene.frame(i)
        frames.append((f.thermal, f.stamp))
    encoding = scene.config.thermal_encoding
    period = loop / scene.config.fps
    detector = ThermalDetector()
    tracemalloc.start()
    rows = []
    t0 = time.perf_counter()
    for k in range(args.frames + 1):
        image, stamp = frames[k % loop]
        detector.process(image, stamp + (k // loop) * period, encoding=encoding)
        if k % args.every == 0:
            heap = tracemalloc.get_traced_memory()[0] / 2 ** 20
            rows.append((k, rss_mib(), heap, len(detector.tracks), time.perf_counter() - t0))
            print(f"frame {k:6d}  RSS {rows[-1][1]:7.1f} MiB  python heap {heap:6.1f} MiB  "
                  f"tracks {rows[-1][3]}", flush=True)
    first = next(r for r in rows if r[0] >= args.every)     # after the start-up allocations
    last = rows[-1]
    growth = (last[1] - first[1]) / max(last[0] - first[0], 1) * 1000
    lines = [
        "# Thermal detector memory over a long stream (library only, no ROS)",
        "",
        "Produced by:",
        "",
        "```",
        f".venv/bin/python benchmarks/detector_memory.py --frames {args.frames}",
        "```",
        "",
        f"Scene: `crowd_scene(n_people={args.people}, seed=0)` 640x480, {loop} rendered "
        f"frames (thermal planes held in memory: part of the RSS) replayed with continuous "
        f"stamps; `ThermalDetector()` defaults.  Load "
        f"average at the end: {os.getloadavg()[0]:.1f}.",
        "",
        "| frame | RSS MiB | Python heap MiB (tracemalloc) | tracks | elapsed s |",
        "|---|---|---|---|---|",
        *[f"| {k} | {r:.1f} | {h:.1f} | {n} | {t:.0f} |" for k, r, h, n, t in rows],
        "",
        f"RSS change after frame {first[0]}: {growth:+.2f} MiB per 1000 frames.",
        "",
    ]
    Path(args.out).write_text("\n".join(lines))
    print(f"RSS change after frame {first[0]}: {growth:+.2f} MiB per 1000 frames; "
          f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
