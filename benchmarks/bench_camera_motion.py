"""Camera-motion compensation (:mod:`mk_tracker.tracking.camera_motion`): cost, accuracy and
what it does for a track under a panning camera.

In one process it measures

1. **the estimate** of every method and downscale on a generated pan: a 640x480 view
   cropped from a wider rendered crowd scene (:mod:`mk_tracker.synthetic.camera_pan`) at
   offsets that move by a random sub-pixel step of up to ``--max-step`` px per frame, the
   people's true boxes left out (as the tracker does with its boxes); the CPU time of the
   thread per frame (median and 90th percentile) and the error of the estimated translation
   against the known one (mean, 95th percentile, max), and the fall-backs;
2. **a hand-started track under a panning robot camera**: one person walking 2 px/frame,
   the view panning in bursts (8 frames still, 10 frames at ``speed`` px/frame, still, back;
   :func:`~mk_tracker.synthetic.camera_pan.robot_pan_offsets`) for several speeds and
   seeds; the tracker at its defaults with ``camera_motion.enabled`` false and true; mean
   and max centre error and the frames off by more than 20 px;
3. the tracker's own time per frame on the same frames, to compare the estimate's cost with;
4. **multi-object tracking under the same robot pan**: a generated crowd (8 people, 25 fps)
   seen through the panning view, detections = the true boxes of people at least half
   visible with 2 px noise and ``--miss`` of them dropped at random; MOTA / IDF1 (IoU 0.5,
   motmetrics) with compensation off and on, and the ID switches.

Run from the repository (figures go to docs/camera_motion.md by hand)::

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/bench_camera_motion.py
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

import cv2
import numpy as np

from mk_tracker.synthetic.camera_pan import panned_frames, robot_pan_offsets
from mk_tracker.synthetic.presets import crowd_scene
from mk_tracker.synthetic.scene import make_scene
from mk_tracker.synthetic.scene_config import PersonSpec, SceneConfig
from mk_tracker.tracking.camera_motion import CameraMotionConfig, CameraMotionEstimator
from mk_tracker.boxes import clip_box
from mk_tracker.evaluation.metrics import MotRow, mot_metrics
from mk_tracker.tracking.multi_object_tracker import FrameDetection, MultiObjectTracker
from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig

W, H = 640, 480


def estimate_table(frames: int, max_step: float, seed: int) -> list[str]:
    rng = np.random.default_rng(seed)
    steps = rng.uniform(-max_step, max_step, (frames, 2))
    steps[0] = 0.0
    offsets = np.cumsum(steps, axis=0)
    offsets -= offsets.min(axis=0)
    offsets += 4.0
    big_w = int(np.ceil(offsets[:, 0].max())) + W + 8
    big_h = int(np.ceil(offsets[:, 1].max())) + H + 8
    scene = crowd_scene(n_people=8, seed=seed, width=big_w, height=big_h, frames=frames)
    views = list(panned_frames(scene, [tuple(o) for o in offsets], W, H))
    lines = ["| method | downscale | grey frame | median ms | p90 ms | err mean px | err p95 px "
             "| err max px | fall-backs |", "|---|---|---|---|---|---|---|---|---|"]
    for method in ("sparse", "ecc"):
        for downscale in (0.25, 0.5, 1.0):
            est = CameraMotionEstimator(CameraMotionConfig(method=method, downscale=downscale))
            times, errors = [], []
            previous_boxes: list = []
            for k, v in enumerate(views):
                t0 = time.thread_time()
                m = est.estimate(v.rgb, previous_boxes)
                times.append(time.thread_time() - t0)
                previous_boxes = list(v.boxes.values())
                if k == 0:
                    continue
                true = -(offsets[k] - offsets[k - 1])
                if not m.fallback:
                    errors.append(float(np.hypot(*(m.translation - true))))
            ms = np.array(times[1:]) * 1e3
            err = np.array(errors) if errors else np.array([np.nan])
            gw, gh = int(round(W * downscale)), int(round(H * downscale))
            lines.append(f"| {method} | {downscale:g} | {gw}x{gh} | {np.median(ms):.2f} | "
                         f"{np.percentile(ms, 90):.2f} | {np.mean(err):.3f} | "
                         f"{np.percentile(err, 95):.3f} | {np.max(err):.3f} | "
                         f"{est.fallbacks} of {len(views) - 1} |")
            print(lines[-1], flush=True)
    return lines


def pan_scene(speed: float, seed: int, frames: int):
    offsets = robot_pan_offsets(frames, speed=speed, still=8, moving=10, start=(200.0, 0.0))
    width = int(max(o[0] for o in offsets)) + W + 10
    rng = np.random.default_rng([seed, 77])
    y = float(rng.uniform(360, 440))
    people = (PersonSpec(waypoints=((500.0, y), (900.0, y)), speed=2.0,
                         height=float(rng.uniform(110, 170)), after_last="continue"),
              PersonSpec(waypoints=((900.0, y - 100), (400.0, y - 100)), speed=1.5,
                         height=100.0, after_last="continue"))
    scene = make_scene(SceneConfig(seed=seed, frames=frames, width=width, height=H,
                                   people=people))
    return list(panned_frames(scene, offsets, W, H))


#: the compensation settings of sections 2-4 when on (``--downscale``, ``--max-features``)
ON = CameraMotionConfig(enabled=True)


def _config(enabled: bool) -> MultiObjectTrackerConfig:
    return replace(MultiObjectTrackerConfig(),
                   camera_motion=ON if enabled else CameraMotionConfig(enabled=False))


def track_run(views, enabled: bool):
    cfg = _config(enabled)
    trk = MultiObjectTracker(cfg)
    tid = trk.start_track(views[0].rgb, views[0].stamp, views[0].boxes[1])
    errors, times = [], []
    for v in views:
        t0 = time.thread_time()
        res = trk.step(v.rgb, v.stamp)
        times.append(time.thread_time() - t0)
        mine = [t for t in res.tracks if t.id == tid]
        if not mine:
            errors.append(float("inf"))
            continue
        b, g = mine[0].box, v.boxes[1]
        errors.append(float(np.hypot(b[0] + b[2] / 2 - g[0] - g[2] / 2,
                                     b[1] + b[3] / 2 - g[1] - g[3] / 2)))
    return np.array(errors), np.array(times[1:]) * 1e3, trk.totals["camera_motion_fallbacks"]


def tracking_table(speeds, seeds, frames: int) -> list[str]:
    lines = ["| pan px/frame | seed | off: mean err | max | frames > 20 px | ms/frame | "
             "on: mean err | max | frames > 20 px | ms/frame | fall-backs |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for speed in speeds:
        for seed in seeds:
            views = pan_scene(speed, seed, frames)
            cells = []
            fallbacks = 0
            for enabled in (False, True):
                err, ms, fallbacks = track_run(views, enabled)
                cells.append(f"{np.mean(err):.1f} | {np.max(err):.1f} | "
                             f"{int(np.sum(err > 20))} of {len(err)} | {np.median(ms):.2f}")
            lines.append(f"| {speed:g} | {seed} | " + " | ".join(cells) + f" | {fallbacks} |")
            print(lines[-1], flush=True)
    return lines


def crowd_pan(speed: float, seed: int, frames: int, miss: float):
    offsets = robot_pan_offsets(frames, speed=speed, still=8, moving=10, start=(0.0, 0.0))
    width = int(max(o[0] for o in offsets)) + W + 10
    scene = crowd_scene(n_people=8, seed=seed, width=width, height=H, frames=frames)
    rng = np.random.default_rng([seed, 99])
    out = []
    for k, v in enumerate(panned_frames(scene, offsets, W, H)):
        frame = scene.frame(k)
        dets, gt = [], []
        for o in frame.objects:
            if o.id not in v.boxes:
                continue
            clipped = clip_box(v.boxes[o.id], W, H)       # the part inside the view
            if clipped is None:
                continue
            x, y, w, h = (float(c) for c in clipped)
            gt.append(MotRow(k + 1, o.id, (x, y, w, h)))
            if o.visible_fraction >= 0.5 and rng.random() >= miss:
                dets.append(FrameDetection((x + rng.normal(0, 2.0), y + rng.normal(0, 2.0),
                                            w, h), float(rng.uniform(0.6, 1.0))))
        out.append((v.rgb, v.stamp, dets, gt))
    return out


def multi_object_table(speeds, seeds, frames: int, miss: float) -> list[str]:
    lines = ["| pan px/frame | seed | off: MOTA | IDF1 | ID switches | on: MOTA | IDF1 | "
             "ID switches | fall-backs |", "|---|---|---|---|---|---|---|---|---|"]
    for speed in speeds:
        for seed in seeds:
            data = crowd_pan(speed, seed, frames, miss)
            gt = [r for *_, g in data for r in g]
            cells, fallbacks = [], 0
            for enabled in (False, True):
                trk = MultiObjectTracker(_config(enabled))
                hyp = []
                for k, (rgb, stamp, dets, _) in enumerate(data):
                    res = trk.step(rgb, stamp, dets)
                    hyp += [MotRow(k + 1, t.id, t.box) for t in res.reported()]
                m = mot_metrics(gt, hyp)
                cells.append(f"{m['mota']:.3f} | {m['idf1']:.3f} | {m['num_switches']}")
                fallbacks = trk.totals["camera_motion_fallbacks"]
            lines.append(f"| {speed:g} | {seed} | " + " | ".join(cells) + f" | {fallbacks} |")
            print(lines[-1], flush=True)
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--max-step", type=float, default=15.0,
                        help="largest pan step per frame and axis of the estimate test, px")
    parser.add_argument("--speeds", default="0,10,20,30")
    parser.add_argument("--seeds", default="1,2,3")
    parser.add_argument("--miss", type=float, default=0.1,
                        help="fraction of true boxes dropped in the multi-object check")
    default = CameraMotionConfig()
    parser.add_argument("--downscale", type=float, default=default.downscale,
                        help="camera_motion.downscale of sections 2 and 4")
    parser.add_argument("--max-features", type=int, default=default.max_features,
                        help="camera_motion.max_features of sections 2 and 4")
    parser.add_argument("--only", default="", help="run only these sections, e.g. '4' or '1,2'")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    global ON
    ON = replace(CameraMotionConfig(enabled=True), downscale=args.downscale,
                 max_features=args.max_features)
    print(f"sections 2 and 4, on: downscale {ON.downscale:g}, max_features {ON.max_features}")
    print(f"load average {os.getloadavg()}; OpenCV {cv2.__version__}", flush=True)
    only = set(args.only.split(",")) if args.only else {"1", "2", "4"}
    speeds = [float(s) for s in args.speeds.split(",")]
    seeds = [int(s) for s in args.seeds.split(",")]
    if "1" in only:
        estimate_table(args.frames, args.max_step, seed=1)
    if "2" in only:
        tracking_table(speeds, seeds, args.frames)
    if "4" in only:
        multi_object_table(speeds, seeds, args.frames, args.miss)
    print(f"load average {os.getloadavg()}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
