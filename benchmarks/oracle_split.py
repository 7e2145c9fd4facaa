"""How much of the thermal -> RGB crowd pipeline's loss is the detector's group boxes
(issue #15): the pipeline fed the default thermal detector's boxes, corrected by an oracle
that knows the ground truth.

For each crowd scene (``PEOPLE-SEED-WxH``) the thermal detector runs once
(:func:`bench_groups.detector_pass`, the shipped detector plus ``--set-detector``
overrides); its boxes, frame by frame, are then changed by one rule, mapped to the RGB image
by the scene's homography and written as ``/detections`` into a copy of the scene's bag,
which ``mk_tracker process`` tracks (``--detections topic:/detections``, the tracker's own
profile) and scores against the bag's ground truth (MOTA / IDF1 / ID switches):

* ``none``: the boxes as they are (the ``kernel`` row of bench_groups.py, through a topic);
* ``split``: a box that holds the box centres of two or more people at least half visible
  is replaced by those people's true boxes; the other boxes stay as they are;
* ``fix``: as ``split``, and a box holding one person's centre becomes that person's box;
* ``strips``: a box holding two or more centres is cut into that many equal column strips
  of its full height (the right count, no geometry).

Not a test: nothing is asserted.

    .venv/bin/python benchmarks/oracle_split.py 8-201-640x480 8-202-640x480 \\
        15-201-640x480 15-202-640x480
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_groups import detector_pass  # noqa: E402
from bench_pipeline import with_detections  # noqa: E402
from bench_thermal_detector import MIN_VISIBLE  # noqa: E402
from setting_values import setting_changes  # noqa: E402

from mk_tracker.boxes import transform_box  # noqa: E402
from mk_tracker.messages.detection_messages import Detection  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402

RULES = ("none", "split", "fix", "strips")


def _centre_inside(person, box) -> bool:
    x, y, w, h = person.box_thermal
    cx, cy = x + w / 2.0, y + h / 2.0
    return box[0] <= cx <= box[0] + box[2] and box[1] <= cy <= box[1] + box[3]


def corrected(boxes: list, objects: list, rule: str) -> list:
    """``boxes`` (thermal px) changed by ``rule`` (module docstring), with the frame's
    ground truth ``objects``; a box repeated by two corrections is kept once."""
    people = [o for o in objects if o.in_frame and o.visible_fraction >= MIN_VISIBLE]
    out = []
    for box in boxes:
        inside = [o for o in people if _centre_inside(o, box)]
        if rule == "strips" and len(inside) >= 2:
            x, y, w, h = box
            n = len(inside)
            out += [(x + k * w / n, y, w / n, h) for k in range(n)]
        elif rule in ("split", "fix") and (len(inside) >= 2
                                          or (rule == "fix" and len(inside) == 1)):
            out += [tuple(o.box_thermal) for o in inside]
        else:
            out.append(tuple(box))
    return list(dict.fromkeys(out))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+", help="PEOPLE-SEED-WxH, e.g. 8-201-640x480")
    parser.add_argument("--rules", nargs="+", default=list(RULES), choices=RULES)
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--set-detector", nargs="*", default=[], metavar="NAME=VALUE")
    args = parser.parse_args(argv)
    base = load_pipeline_config()
    if args.set_detector:
        base = replace(base, detector=updated(base.detector,
                                              setting_changes(args.set_detector)))
    print("| scene | rule | MOTA | IDF1 | ID sw. |\n|---|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name in args.scenes:
            people, seed, size = name.split("-")
            width, height = (int(v) for v in size.split("x"))
            scene = build_preset("crowd", seed=int(seed), people=int(people),
                                 frames=args.frames, width=width, height=height)
            bag = tmp / name
            write_scene_bag(scene, bag, preset="crowd")
            _, frames = detector_pass(scene, "kernel", base.detector)
            for rule in args.rules:
                dst = tmp / f"{name}_{rule}"
                with_detections(bag, dst, lambda index, _msg, rule=rule: [
                    Detection(transform_box(b, scene.homography), 1.0)
                    for b in corrected([d.box for d in frames[index][1]],
                                       scene.frame(index).objects, rule)])
                result = process_bag(dst, tmp / f"run_{name}_{rule}", base,
                                     PipelineOptions(detections="topic:/detections",
                                                     progress=False, tracker_profile="own",
                                                     write_video=False, write_plots=False,
                                                     write_bag=False))
                m = result.metrics
                print(f"| {name} | {rule} | {m['mota']:.3f} | {m['idf1']:.3f} | "
                      f"{m['num_switches']} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
