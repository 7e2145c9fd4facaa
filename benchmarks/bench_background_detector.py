"""Background-subtraction detector (issue #13): detection recall/precision and CPU time,
with every default of the detector chosen by leave-one-sequence-out, and the automatic
RGB-only system (background detector -> this tracker) against this tracker on the
sequences' public detections.

    .venv/bin/python benchmarks/bench_background_detector.py --low-fps-checks --out docs/benchmark_background_detector.md

Sequences: TUD-Campus and TUD-Stadtmitte (../shared/data/mot, static cameras, 25 fps,
people present from the first frame), a generated crowd scene (640x480, 3 people,
seed 5, a static camera), and three generated `static_camera` scenes (640x480: small people
crossing at 7 fps, seed 21, and at 25 fps, seed 22, with pairs, a pillar, cast shadows,
the light fading by 25% over the clip, and some walkers stopping for good; and issue #13's
kind, seed 23: 80 people of 40-60 px at 7 fps over 795 frames, about 20 in view, most of
them standing by the end).  Detection is
matched to ground truth one-to-one (Hungarian) at
IoU >= 0.5.  **Recall counts every frame**, the start-up ones too (a detector that waits
for its background pays for the people it missed meanwhile); precision is over the boxes
reported.  Each grid setting (:data:`GRID`) runs on every sequence; for each held-out
sequence the setting with the best mean F1 over the *other* sequences is reported on it
(the primary figures).  Time is the detector's CPU time per 640x480 frame (median over the
frames, thread time).  Peers: plain OpenCV MOG2 connected components (issue #13's recipe)
as a detector, and SORT and norfair fed by it and by our detector.  Our tracker runs on our
detector's boxes with config/tracker_background_detections.yaml (what ``mk_tracker process``
gives ``--detections background``; benchmarks/background_tracker_profile.py chose it) and,
for comparison, with the tracker's defaults alone.  With
``--low-fps-checks``: the real 6.25-fps checks (every 4th frame of the TUD clips, offsets
0-3), each with the setting chosen by the fold that held out its source clip.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from scipy.optimize import linear_sum_assignment

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mk_tracker.bags.dataset_import import import_sequence  # noqa: E402
from mk_tracker.bags.datasets import read_sequence, subsampled  # noqa: E402
from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.detection.background_detector import (BackgroundDetector,  # noqa: E402
                                                      BackgroundDetectorConfig)
from mk_tracker.evaluation.metrics import MotRow, mot_metrics, read_mot_file  # noqa: E402
from mk_tracker.synthetic.presets import static_camera_scene  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402
from mk_tracker.tools import cli  # noqa: E402

sys.path.insert(0, str(ROOT / "benchmarks"))
from peers.mog2_components import Mog2Components  # noqa: E402
from peers.norfair_peer import NorfairPeer  # noqa: E402
from peers.sort_tracker import SortTracker  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "mot"

#: Shadow variants: OpenCV MOG2's own test at two thresholds, and the ratio test of
#: :mod:`mk_tracker.detection.shadows`.
SHADOWS = ({"shadow_method": "model", "shadow_threshold": 0.5},
           {"shadow_method": "model", "shadow_threshold": 0.7},
           {"shadow_method": "ratio"})
#: Every combination is scored on every sequence.
#: (``bootstrap_frames`` 20 and ``join_gap`` 0.3 lost on every sequence in the runs of
#: commit 1809775's report and left the grid; ``min_height_ratio`` 0.0 and 0.5 lost on
#: every sequence in commit b464092's report and left it.  ``min_person_height`` 12 (against
#: 24) was in the grid of commit 74ccb22's run: the folds of both TUD clips and of the 7-fps
#: scene chose it on F1 (mean F1 within 0.006), and it broke their chains with more small
#: boxes, held out MOTA -0.061 / 0.202 / 0.696 against 0.214 / 0.339 / 0.928 at 24; it left.)
GRID: dict[str, tuple] = {
    "bootstrap_frames": (0, 10),
    "join_gap": (0.1,),
    "min_height_ratio": (0.8,),
    "split_ratio": (1.3, 1.6),
    "column_trim": (0.0, 0.2),
    "counts_fps": (0.0, 25.0),
}
#: Real low-frame-rate CHECKS (``--low-fps-checks``), not folds: every ``LOW_FPS_STEP``-th
#: frame of the TUD clips (25 fps -> 6.25 fps, 4x the motion per frame), each offset a run
#: (:func:`mk_tracker.bags.datasets.subsampled`).  They show the people of the 25-fps folds,
#: so each is reported with the setting chosen by the fold that held out its source clip.
LOW_FPS_STEP = 4
LOW_FPS_SOURCES = ("TUD-Campus", "TUD-Stadtmitte")
#: People of the small-people scene: heights at the reference row, and speeds scaled by
#: the mean height so they walk as many body heights per second as the default people
#: (benchmarks/bench_small_far.py's proxy of issue #16's unseen B).
SMALL_HEIGHTS = (40.0, 60.0)
SMALL_SPEED = 50.0 / 77.5
#: The detector as first built for issue #13 (no bootstrap, no size filter): a reference.
BEFORE = {"bootstrap_frames": 0, "min_height_ratio": 0.0, "split_ratio": 1.6,
          "join_gap": 0.3, "column_trim": 0.0, "shadow_method": "model",
          "shadow_threshold": 0.5}


def settings() -> list[dict]:
    out = []
    for values in itertools.product(*GRID.values()):
        for shadow in SHADOWS:
            out.append({**dict(zip(GRID, values)), **shadow})
    return out


def detection_scores(frames, truth, fps: float, config: BackgroundDetectorConfig) -> dict:
    det = BackgroundDetector(config)
    return _scored(lambda k, img: [d.box for d in det.process(img, k / fps, encoding="bgr8")],
                   frames, truth)


def matches(gt, boxes, threshold: float = 0.5) -> list[tuple[int, int]]:
    """One-to-one (Hungarian) pairs ``(truth index, box index)`` at IoU >= ``threshold``."""
    if not gt or not boxes:
        return []
    m = iou_matrix(np.array(gt, float), np.array(boxes, float))
    r, c = linear_sum_assignment(-m)
    return [(int(i), int(j)) for i, j in zip(r, c) if m[i, j] >= threshold]


def _scored(detect, frames, truth) -> dict:
    """Detection recall / precision / F1 (one-to-one at IoU >= 0.5, every frame) and the
    median CPU ms per frame of ``detect``, a ``(frame index, bgr) -> boxes`` callable."""
    tp = fp = fn = 0
    times = []
    for k, img in enumerate(frames):
        t0 = time.thread_time()
        out = detect(k, img)
        times.append(time.thread_time() - t0)
        gt, boxes = truth[k], [tuple(b[:4]) for b in out]
        good = len(matches(gt, boxes))
        tp, fp, fn = tp + good, fp + len(boxes) - good, fn + len(gt) - good
    recall, precision = tp / max(tp + fn, 1), tp / max(tp + fp, 1)
    return {"recall": recall, "precision": precision,
            "f1": 2 * recall * precision / max(recall + precision, 1e-9),
            "ms": 1000 * float(np.median(times))}


def tracking_scores(bag: Path, out: Path, source: str, background: dict | None = None,
                    tracker: dict | None = None, profile: str = "own") -> dict:
    """MOTA / IDF1 / recall / precision of ``mk_tracker process`` on ``bag`` with detections
    from ``source``, the detector's ``background.*`` and the tracker's ``tracker.*``
    parameters changed as given (nested dicts), with the tracker profile ``profile``
    (``--tracker-profile``)."""
    args = ["process", str(bag), "--out", str(out), "--detections", source, "--quiet",
            "--no-video", "--tracker-profile", profile]
    nodes = {}
    if background:
        nodes["/**/detector_node"] = {"ros__parameters": {"background": background}}
    if tracker:
        nodes["/**/tracker_node"] = {"ros__parameters": {"tracker": tracker}}
    if nodes:
        params = out.parent / f"{out.name}.yaml"
        params.write_text(yaml.safe_dump(nodes))
        args += ["--params-file", str(params)]
    cli.main(args)
    m = json.loads((out / "summary.json").read_text())["metrics"]
    return {k: m[k] for k in ("mota", "idf1", "recall", "precision")}


def load_sequences(tmp: Path) -> list[tuple]:
    sequences = []
    for name in ("TUD-Campus", "TUD-Stadtmitte"):
        if (DATA / name).is_dir():
            seq = read_sequence(DATA / name)
            import_sequence(seq, tmp / name)
            frames = [seq.image(k) for k in range(len(seq))]
            truth = [list(seq.ground_truth[k].values()) for k in range(len(seq))]
            sequences.append((name, tmp / name, frames, truth, seq.frame_rate, True))
    for name, slug, scene in (
            ("generated crowd-3 (seed 5)", "crowd",
             build_preset("crowd", seed=5, people=3, frames=120, width=640, height=480)),
            ("generated static camera, 7 fps (seed 21)", "static7",
             build_preset("static_camera", seed=21, frames=210, fps=7.0)),
            ("generated static camera, 25 fps (seed 22)", "static25",
             build_preset("static_camera", seed=22, frames=300, fps=25.0)),
            # issue #13's kind of sequence: small people (40-60 px at 80% of the height,
            # smaller farther up) at 7 fps, many of them, a long clip (as #16's unseen B)
            ("generated small people, 7 fps (seed 23)", "small7",
             static_camera_scene(n_people=80, seed=23, frames=795, fps=7.0,
                                 heights=SMALL_HEIGHTS, speed_scale=SMALL_SPEED))):
        write_scene_bag(scene, tmp / slug)
        frames, truth = [], []
        for k in range(len(scene)):
            f = scene.frame(k)
            frames.append(f.rgb)
            truth.append([o.box_rgb for o in f.objects if o.visible_fraction > 0.5])
        sequences.append((name, tmp / slug, frames, truth, scene.config.fps, False))
    return sequences


def load_low_fps_checks(tmp: Path, offsets=tuple(range(LOW_FPS_STEP))) -> list[tuple]:
    """The real 6.25-fps checks as :func:`load_sequences` tuples, the last item the source
    clip's name: every :data:`LOW_FPS_STEP`-th frame of each TUD clip from each offset, its
    bag written with stamps ``k / 6.25`` s."""
    checks = []
    for source in LOW_FPS_SOURCES:
        if not (DATA / source).is_dir():
            print(f"{DATA / source} is absent: its low-frame-rate checks skipped",
                  file=sys.stderr)
            continue
        full = read_sequence(DATA / source)
        for offset in offsets:
            seq = subsampled(full, LOW_FPS_STEP, offset)
            name = f"{source} {seq.frame_rate:g} fps +{offset}"
            bag = tmp / f"{source}-low{offset}"
            import_sequence(seq, bag)
            frames = [seq.image(k) for k in range(len(seq))]
            truth = [list(seq.ground_truth[k].values()) for k in range(len(seq))]
            checks.append((name, bag, frames, truth, seq.frame_rate, source))
    return checks


def peer_detection_scores(frames, truth) -> dict:
    """Recall / precision / F1 / CPU ms of the plain MOG2 peer, matched as ours."""
    peer = Mog2Components()
    return _scored(lambda _k, img: peer.detect(img), frames, truth)


def peer_tracking_scores(frames, fps: float, gt_file: Path, detector, trackers) -> dict:
    """MOTA / IDF1 / recall / precision of each peer tracker fed by ``detector`` (a
    ``(frame index, bgr) -> [(x, y, w, h, score)]`` callable run once), scored against the
    ground truth that ``mk_tracker process`` wrote for our run of the same bag (the same
    frames)."""
    detections = [detector(k, img) for k, img in enumerate(frames)]
    gt = read_mot_file(gt_file, ground_truth=True)
    out = {}
    for name, make in trackers.items():
        trk, hyp = make(), []
        for k, dets in enumerate(detections):
            hyp.extend(MotRow(k + 1, tid, tuple(box)) for tid, box in trk.update(k / fps, dets))
        m = mot_metrics(gt, hyp)
        out[name] = {"mota": m["mota"], "idf1": m["idf1"], "recall": m["recall"],
                     "precision": m["precision"]}
    return out


def chain_rows(name: str, bag: Path, frames, fps: float, public: bool, held: dict,
               tmp: Path) -> list[tuple[str, dict]]:
    """Tracking scores of the RGB-only chain on one sequence: our detector (the setting
    ``held`` and the shipped defaults) -> this tracker, the public detections -> this
    tracker (``public``), and plain MOG2 / our detector -> SORT and norfair."""
    # our tracker on the background detector's boxes with the parameters a user gets
    # (--tracker-profile auto: config/tracker_background_detections.yaml), and with the
    # shipped defaults alone (own) for comparison; the public detections with the defaults
    rows = [("background, setting held out -> ours",
             tracking_scores(bag, tmp / f"{name}-held", "background", held, profile="auto")),
            ("background, shipped defaults -> ours",
             tracking_scores(bag, tmp / f"{name}-bg", "background", profile="auto")),
            ("background, shipped defaults -> ours, tracker defaults (no profile)",
             tracking_scores(bag, tmp / f"{name}-own", "background"))]
    if public:
        rows.append(("public detections -> ours",
                     tracking_scores(bag, tmp / f"{name}-pub", "topic:/detections")))
    ours, plain = BackgroundDetector(BackgroundDetectorConfig()), Mog2Components()

    def background_boxes(k, img):
        return [(*d.box, d.score) for d in ours.process(img, k / fps, encoding="bgr8")]
    peers = {"SORT": SortTracker, "norfair": NorfairPeer}
    gt_file = tmp / f"{name}-bg" / "gt.txt"
    for det_name, det in (("plain MOG2 components", lambda _k, img: plain.detect(img)),
                          ("background, shipped defaults", background_boxes)):
        for trk_name, s in peer_tracking_scores(frames, fps, gt_file, det, peers).items():
            rows.append((f"{det_name} -> {trk_name}", s))
    return rows


def low_fps_lines(checks: list[tuple], held: dict, tmp: Path) -> list[str]:
    """The section of the real 6.25-fps checks (:func:`load_low_fps_checks`): detector
    recall / precision and the chain's MOTA / IDF1 per check, each with the setting chosen
    by the fold that held out its source clip (``held``: source -> setting), the shipped
    defaults and the plain-MOG2 peers; then the means over the offsets per source."""
    if not checks:
        return []
    lines = ["", "## Real video at 6.25 fps (checks, not folds)", "",
             f"Every {LOW_FPS_STEP}th frame of " + " and ".join(LOW_FPS_SOURCES)
             + " (25 fps -> 6.25 fps, 4x the motion per frame; each offset 0-3 a separate "
             "run, stamps k / 6.25 s; `mk_tracker.bags.datasets.subsampled`).  They show the "
             "people of the 25-fps folds, so each is reported with the setting chosen by the "
             "fold that held out its source clip (`held out`).  Run with `--low-fps-checks`.",
             "", "| check | detector | recall | precision | F1 | CPU ms / frame |",
             "|---|---|---|---|---|---|"]
    det_rows, chain = [], []
    for name, bag, frames, truth, fps, source in checks:
        for what, s in (
                ("background, setting held out",
                 detection_scores(frames, truth, fps,
                                  BackgroundDetectorConfig(**held[source]))),
                ("background, shipped defaults",
                 detection_scores(frames, truth, fps, BackgroundDetectorConfig())),
                ("plain MOG2 components", peer_detection_scores(frames, truth))):
            det_rows.append((source, what, s))
            lines.append(f"| {name} | {what} | {s['recall']:.3f} | {s['precision']:.3f} | "
                         f"{s['f1']:.3f} | {s['ms']:.1f} |")
            print(lines[-1], file=sys.stderr, flush=True)
        for what, s in chain_rows(name.replace(" ", "_"), bag, frames, fps, True,
                                  held[source], tmp):
            chain.append((source, what, s))
    lines += ["", "| check | detections -> tracker | MOTA | IDF1 | recall | precision |",
              "|---|---|---|---|---|---|"]
    k = 0
    for name, *_rest in checks:
        n = len(chain) // len(checks)
        for _source, what, s in chain[k:k + n]:
            lines.append(f"| {name} | {what} | {s['mota']:.3f} | {s['idf1']:.3f} | "
                         f"{s['recall']:.3f} | {s['precision']:.3f} |")
        k += n
    lines += ["", "Mean over the offsets (detector recall / precision; chain MOTA / IDF1):",
              "", "| what | " + " | ".join(LOW_FPS_SOURCES) + " |",
              "|---|" + "---|" * len(LOW_FPS_SOURCES)]
    for rows, keys in ((det_rows, ("recall", "precision")), (chain, ("mota", "idf1"))):
        for what in dict.fromkeys(w for _s, w, _v in rows):
            cells = []
            for source in LOW_FPS_SOURCES:
                vals = [v for s, w, v in rows if s == source and w == what]
                cells.append("-" if not vals else " / ".join(
                    f"{np.mean([v[key] for v in vals]):.3f}" for key in keys))
            lines.append(f"| {what} | " + " | ".join(cells) + " |")
    return lines


def _short(setting: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in setting.items())


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--low-fps-checks", action="store_true",
                        help="also the real 6.25-fps checks (every 4th frame of the TUD "
                        "clips, offsets 0-3)")
    parser.add_argument("--grid", nargs="*", default=[], metavar="KEY=V1,V2",
                        help="GRID dimensions replaced (or added) for this run, values as "
                        "YAML, e.g. min_height_ratio=0.5,0.8 column_trim=0.2")
    args = parser.parse_args(argv)
    for item in args.grid:
        key, values = item.split("=", 1)
        GRID[key] = tuple(yaml.safe_load(v) for v in values.split(","))
    grid = settings()
    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sequences = load_sequences(tmp)
        names = [s[0] for s in sequences]
        scores = {}                       # (setting index, sequence) -> detection scores
        for i, setting in enumerate(grid):
            cfg = BackgroundDetectorConfig(**setting)
            # at the frame rate it counts at, counts_fps changes nothing (the same boxes:
            # test_background_frame_rate.py): its twin's scores are taken
            twin = grid.index({**setting, "counts_fps": 0.0})
            for name, _bag, frames, truth, fps, _pub in sequences:
                scores[i, name] = (scores[twin, name] if twin < i and setting["counts_fps"] == fps
                                   else detection_scores(frames, truth, fps, cfg))
            print(i, _short(setting), " | ".join(
                f"{n}: R {scores[i, n]['recall']:.3f} P {scores[i, n]['precision']:.3f}"
                for n in names), file=sys.stderr, flush=True)
        choices = {}
        for held in names:
            others = [n for n in names if n != held]
            choices[held] = max(range(len(grid)), key=lambda i: np.mean(
                [scores[i, n]["f1"] for n in others]))
        overall = max(range(len(grid)), key=lambda i: np.mean([scores[i, n]["f1"]
                                                             for n in names]))
        before = {n: detection_scores(frames, truth, fps, BackgroundDetectorConfig(**BEFORE))
                  for n, _bag, frames, truth, fps, _pub in sequences}
        lines += ["## Detector, held out (primary)", "",
                  "| held-out sequence | setting chosen on the others | recall | precision "
                  "| F1 | CPU ms / frame |", "|---|---|---|---|---|---|"]
        for held in names:
            s = scores[choices[held], held]
            lines.append(f"| {held} | {_short(grid[choices[held]])} | {s['recall']:.3f} | "
                         f"{s['precision']:.3f} | {s['f1']:.3f} | {s['ms']:.1f} |")
        lines += ["", "Reference, the settings of the detector as first built for issue #13 "
                  "(with today's code; "
                  + _short(BEFORE) + "):", "",
                  "| sequence | recall | precision | F1 | CPU ms / frame |",
                  "|---|---|---|---|---|"]
        for n in names:
            s = before[n]
            lines.append(f"| {n} | {s['recall']:.3f} | {s['precision']:.3f} | "
                         f"{s['f1']:.3f} | {s['ms']:.1f} |")
        lines += ["", "Peer: plain OpenCV MOG2 connected components (issue #13's recipe: "
                  "history 200, varThreshold 16, shadows dropped, open/close 5x5, "
                  "person-shaped components; `benchmarks/peers/mog2_components.py`):", "",
                  "| sequence | recall | precision | F1 | CPU ms / frame |",
                  "|---|---|---|---|---|"]
        for name, _bag, frames, truth, _fps, _pub in sequences:
            s = peer_detection_scores(frames, truth)
            lines.append(f"| {name} | {s['recall']:.3f} | {s['precision']:.3f} | "
                         f"{s['f1']:.3f} | {s['ms']:.1f} |")
        lines += ["", f"Best mean F1 over all {len(names)} sequences (the library defaults; not a "
                  f"held-out figure): {_short(grid[overall])}.", "",
                  f"### Each dimension: the best setting with that value ({len(grid)} "
                  "settings; F1 per sequence, all frames)", "",
                  "| dimension = value | " + " | ".join(names) + " | mean |",
                  "|---|" + "---|" * (len(names) + 1)]
        dims = list(GRID) + ["shadow"]
        for dim in dims:
            values = GRID.get(dim) or tuple(_short(v) for v in SHADOWS)
            for value in values:
                members = [i for i, st in enumerate(grid)
                           if (st.get(dim) == value if dim != "shadow" else
                               _short({k: st[k] for k in st if k.startswith("shadow")})
                               == value)]
                best = max(members, key=lambda i: np.mean([scores[i, n]["f1"]
                                                           for n in names]))
                f1 = [scores[best, n]["f1"] for n in names]
                label = f"{dim} = {value}" if dim != "shadow" else value
                lines.append(f"| {label} | " + " | ".join(f"{v:.3f}" for v in f1)
                             + f" | {np.mean(f1):.3f} |")
        lines += ["", "## Tracking: background detector -> this tracker", "",
                  "| sequence | detections -> tracker | MOTA | IDF1 | recall | precision |",
                  "|---|---|---|---|---|---|"]
        for name, bag, frames, _truth, fps, public in sequences:
            for what, s in chain_rows(name, bag, frames, fps, public, grid[choices[name]], tmp):
                lines.append(f"| {name} | {what} | {s['mota']:.3f} | {s['idf1']:.3f} | "
                             f"{s['recall']:.3f} | {s['precision']:.3f} |")
                print(lines[-1], file=sys.stderr, flush=True)
        if args.low_fps_checks:
            checks = load_low_fps_checks(tmp)
            lines += low_fps_lines(checks, {c[5]: grid[choices[c[5]]] for c in checks
                                            if c[5] in choices}, tmp)
    table = "\n".join(lines)
    print(table)
    if args.out:
        args.out.write_text("# Background-subtraction detector (issue #13)\n\nProduced by:\n\n"
                            "```\n.venv/bin/python benchmarks/bench_background_detector.py "
                            + ("--low-fps-checks " if args.low_fps_checks else "")
                            + ("--grid " + " ".join(args.grid) + " " if args.grid else "")
                            + "--out docs/benchmark_background_detector.md\n```\n\n"
                            + __doc__.split("\n\n", 2)[2] + "\n" + table + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
