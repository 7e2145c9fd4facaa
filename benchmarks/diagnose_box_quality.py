"""How well the thermal detector's boxes cover the people they find, and what better boxes
would give the pipeline (issues #15 and #19: "boxes cover half a body").

The detector alone (:class:`mk_tracker.detection.thermal_detector.ThermalDetector` with the
shipped ``config/detector.yaml``, plus ``--set`` overrides) runs over crowd-preset scenes.
Each detection is matched to a person as in ``benchmarks/bench_thermal_detector.py``
(its centroid inside the person's box; Hungarian on the distance to the box centre) and
compared with that person's ground-truth box (clipped to the image):

* IoU in the thermal image, and in the RGB image after the scene's homography (where the
  tracker works and MOTA is scored, at IoU 0.5), and the share of matched detections with
  IoU >= 0.5;
* height and width ratio (detection / person);
* which edge is missing: the top (the detection's top edge more than ``--edge`` of the
  person's height below the person's), the bottom, or a side (either side short by more
  than ``--edge`` of the person's width); and ``covers 2+``: the box covers more than
  30% of a second person's box (a merged pair).

Then the pipeline (``mk_tracker process``: homography -> tracker, scored against the bag's
ground truth) is driven by detection bags made from the same detections:

* ``as is``: the detections themselves (the pipeline's own figure, a check);
* ``truth box``: every matched detection's box replaced by its person's box, misses and
  unmatched detections kept as they are: what perfect box completion could give;
* ``truth box, one person``: the same, but only for the matched detections that do not
  cover a second person (what completing or trimming one person's box could give; a
  merged pair keeps its box);
* ``truth size``: the person's box size centred on the detection's centroid (the centre
  kept, the extent perfect).

The box figures are given for all matched detections and for those of one person (not
``covers 2+``).

``--causes`` prints instead, per scene, why each matched detection misses IoU 0.5 in the
thermal image (its share of the matched detections; first cause that applies):

* ``merged``: the box covers a second person (``covers 2+``: a merged pair or group);
* ``part``: one person, height ratio < ``--short`` (head, torso or legs only);
* ``too big``: one person, height or width ratio > 1 / ``--short`` (box around more than
  the person: a shadow, a limb, a neighbour's fringe);
* ``offset``: the rest (right size, wrong place).

Not a test: nothing is asserted.

    nice -n 10 .venv/bin/python benchmarks/diagnose_box_quality.py --people 3 8 15 \\
        --sizes 320x240 640x480 --seeds 101 102 103
    nice -n 10 .venv/bin/python benchmarks/diagnose_box_quality.py --causes --people 8 15 \\
        --seeds 101 102 [--set split_by_valleys=true]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.bag_writer import BagWriter  # noqa: E402
from mk_tracker.boxes import clip_box, iou, transform_box  # noqa: E402
from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402
from mk_tracker.messages.detection_messages import Detection, make_detection_array  # noqa: E402
from mk_tracker.messages.message_types import bag_message_types, make_header  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.synthetic.scene_bag import (THERMAL_FRAME_ID, build_preset,  # noqa: E402
                                            write_scene_bag)
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402
from mk_tracker.tracking.association import assign  # noqa: E402
from bench_pipeline import copied_without_thermal  # noqa: E402
from bench_thermal_detector import centroid_cost  # noqa: E402
from setting_values import setting_changes  # noqa: E402

VARIANTS = ("as is", "truth box", "truth box, one person", "truth size")
DETECTIONS_TOPIC = "/box_quality/detections"


def match(detections, objects) -> dict[int, object]:
    """Detection index -> the person (ObjectTruth) it belongs to."""
    gts = [o for o in objects if o.in_frame]
    if not detections or not gts:
        return {}
    cost = centroid_cost(detections, gts)
    return {i: gts[j] for i, j in assign(cost, max_cost=float("inf")).matches}


def _common(a, b) -> float:
    w = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    h = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    return max(w, 0.0) * max(h, 0.0)


def box_figures(box, person, others, scene, edge: float) -> dict:
    """Figures of one matched detection ``box`` (thermal px) against ``person``."""
    tw, th = scene.thermal_size
    rw, rh = scene.rgb_size
    truth = clip_box(person.box_thermal, tw, th)
    truth_rgb = clip_box(person.box_rgb, rw, rh)
    x, y, w, h = box
    gx, gy, gw, gh = truth
    mapped = transform_box(box, scene.homography)
    covers = any(_common(box, o.box_thermal) > 0.3 * o.box_thermal[2] * o.box_thermal[3]
                 for o in others if o is not person and o.in_frame)
    return {"iou": iou(box, truth),
            "iou_rgb": iou(mapped, truth_rgb) if truth_rgb is not None else 0.0,
            "h_ratio": h / gh, "w_ratio": w / gw,
            "top": y - gy > edge * gh,
            "bottom": (gy + gh) - (y + h) > edge * gh,
            "side": x - gx > edge * gw or (gx + gw) - (x + w) > edge * gw,
            "covers": covers}


def run_detector(scene, config, edge: float):
    """Per frame ``(stamp, [(box, score, replacement boxes by variant)])`` and the list of
    figures of every matched detection."""
    detector = ThermalDetector(config)
    tw, th = scene.thermal_size
    frames, figures = [], []
    for i in range(len(scene)):
        fr = scene.frame(i)
        dets = detector.process(fr.thermal, fr.stamp)
        owners = match(dets, fr.objects)
        out = []
        for k, d in enumerate(dets):
            boxes = {v: tuple(d.box) for v in VARIANTS}
            person = owners.get(k)
            if person is not None:
                truth = clip_box(person.box_thermal, tw, th)
                if truth is not None:
                    boxes["truth box"] = truth
                    fig = box_figures(d.box, person, fr.objects, scene, edge)
                    if not fig["covers"]:
                        boxes["truth box, one person"] = truth
                    cx, cy = d.centroid
                    sized = clip_box((cx - truth[2] / 2, cy - truth[3] / 2, truth[2],
                                      truth[3]), tw, th)
                    boxes["truth size"] = sized if sized is not None else tuple(d.box)
                    figures.append(fig)
            out.append((d.score, boxes))
        frames.append((fr.stamp, out))
    return frames, figures


def detection_bag(src: Path, dst: Path, frames, variant: str) -> None:
    """A copy of scene bag ``src`` without thermal images, with ``DETECTIONS_TOPIC`` in the
    thermal frame holding ``variant``'s boxes."""
    with open_bag(src) as reader, BagWriter(dst, typestore=reader.typestore) as writer:
        types = bag_message_types(reader.typestore)
        for _ in copied_without_thermal(reader, writer):
            pass
        writer.add_topic(DETECTIONS_TOPIC, "vision_msgs/msg/Detection2DArray")
        for stamp, dets in frames:
            ns = round(stamp * 1e9)
            header = make_header(types, THERMAL_FRAME_ID, ns)
            writer.write(DETECTIONS_TOPIC, ns, make_detection_array(
                [Detection(box=boxes[variant], score=score, class_id="person")
                 for score, boxes in dets], header, types))


