"""Throughput and scores of the offline pipeline (``mk_tracker process``) per configuration.

One generated crowd bag is processed, in the same run, by:

* the full system: sparse kernel covariance detector (Schizas et al. 2018) + multi-object
  tracker with multiple-kernel refinement (Chu et al. 2013);
* the threshold detector baseline instead of the kernel covariance detector;
* the kernel covariance detector with the tracker's multiple-kernel refinement switched
  off (Kalman + association only);
* ground-truth boxes as detections (topic mode), the tracker's ceiling on this scene.

For each: frames per second of the whole pipeline (bag reading, detection, tracking, output
bag; no video), MOTA, IDF1, ID switches.

Usage::

    .venv/bin/python benchmarks/bench_pipeline.py [--frames 120] [--people 4] [--seed 7]
        [--out docs/benchmark_pipeline.md]
"""

from __future__ import annotations

import argparse
import platform
import shlex
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.bag_writer import BagWriter  # noqa: E402
from mk_tracker.boxes import intersection_area  # noqa: E402
from mk_tracker.messages.detection_messages import (Detection, make_detection_array,  # noqa: E402
                                           read_detection_array)
from mk_tracker.messages.message_types import bag_message_types  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402


def copied_without_thermal(reader, writer):
    """Copy every message of ``reader`` that is not on a ``/thermal`` topic into ``writer``
    (raw, same stamps), yielding each one after it is written, so a caller can add its own
    topics in the same pass."""
    for m in reader.messages():
        if m.topic.startswith("/thermal"):
            continue
        writer.add_topic(m.topic, m.msgtype)
        writer.write_raw(m.topic, m.timestamp_ns, m.data)
        yield m


def merged_boxes(boxes: list, overlap: float) -> list:
    """``boxes`` (x, y, w, h) with every pair whose intersection exceeds ``overlap`` times the
    smaller box's area replaced by their bounding box, until no such pair is left: what a
    detector that reports people who touch as one object would give."""
    out = [tuple(float(v) for v in b) for b in boxes]
    joined = True
    while joined:
        joined = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                a, b = out[i], out[j]
                if intersection_area(a, b) > overlap * min(a[2] * a[3], b[2] * b[3]):
                    x0, y0 = min(a[0], b[0]), min(a[1], b[1])
                    x1, y1 = max(a[0] + a[2], b[0] + b[2]), max(a[1] + a[3], b[1] + b[3])
                    out[i] = (x0, y0, x1 - x0, y1 - y0)
                    del out[j]
                    joined = True
                    break
            if joined:
                break
    return out


def with_detections(src: Path, dst: Path, detections_of) -> None:
    """A copy of ``src`` without thermal images, with ``/detections`` beside each
    ``/ground_truth`` message: ``detections_of(index, ground_truth_msg)`` (the frame's index
    among the ground-truth messages) gives the list of
    :class:`~mk_tracker.messages.detection_messages.Detection`, written with that message's
    header and stamp."""
    with open_bag(src) as reader, BagWriter(dst, typestore=reader.typestore) as writer:
        types = bag_message_types(reader.typestore)
        index = 0
        for m in copied_without_thermal(reader, writer):
            if m.topic == "/ground_truth":
                msg = reader.deserialize(m)
                dets = detections_of(index, msg)
                index += 1
                writer.add_topic("/detections", m.msgtype)
                writer.write("/detections", m.timestamp_ns,
                             make_detection_array(dets, msg.header, types))


def with_truth_as_detections(src: Path, dst: Path, min_visible: float = 0.0,
                             merge_overlap: float | None = None) -> None:
    """A copy of ``src`` without thermal images, with ``/detections`` = ground truth.

    ``min_visible`` leaves out people less visible than that fraction (the generator writes
    each person's visible fraction as the score of its ground-truth box); ``merge_overlap``
    (``None``: off) joins the boxes of people who overlap, :func:`merged_boxes`."""
    def truth(_index, msg):
        boxes = [d.box for d in read_detection_array(msg) if d.score >= min_visible]
        if merge_overlap is not None:
            boxes = merged_boxes(boxes, merge_overlap)
        return [Detection(tuple(b), 1.0) for b in boxes]

    with_detections(src, dst, truth)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--people", type=int, default=4)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--out", type=Path, default=Path("docs/benchmark_pipeline.md"))
    args = parser.parse_args(argv)

    base = load_pipeline_config()
    configs = [
        ("kernel covariance + multiple kernels", base, "thermal"),
        ("threshold baseline + multiple kernels", replace(base, method="threshold"), "thermal"),
        ("kernel covariance, no multiple-kernel refinement",
         replace(base, tracker=replace(base.tracker, use_multi_kernel=False)), "thermal"),
        ("ground truth as detections + multiple kernels", base, "topic:/detections"),
    ]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        scene = build_preset("crowd", seed=args.seed, people=args.people, frames=args.frames,
                             width=args.width, height=args.height)
        write_scene_bag(scene, tmp / "scene", preset="crowd")
        with_truth_as_detections(tmp / "scene", tmp / "truth")
        # warm-up (numba compilation, imports) outside the timed runs
        process_bag(tmp / "scene", tmp / "warmup", base,
                    PipelineOptions(progress=False, write_video=False, write_plots=False))
        for i, (name, config, source) in enumerate(configs):
            bag = tmp / ("truth" if source.startswith("topic:") else "scene")
            result = process_bag(bag, tmp / f"run{i}", config, PipelineOptions(
                detections=source, progress=False, write_video=False, write_plots=False,
                tracker_profile="own"))     # the same tracker in every row
            m = result.metrics
            fps = result.frames / result.seconds
            rows.append((name, fps, m["mota"], m["idf1"], m["num_switches"],
                         m["num_false_positives"], m["num_misses"]))
            print(f"{name}: {fps:.1f} frames/s, MOTA {100 * m['mota']:.1f}%, IDF1 "
                  f"{100 * m['idf1']:.1f}%, ID switches {m['num_switches']}", flush=True)

    command = ".venv/bin/python benchmarks/bench_pipeline.py " + shlex.join(
        argv if argv is not None else sys.argv[1:])
    lines = [
        "# Offline pipeline: throughput and scores per configuration", "",
        "Produced by:", "", "```", command.rstrip(), "```", "",
        f"Scene: preset crowd, {args.people} people, {args.frames} frames, "
        f"{args.width}x{args.height}, seed {args.seed}.  Machine: {platform.machine()}, "
        f"Python {platform.python_version()}, {platform.platform()}.  Frames per second of "
        "the whole `mk_tracker process` run (bag reading, detection, tracking, output bag; "
        "no video), after a warm-up run.", "",
        "| configuration | frames/s | MOTA | IDF1 | ID switches | FP | misses |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, fps, mota, idf1, sw, fp, fn in rows:
        lines.append(f"| {name} | {fps:.1f} | {100 * mota:.1f}% | {100 * idf1:.1f}% | {sw} "
                     f"| {fp} | {fn} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
