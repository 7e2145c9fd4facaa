"""How people move and how detections err, measured without any tracker (issue #16).

The generated development sequences of bench_multi_object.py (``crowd-15``, ``far-7fps``)
and the real TUD clips disagree about coasting boxes; this script compares the *motion* of
their ground truth and the *error* of their detections, in units that carry over between
image scales and frame rates (box heights, seconds):

* per identity, the box centre's velocity (box heights per second, H/s), the spread of its
  acceleration (velocity over 0.2 s windows, change per second, H/s^2);
* the drift of a constant-velocity extrapolation -- the velocity of the last 0.2 s carried
  on for 0.2 / 0.5 / 1 s, the Kalman prediction of a coasting track without its noise --
  from where the person really is, in box heights (median and 90th percentile);
* the public detections' error against the matched truth (IoU >= 0.5): centre offset and
  size as fractions of the true height, and the lag-1 / lag-5 frame autocorrelation of the
  centre error along a person (1 = a slowly varying offset, 0 = i.i.d.), against the
  bench's generated detections (``--noise`` px i.i.d. centre, 3% size).

    .venv/bin/python benchmarks/diagnose_motion.py [--real-motion] [--out report.md]

``--real-motion`` builds the generated scenes with the motion variation of
:data:`bench_multi_object.REAL_MOTION` (people.py: heading and speed follow Ornstein-
Uhlenbeck processes) instead of today's piecewise-straight walks.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from mk_tracker.bags.datasets import read_mot_sequence  # noqa: E402
from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.synthetic.presets import crowd_scene, far_view_scene  # noqa: E402

HORIZONS = (0.2, 0.5, 1.0)   # seconds of constant-velocity extrapolation
WINDOW = 0.2                 # seconds over which the extrapolated velocity is measured


def tracks_from_frames(boxes_per_frame) -> dict:
    """``{id: (frame indices, (n, 4) boxes)}`` from a list of ``{id: (x, y, w, h)}``."""
    out: dict = {}
    for k, frame in enumerate(boxes_per_frame):
        for i, b in frame.items():
            out.setdefault(i, ([], []))
            out[i][0].append(k)
            out[i][1].append(tuple(float(v) for v in b))
    return {i: (np.asarray(f, int), np.asarray(b, float).reshape(-1, 4))
            for i, (f, b) in out.items()}


def _runs(frames: np.ndarray) -> list[slice]:
    """Slices of consecutive frame indices."""
    if len(frames) == 0:
        return []
    cuts = np.flatnonzero(np.diff(frames) != 1) + 1
    edges = np.concatenate(([0], cuts, [len(frames)]))
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def motion_statistics(tracks: dict, fps: float, horizons=HORIZONS,
                      window: float = WINDOW) -> dict:
    """Motion statistics of box centres, in box heights (H) and seconds.

    ``speed``: the per-frame centre speed (H/s) pooled over every person and frame;
    ``accel``: the change per second of the ``window``-second velocity between consecutive
    windows (H/s^2), pooled; ``drift[T]``: distance, in heights at the start, between the
    centre ``T`` s after a frame and its constant-velocity extrapolation from that frame
    with the velocity of the ``window`` s before it (only horizons whose frame offset is
    exact at ``fps`` within half a frame are kept)."""
    lag = max(int(round(window * fps)), 1)
    speeds, accels = [], []
    drift: dict = {t: [] for t in horizons}
    for frames, boxes in tracks.values():
        for run in _runs(frames):
            b = boxes[run]
            if len(b) < 2:
                continue
            c = b[:, :2] + b[:, 2:] / 2.0
            h = np.maximum(b[:, 3], 1.0)
            step = np.diff(c, axis=0) * fps / h[:-1, None]
            speeds.extend(np.hypot(step[:, 0], step[:, 1]).tolist())
            if len(c) > 2 * lag:
                v = (c[lag:] - c[:-lag]) * fps / lag / h[lag:, None]   # H/s, ends at k+lag
                dv = (v[lag:] - v[:-lag]) * fps / lag                  # H/s^2
                accels.extend(np.hypot(dv[:, 0], dv[:, 1]).tolist())
            for t in horizons:
                ahead = int(round(t * fps))
                if ahead < 1 or len(c) <= lag + ahead:
                    continue
                k = np.arange(lag, len(c) - ahead)
                vel = (c[k] - c[k - lag]) / lag                         # px per frame
                err = c[k + ahead] - (c[k] + vel * ahead)
                drift[t].extend((np.hypot(err[:, 0], err[:, 1]) / h[k]).tolist())
    return {"speed": np.asarray(speeds), "accel": np.asarray(accels),
            "drift": {t: np.asarray(v) for t, v in drift.items()}}


def detection_errors(truth_per_frame, dets_per_frame, min_iou: float = 0.5) -> dict:
    """Errors of the detections matched (greedy by IoU >= ``min_iou``) to the truth.

    ``dx``, ``dy``: centre offset over the true height; ``dw``, ``dh``: width and height
    ratio minus 1; ``autocorr``: ``{1: r1, 5: r5}``, the correlation of the centre offset
    of the same person ``lag`` frames apart (both frames matched), the mean of x's and
    y's; ``miss_runs``: lengths in frames of every run of frames in which a person of the
    truth has no matched detection; ``truth_boxes``: their number."""
    per_id: dict = {}
    dx, dy, dw, dh = [], [], [], []
    for k, (truth, dets) in enumerate(zip(truth_per_frame, dets_per_frame)):
        ids = list(truth)
        if not ids or not dets:
            continue
        t = np.asarray([truth[i] for i in ids], float)
        d = np.asarray([x[:4] for x in dets], float)
        m = iou_matrix(t, d)
        used: set = set()
        for flat in np.argsort(-m, axis=None):
            r, q = divmod(int(flat), m.shape[1])
            if m[r, q] < min_iou:
                break
            if ids[r] in per_id and k in per_id[ids[r]] or q in used:
                continue
            used.add(q)
            tb, db = t[r], d[q]
            h = max(tb[3], 1.0)
            e = ((db[0] + db[2] / 2 - tb[0] - tb[2] / 2) / h,
                 (db[1] + db[3] / 2 - tb[1] - tb[3] / 2) / h)
            per_id.setdefault(ids[r], {})[k] = e
            dx.append(e[0])
            dy.append(e[1])
            dw.append(db[2] / max(tb[2], 1.0) - 1.0)
            dh.append(db[3] / h - 1.0)
    auto = {}
    for lag in (1, 5):
        a, b = [], []
        for errs in per_id.values():
            for k, e in errs.items():
                if k + lag in errs:
                    a.append(e)
                    b.append(errs[k + lag])
        a_, b_ = np.asarray(a).reshape(-1, 2), np.asarray(b).reshape(-1, 2)
        auto[lag] = float(np.mean([np.corrcoef(a_[:, j], b_[:, j])[0, 1] for j in (0, 1)])) \
            if len(a) > 2 else float("nan")
    present: dict = {}
    for k, truth in enumerate(truth_per_frame):
        for i in truth:
            present.setdefault(i, []).append(k)
    runs = []   # lengths (frames) of runs of a present person without a matched detection
    for i, ks in present.items():
        hit = per_id.get(i, {})
        run = 0
        for k in ks:
            if k in hit:
                if run:
                    runs.append(run)
                run = 0
            else:
                run += 1
        if run:
            runs.append(run)
    return {"dx": np.asarray(dx), "dy": np.asarray(dy), "dw": np.asarray(dw),
            "dh": np.asarray(dh), "autocorr": auto, "miss_runs": np.asarray(runs, int),
            "truth_boxes": sum(len(ks) for ks in present.values())}


def real_clip(folder: Path):
    """``(tracks, fps, truth per frame, detections per frame)`` of a MOTChallenge clip."""
    seq = read_mot_sequence(folder)
    truth = [dict(g) for g in seq.ground_truth]
    dets = [[tuple(d.box) for d in frame] for frame in (seq.detections or ())]
    return tracks_from_frames(truth), float(seq.frame_rate), truth, dets


def generated_tracks(scene) -> tuple[dict, float]:
    """Tracks of a generated scene's people while their box centre is inside the image
    (boxes from the paths, no rendering)."""
    c = scene.config
    width, height = scene.rgb_size
    frames = []
    for k in range(len(scene)):
        boxes = scene.boxes_thermal(k)
        frames.append({i + 1: tuple(b) for i, b in enumerate(boxes)
                       if 0 <= b[0] + b[2] / 2 < width and 0 <= b[1] + b[3] / 2 < height})
    return tracks_from_frames(frames), float(c.fps)


def generated_detection_errors(scene, noise: float, seed: int,
                               box_error: dict | None = None, miss: float = 0.1) -> dict:
    """The bench's detections (bench_multi_object.scene_frames: people at least half
    visible, ``miss`` of them missed, ``noise`` px i.i.d. or ``box_error``) against the
    scene's ground truth (every person in the frame)."""
    import bench_multi_object as bench
    frames, _ = bench.scene_frames(scene, seed, 0.5, miss, 0.0, noise, box_error=box_error)
    truth = [{row.id: row.box for row in gt} for _, _, _, gt in frames]
    dets = [d for _, _, d, _ in frames]
    return detection_errors(truth, dets)