CAUSES = ("merged", "part", "too big", "offset")


def cause(figure: dict, short: float) -> str | None:
    """Why one matched detection misses IoU 0.5 (``--causes``); None when it does not."""
    if figure["iou"] >= 0.5:
        return None
    if figure["covers"]:
        return "merged"
    if figure["h_ratio"] < short:
        return "part"
    if figure["h_ratio"] > 1.0 / short or figure["w_ratio"] > 1.0 / short:
        return "too big"
    return "offset"


def cause_cells(figures, short: float) -> str:
    """Markdown cells of ``--causes``: matched, IoU >= 0.5, then each cause's share, and the
    median height / width ratio."""
    if not figures:
        return " | ".join(["-"] * (4 + len(CAUSES)))
    found = [cause(f, short) for f in figures]
    n = len(figures)
    return " | ".join([f"{n}", f"{found.count(None) / n:.2f}"]
                      + [f"{found.count(c) / n:.2f}" for c in CAUSES]
                      + [f"{np.median([f['h_ratio'] for f in figures]):.2f}",
                         f"{np.median([f['w_ratio'] for f in figures]):.2f}"])


def summary(figures) -> str:
    """Markdown cells of the box figures: all matched detections, then those of one
    person."""
    single = [f for f in figures if not f["covers"]]
    return _cells(figures, 9) + " | " + _cells(single, 7)


