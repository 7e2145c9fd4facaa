"""People who stand still keep their track (issue #19): a measurement with ground truth.

Crowd scenes (:func:`mk_tracker.synthetic.presets.crowd_scene`) in which ``--stop-fraction``
of the people stop for good at a waypoint part-way through the clip and stand perfectly
still to the end -- the case the kernel covariance detector (Schizas et al. 2018) no longer
detects, since it finds what moves.  Each scene is run through ``mk_tracker process``'s code
(:func:`mk_tracker.tools.pipeline.process_bag`) twice: thermal + RGB (the tracker follows
the RGB image), and thermal-only (the bag without ``/image_raw``: the tracker follows the
thermal image, the mode ``mk_tracker process --thermal`` uses).

Per person who stops, over their *still frames* (the foot point did not move since the
previous frame, at least half of the person visible):

* ``covered``: the fraction of those frames in which some reported box overlaps the
  person's true box at IoU >= 0.5;
* ``same id``: the fraction covered by the id that covered the person in the last frame
  before the stop (0 when no box covered them then);
* the fraction covered at IoU >= 0.3 (a box on part of the person counts).

Plus MOTA / IDF1 of the scene (every person with a visible part, IoU >= 0.5).  Configurations:
``defaults``; ``recovery off`` (``tracker.recovery.enabled: false``); the SORT-style peer of
benchmarks/peers/ fed the defaults run's detections frame by frame, which reports only the
boxes it matched (as ByteTrack does).  Not a test: nothing is asserted.

    nice -n 10 .venv/bin/python benchmarks/bench_still_people.py --seeds 201 202

``--set NAME=VALUE`` overrides a tracker parameter in every configuration (YAML value), for
ablations on the seeds the choices are made on (101-103); ``--no-recovery-off --no-peer
--modes thermal-only`` runs only the defaults thermal-only (a sweep, e.g. of
``multi_kernel.grey_bins``).
"""

from __future__ import annotations

import argparse
import shlex
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.bag_writer import BagWriter  # noqa: E402
from mk_tracker.boxes import clip_box, iou_matrix  # noqa: E402
from mk_tracker.evaluation.metrics import MotRow, mot_metrics  # noqa: E402
from mk_tracker.messages.detection_messages import read_detection_array  # noqa: E402
from mk_tracker.messages.message_types import stamp_to_nanoseconds  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.synthetic.presets import crowd_scene  # noqa: E402
from mk_tracker.synthetic.scene_bag import write_scene_bag  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402
from setting_values import setting_changes  # noqa: E402

MATCH_IOU = 0.5
LOOSE_IOU = 0.3          # the second bound: a box on part of the person
MIN_VISIBLE = 0.5


def thermal_only_copy(src: Path, dst: Path) -> None:
    """``src`` without the RGB image topic: ``mk_tracker process`` then tracks on thermal."""
    with open_bag(src) as reader, BagWriter(dst, typestore=reader.typestore) as writer:
        for m in reader.messages():
            if m.topic == "/image_raw":
                continue
            writer.add_topic(m.topic, m.msgtype)
            writer.write_raw(m.topic, m.timestamp_ns, m.data)


def scene_truth(scene) -> list[list[tuple[int, tuple, float]]]:
    """Per frame, ``(id, clipped box, visible fraction)`` of every person with a visible part
    (thermal plane = RGB plane in the crowd preset: identity homography)."""
    width, height = scene.rgb_size
    out = []
    for i in range(len(scene)):
        frame = []
        for obj in scene.ground_truth(i):
            box = clip_box(obj.box_rgb, width, height)
            if obj.visible_fraction > 0.0 and box is not None:
                frame.append((obj.id, tuple(box), obj.visible_fraction))
        out.append(frame)
    return out


def still_frames(scene) -> dict[int, list[int]]:
    """Per person who ends the clip standing still, the frames from the stop on (the foot
    point equal to the previous frame's)."""
    feet = np.stack([scene.foot_points(i) for i in range(len(scene))])
    out = {}
    for k in range(feet.shape[1]):
        moved = np.any(feet[1:, k] != feet[:-1, k], axis=1)
        if moved.size and not moved[-1] and moved.any():
            first = int(np.flatnonzero(moved)[-1]) + 2   # first frame with no motion
            out[k + 1] = list(range(first, len(feet)))
    return out