def _q(values, q) -> str:
    return f"{np.percentile(values, q):.3f}" if len(values) else "-"


def motion_row(name: str, stats: dict) -> str:
    cells = [name, _q(stats["speed"], 50), _q(stats["accel"], 50), _q(stats["accel"], 90)]
    for t in HORIZONS:
        cells += [_q(stats["drift"][t], 50), _q(stats["drift"][t], 90)]
    return "| " + " | ".join(cells) + " |"


def error_row(name: str, e: dict, fps: float) -> str:
    def sd(v):
        return f"{np.std(v):.3f}" if len(v) else "-"
    runs = e["miss_runs"]
    long = int(runs[runs >= 0.5 * fps].sum()) / max(e["truth_boxes"], 1)
    return (f"| {name} | {len(e['dx'])} | {sd(e['dx'])} | {sd(e['dy'])} | {sd(e['dw'])} | "
            f"{sd(e['dh'])} | {e['autocorr'][1]:.2f} | {e['autocorr'][5]:.2f} | "
            f"{runs.sum() / max(e['truth_boxes'], 1):.3f} | {long:.3f} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--seed", type=int, default=1, help="the bench's seed (default 1)")
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--noise", type=float, default=2.0)
    parser.add_argument("--real-motion", action="store_true",
                        help="generated scenes with bench_multi_object.REAL_MOTION")
    parser.add_argument("--window", type=float, default=WINDOW,
                        help="seconds over which the extrapolated velocity is measured "
                             "(default 0.2; longer windows damp annotation jitter)")
    parser.add_argument("--motion", type=float, nargs=3, default=None,
                        metavar=("HEADING_STD", "SPEED_STD", "TIME_CONSTANT"),
                        help="generated scenes with this motion variation instead")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    import bench_multi_object as bench
    motion = bench.REAL_MOTION if args.real_motion else None
    if args.motion is not None:
        motion = dict(zip(("heading_std", "speed_std", "time_constant"), args.motion))
    lines = ["| sequence | speed H/s (median) | accel H/s^2 (median) | (p90) | "
             + " | ".join(f"CV drift {t:g} s (median) | (p90)" for t in HORIZONS) + " |",
             "|" + "---|" * (4 + 2 * len(HORIZONS))]
    errors = ["| sequence | matched | centre x sd (H) | centre y sd (H) | width ratio sd | "
              "height ratio sd | autocorr lag 1 | lag 5 | truth unmatched | in runs >= 0.5 s |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for name in ("TUD-Campus", "TUD-Stadtmitte"):
        folder = args.data / "mot" / name
        if not folder.is_dir():
            print(f"{folder} is absent: skipped", file=sys.stderr)
            continue
        tracks, fps, truth, dets = real_clip(folder)
        lines.append(motion_row(name, motion_statistics(tracks, fps, window=args.window)))
        errors.append(error_row(name + " (public)", detection_errors(truth, dets), fps))
    scenes = {f"crowd-15 (seed {args.seed})": crowd_scene(15, seed=args.seed,
                                                          frames=args.frames, motion=motion),
              f"far-7fps (seed {args.seed})": far_view_scene(seed=args.seed, motion=motion)}
    for name, scene in scenes.items():
        tracks, fps = generated_tracks(scene)
        lines.append(motion_row(name, motion_statistics(tracks, fps, window=args.window)))
    name, scene = next(iter(scenes.items()))
    fps = float(scene.config.fps)
    errors.append(error_row(f"{name} (bench, {args.noise:g} px)",
                            generated_detection_errors(scene, args.noise, args.seed), fps))
    errors.append(error_row(f"{name} (bench, --real-detection-noise)",
                            generated_detection_errors(scene, args.noise, args.seed,
                                                       bench.REAL_DETECTION_NOISE), fps))
    text = "\n".join([f"Motion (generator motion {motion}; velocity over "
                      f"{args.window:g} s):", ""] + lines + ["", "Detection error:", ""] + errors) + "\n"
    print(text)
    if args.out is not None:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