def _cells(figures, n: int) -> str:
    if not figures:
        return " | ".join(["-"] * n)
    get = lambda k: np.array([f[k] for f in figures], dtype=float)  # noqa: E731
    ious, rgb = get("iou"), get("iou_rgb")
    return " | ".join([
        f"{len(figures)}",
        f"{np.median(ious):.2f} / {np.median(rgb):.2f}",
        f"{np.mean(ious >= 0.5):.2f} / {np.mean(rgb >= 0.5):.2f}",
        f"{np.median(get('h_ratio')):.2f}", f"{np.median(get('w_ratio')):.2f}",
        f"{np.mean(get('top')):.2f}", f"{np.mean(get('bottom')):.2f}",
        f"{np.mean(get('side')):.2f}", f"{np.mean(get('covers')):.2f}"][:n])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, nargs="+", default=[3, 8, 15])
    parser.add_argument("--sizes", nargs="+", default=["320x240", "640x480"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[101, 102, 103])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--edge", type=float, default=0.15,
                        help="an edge is missing when the box falls short of the person's "
                             "by more than this fraction of its height (top, bottom) or "
                             "width (sides)")
    parser.add_argument("--causes", action="store_true",
                        help="only the causes of IoU < 0.5 per scene (no pipeline)")
    parser.add_argument("--short", type=float, default=0.7,
                        help="--causes: height ratio below which a box is a part, and "
                             "whose inverse a ratio must exceed to be too big")
    parser.add_argument("--no-pipeline", action="store_true",
                        help="box figures only (no MOTA bound)")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a detector parameter (YAML value)")
    args = parser.parse_args(argv)
    base = load_pipeline_config()
    detector_config = base.detector
    if args.set:
        detector_config = updated(detector_config, setting_changes(args.set))
    if args.causes:
        return print_causes(args, detector_config)
    print("| size | people | seed | matched | IoU median thermal / RGB | IoU >= 0.5 thermal / "
          "RGB | height ratio | width ratio | top missing | bottom missing | side missing "
          "| covers 2+ | one person: matched | IoU median | IoU >= 0.5 | height ratio | width "
          "ratio | top | bottom | " + " | ".join(f"MOTA / IDF1 {v}" for v in VARIANTS) + " |")
    print("|---|---:|---:|" + "---:|" * 16 + "---|" * len(VARIANTS))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for size in args.sizes:
            width, height = (int(v) for v in size.split("x"))
            for people in args.people:
                pooled = []
                sums = {v: [] for v in VARIANTS}
                for seed in args.seeds:
                    scene = build_preset("crowd", seed=seed, people=people,
                                         frames=args.frames, width=width, height=height)
                    frames, figures = run_detector(scene, detector_config, args.edge)
                    pooled += figures
                    cells = []
                    if not args.no_pipeline:
                        bag = tmp / f"scene_{size}_{people}_{seed}"
                        write_scene_bag(scene, bag, preset="crowd")
                        for v in VARIANTS:
                            dbag = tmp / f"det_{size}_{people}_{seed}_{v.replace(' ', '_')}"
                            detection_bag(bag, dbag, frames, v)
                            result = process_bag(
                                dbag, tmp / f"run_{size}_{people}_{seed}_{v.replace(' ', '_')}",
                                base, PipelineOptions(detections=f"topic:{DETECTIONS_TOPIC}",
                                                      tracker_profile="own",
                                                      progress=False, write_video=False,
                                                      write_plots=False, write_bag=False))
                            m = result.metrics
                            sums[v].append((m["mota"], m["idf1"]))
                            cells.append(f"{m['mota']:.3f} / {m['idf1']:.3f}")
                    else:
                        cells = ["-"] * len(VARIANTS)
                    print(f"| {size} | {people} | {seed} | {summary(figures)} | "
                          + " | ".join(cells) + " |", flush=True)
                means = [f"{np.mean([s[0] for s in sums[v]]):.3f} / "
                         f"{np.mean([s[1] for s in sums[v]]):.3f}" if sums[v] else "-"
                         for v in VARIANTS]
                print(f"| {size} | {people} | all | {summary(pooled)} | "
                      + " | ".join(means) + " |", flush=True)
    return 0


def print_causes(args, detector_config) -> int:
    """The ``--causes`` table: per scene and pooled over the seeds."""
    print("| size | people | seed | matched | IoU >= 0.5 | " + " | ".join(CAUSES)
          + " | height ratio | width ratio |")
    print("|---|---:|---:|" + "---:|" * (4 + len(CAUSES)))
    for size in args.sizes:
        width, height = (int(v) for v in size.split("x"))
        for people in args.people:
            pooled = []
            for seed in args.seeds:
                scene = build_preset("crowd", seed=seed, people=people, frames=args.frames,
                                     width=width, height=height)
                _, figures = run_detector(scene, detector_config, args.edge)
                pooled += figures
                print(f"| {size} | {people} | {seed} | {cause_cells(figures, args.short)} |",
                      flush=True)
            print(f"| {size} | {people} | all | {cause_cells(pooled, args.short)} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