def covering_id(tracks, box, threshold: float = MATCH_IOU) -> int | None:
    """The id of the reported box that overlaps ``box`` most, if at IoU >= ``threshold``."""
    if not tracks:
        return None
    ious = iou_matrix(np.array([box], float), np.array([b for _, b in tracks], float))[0]
    k = int(np.argmax(ious))
    return tracks[k][0] if ious[k] >= threshold else None


def still_figures(truth, tracks, stills) -> list[dict]:
    """Per stopper: still frames counted, fraction covered, fraction covered by the stop id."""
    rows = []
    for pid, frames in stills.items():
        by_frame = {i: {o: (b, v) for o, b, v in truth[i]} for i in [frames[0] - 1, *frames]}
        before = by_frame[frames[0] - 1].get(pid)
        stop_id = covering_id(tracks[frames[0] - 1], before[0]) if before else None
        counted = covered = same = loose = 0
        for i in frames:
            gt = by_frame[i].get(pid)
            if gt is None or gt[1] < MIN_VISIBLE:
                continue
            counted += 1
            tid = covering_id(tracks[i], gt[0])
            covered += tid is not None
            loose += covering_id(tracks[i], gt[0], LOOSE_IOU) is not None
            same += tid is not None and tid == stop_id
        rows.append({"person": pid, "frames": counted, "covered": covered / max(counted, 1),
                     "same_id": same / max(counted, 1), "stop_id": stop_id,
                     "loose": loose / max(counted, 1)})
    return rows


def scene_metrics(truth, tracks) -> dict:
    gt = [MotRow(i + 1, o, b) for i, frame in enumerate(truth) for o, b, _ in frame]
    hyp = [MotRow(i + 1, t, b) for i, frame in enumerate(tracks) for t, b in frame]
    return mot_metrics(gt, hyp, iou_threshold=MATCH_IOU)


def run_ours(bag: Path, out: Path, config) -> tuple[list, list]:
    result = process_bag(bag, out, config, PipelineOptions(
        detections="thermal", progress=False, write_video=False, write_plots=False))
    stamps = sorted(result.frame_stamps) or sorted(result.tracks)
    tracks = [list(result.tracks.get(ns, [])) for ns in stamps]
    dets: dict[int, list] = {}
    with open_bag(out / "bag") as reader:
        for m in reader.messages(["/thermal/detections"]):
            msg = reader.deserialize(m)
            dets[stamp_to_nanoseconds(msg.header.stamp)] = [
                (*d.box, d.score) for d in read_detection_array(msg)]
    return tracks, [(ns, dets.get(ns, [])) for ns in stamps]


def config_with(sets: list[str], detector_sets: list[str] = ()):
    """The pipeline configuration with ``--set name=value`` tracker overrides and
    ``--set-detector name=value`` detector overrides."""
    base = load_pipeline_config()
    if sets:
        base = replace(base, tracker=updated(base.tracker, setting_changes(sets)))
    if detector_sets:
        base = replace(base, detector=updated(base.detector, setting_changes(detector_sets)))
    return base


def scene_bags(args, tmp: Path):
    """``(seed, mode, bag, truth, stills)`` for each seed of ``args`` and each of its modes:
    the scene with people who stop, written as a bag (thermal-only: a copy without the RGB
    topic), its ground truth per frame and each stopper's still frames."""
    for seed in args.seeds:
        scene = crowd_scene(args.people, seed=seed, frames=args.frames,
                            stop_fraction=args.stop_fraction)
        truth, stills = scene_truth(scene), still_frames(scene)
        bag = tmp / f"scene_{seed}"
        write_scene_bag(scene, bag, preset="crowd")
        for mode in args.modes:
            src = bag
            if mode == "thermal-only":
                src = tmp / f"thermal_{seed}"
                thermal_only_copy(bag, src)
            yield seed, mode, src, truth, stills


