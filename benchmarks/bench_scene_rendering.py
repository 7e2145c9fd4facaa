"""Speed and memory of the synthetic scene generator (:mod:`mk_tracker.synthetic.scene`).

In one process, on the same scenes, it measures

* set-up time of ``crowd_scene(n)`` (trajectories, sprites, static backgrounds, noise
  buffers) for 5 / 15 / 30 people at 640x480, 300 and 10,000 frames;
* per-frame time of ``scene.frame(i)`` (RGB + thermal + ground truth) against its peers
  ``scene.ground_truth(i)`` (ground truth only, no images) and a naive baseline that draws
  the same number of people as plain ``cv2`` filled rectangles/ellipses with full-frame
  ``numpy`` Gaussian noise (what a minimal generator costs);
* bag writing throughput of :func:`mk_tracker.synthetic.scene_bag.write_scene_bag`, mcap vs sqlite3;
* memory: traced peak while iterating over 2,000 frames of a 10,000-frame scene, against
  the peak of rendering a single frame (a lazy generator keeps the two equal).

It prints the figures and writes ``docs/scene_rendering.md``.  Run from the repository::

    .venv/bin/python benchmarks/bench_scene_rendering.py
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from mk_tracker.synthetic.presets import PRESETS, crowd_scene  # noqa: E402
from mk_tracker.synthetic.scene_bag import write_scene_bag  # noqa: E402


def timed(fn, repeats: int) -> list[float]:
    """CPU milliseconds of this process per call (the machine is shared: wall time would
    include other processes' load)."""
    out = []
    for r in range(repeats):
        t0 = time.process_time()
        fn(r)
        out.append((time.process_time() - t0) * 1000.0)
    return out


def naive_frame(rng: np.random.Generator, boxes: np.ndarray) -> np.ndarray:
    """Minimal peer: flat background, one rectangle + ellipse per person, fresh noise."""
    img = np.full((480, 640, 3), 110, np.uint8)
    for x, y, w, h in boxes.astype(int):
        cv2.rectangle(img, (x, y + h // 5), (x + w, y + h), (40, 40, 200), -1)
        cv2.ellipse(img, (x + w // 2, y + h // 10), (w // 5, h // 10), 0, 0, 360,
                    (80, 130, 200), -1)
    noise = rng.normal(0.0, 4.0, img.shape)
    return np.clip(img + noise, 0, 255).astype(np.uint8)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200, help="frames timed per scene")
    parser.add_argument("--out", default=str(REPO / "docs" / "scene_rendering.md"))
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    command = " ".join([".venv/bin/python benchmarks/bench_scene_rendering.py"] +
                       (argv if argv is not None else sys.argv[1:]))
    lines = ["# Synthetic scene generator: speed and memory", "",
             "Produced by:", "", "```", command.strip(), "```", "",
             f"Machine: {cv2.getNumberOfCPUs()} CPUs, OpenCV {cv2.__version__}, numpy "
             f"{np.__version__}; one OpenCV thread; times are CPU ms of the process (median, "
             f"90th percentile over {args.frames} frames; the bag section is wall time).", ""]

    # -- set-up ------------------------------------------------------------------------
    lines += ["## Set-up of crowd_scene (640x480)", "", "| people | frames | set-up ms |",
              "|---|---|---|"]
    for n in (5, 15, 30):
        for frames in (300, 10_000):
            t = timed(lambda _: crowd_scene(n, seed=1, frames=frames), 1)[0]
            print(f"set-up  {n:2d} people {frames:5d} frames: {t:8.1f} ms")
            lines.append(f"| {n} | {frames} | {t:.0f} |")

    # -- per frame ---------------------------------------------------------------------
    lines += ["", "## Per frame (640x480, mono8 thermal, 2 occluders)", "",
              "| people | frame() median / p90 | ground_truth() median / p90 | "
              "naive cv2 peer median / p90 |", "|---|---|---|---|"]
    for n in (5, 15, 30):
        scene = crowd_scene(n, seed=1, frames=max(args.frames, 1))
        scene.frame(0)
        f = timed(lambda r: scene.frame(r % len(scene)), args.frames)
        g = timed(lambda r: scene.ground_truth(r % len(scene)), args.frames)
        rng = np.random.default_rng(0)
        boxes = [scene.boxes_thermal(i) for i in range(len(scene))]
        b = timed(lambda r: naive_frame(rng, boxes[r % len(boxes)]), args.frames)
        row = [f"{np.median(x):.2f} / {np.percentile(x, 90):.2f}" for x in (f, g, b)]
        print(f"frame   {n:2d} people: frame {row[0]}  ground_truth {row[1]}  naive {row[2]}")
        lines.append(f"| {n} | " + " | ".join(row) + " |")

    # -- other presets ---------------------------------------------------------------------
    lines += ["", "## Per frame, other presets", "", "| preset | size | frame() median ms |",
              "|---|---|---|"]
    for name, factory in PRESETS.items():
        if name == "crowd":
            continue
        scene = factory()
        t = timed(lambda r: scene.frame(r % len(scene)), min(args.frames, len(scene)))
        size = f"RGB {scene.rgb_size[0]}x{scene.rgb_size[1]}, thermal " \
               f"{scene.thermal_size[0]}x{scene.thermal_size[1]}"
        print(f"preset  {name:20s} {np.median(t):6.2f} ms")
        lines.append(f"| {name} | {size} | {np.median(t):.2f} |")

    # -- bag writing -------------------------------------------------------------------------
    lines += ["", "## Bag writing (crowd, 5 people, 100 frames, 640x480)", "",
              "| storage | s | frames/s | MB |", "|---|---|---|---|"]
    tmp = Path(tempfile.mkdtemp(prefix="scene_bench_"))
    try:
        for storage in ("mcap", "sqlite3"):
            scene = crowd_scene(5, seed=1, frames=100)
            path = tmp / storage
            t0 = time.perf_counter()
            write_scene_bag(scene, path, storage=storage)
            dt = time.perf_counter() - t0  # wall: includes the file system
            size = sum(p.stat().st_size for p in path.iterdir()) / 1e6
            print(f"bag     {storage:8s} {dt:6.2f} s  {100 / dt:6.1f} frames/s  {size:.0f} MB")
            lines.append(f"| {storage} | {dt:.2f} | {100 / dt:.1f} | {size:.0f} |")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    # -- memory ------------------------------------------------------------------------------
    scene = crowd_scene(15, seed=2, frames=10_000)
    tracemalloc.start()
    scene.frame(0)
    _, single = tracemalloc.get_traced_memory()
    tracemalloc.reset_peak()
    for i in range(0, 10_000, 5):
        scene.frame(i)
    current, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"memory  one frame peak {single / 1e6:.1f} MB; 2000 frames peak {peak / 1e6:.1f} MB,"
          f" still held after {current / 1e6:.1f} MB")
    lines += ["", "## Memory (15 people, 10,000-frame scene, tracemalloc)", "",
              f"* peak while rendering one frame: {single / 1e6:.1f} MB",
              f"* peak while rendering 2,000 frames (every 5th of 10,000): {peak / 1e6:.1f} MB",
              f"* held after those 2,000 frames: {current / 1e6:.1f} MB (the sprite resize "
              "cache, bounded at 256 entries)", ""]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