def main(argv: list[str] | None = None) -> int:
    from peers.sort_tracker import SortTracker

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[201, 202])
    parser.add_argument("--people", type=int, default=6)
    parser.add_argument("--frames", type=int, default=250)
    parser.add_argument("--stop-fraction", type=float, default=0.5)
    parser.add_argument("--modes", nargs="+", default=["thermal+rgb", "thermal-only"],
                        choices=["thermal+rgb", "thermal-only"])
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a tracker parameter (YAML value) in every run")
    parser.add_argument("--set-detector", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a detector parameter (YAML value) in every run")
    parser.add_argument("--no-peer", action="store_true", help="skip the SORT-style peer")
    parser.add_argument("--detail", action="store_true", help="print every stopper's row")
    parser.add_argument("--no-recovery-off", action="store_true",
                        help="skip the 'recovery off' configuration (parameter sweeps)")
    args = parser.parse_args(argv)

    base = config_with(args.set, args.set_detector)
    no_recovery = replace(base, tracker=replace(
        base.tracker, recovery=replace(base.tracker.recovery, enabled=False)))
    results: dict[tuple[str, str], list] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for seed, mode, src, truth, stills in scene_bags(args, tmp):
            runs = [("defaults", base)]
            if not args.no_recovery_off:
                runs.append(("recovery off", no_recovery))
            peer_dets = None
            for name, config in runs:
                tracks, dets = run_ours(src, tmp / f"run_{seed}_{mode}_{name}".replace(
                    " ", "_"), config)
                peer_dets = peer_dets or dets
                results.setdefault((mode, name), []).append(
                    (seed, still_figures(truth, tracks, stills),
                     scene_metrics(truth, tracks)))
            if not args.no_peer:
                peer = SortTracker()
                tracks = [peer.update(ns * 1e-9, d) for ns, d in peer_dets]
                results.setdefault((mode, "SORT-style peer"), []).append(
                    (seed, still_figures(truth, tracks, stills),
                     scene_metrics(truth, tracks)))
            for name in ("defaults", "recovery off", "SORT-style peer"):
                if (mode, name) in results:
                    seed_, rows, m = results[(mode, name)][-1]
                    print(f"seed {seed_} {mode} {name}: mota {m['mota']:.3f} idf1 "
                          f"{m['idf1']:.3f} " + " ".join(
                              f"p{r['person']}:{r['frames']}f cov {r['covered']:.2f} "
                              f"same {r['same_id']:.2f}" for r in rows), flush=True)
    command = "nice -n 10 .venv/bin/python benchmarks/bench_still_people.py " + shlex.join(
        argv if argv is not None else sys.argv[1:])
    print(f"\n{command.rstrip()}\n")
    print(f"crowd_scene({args.people} people, {args.frames} frames, stop_fraction "
          f"{args.stop_fraction}), seeds {' '.join(map(str, args.seeds))}\n")
    print("| mode | tracker | stoppers | still frames | covered (IoU >= 0.5) | covered by the "
          "id at the stop | stoppers kept by that id (>= 95 %) | covered (IoU >= 0.3) | MOTA "
          "| IDF1 | ID sw. |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (mode, name), per_seed in results.items():
        rows = [r for _, rs, _ in per_seed for r in rs if r["frames"] > 0]
        frames = sum(r["frames"] for r in rows)
        covered = sum(r["covered"] * r["frames"] for r in rows) / max(frames, 1)
        same = sum(r["same_id"] * r["frames"] for r in rows) / max(frames, 1)
        kept = sum(r["same_id"] > 0.95 for r in rows)
        loose = sum(r["loose"] * r["frames"] for r in rows) / max(frames, 1)
        mota = np.mean([m["mota"] for _, _, m in per_seed])
        idf1 = np.mean([m["idf1"] for _, _, m in per_seed])
        sw = sum(m["num_switches"] for _, _, m in per_seed)
        print(f"| {mode} | {name} | {len(rows)} | {frames} | {covered:.2f} | {same:.2f} | "
              f"{kept}/{len(rows)} | {loose:.2f} | {mota:.3f} | {idf1:.3f} | {sw} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
