"""Single-target benchmark of the multiple-kernel tracker against OpenCV's trackers.

Default (issue #16): the **leave-one-clip-out protocol** of the hand-started tracker.  The
development set (:func:`development_set`: OTB Crossing, OTB Woman, every TUD-Campus and
TUD-Stadtmitte person, TUD-Stadtmitte at 6.25 fps, generator scenes at 7 fps with edge
entries and fast walkers, a generator crowd) is run with every setting of a small grid of
``manual_track`` settings (:data:`GRID`) and with CSRT and KCF on the same frames; for each
clip the setting with the best success AUC on the other clips is chosen and reported on it
(:func:`loso_main`).  It writes ``docs/benchmark_single_target.md``; ``--json FILE`` also
dumps every figure.  ``--legacy`` gives the older in-sample tables described below.
``--set NAME=VALUE ...`` changes the tracker's defaults under every grid setting, so a
candidate default is measured held out (``--output`` elsewhere keeps the committed report).

Runs, in one process on the same frames, the projected-gradient multiple-kernel tracker
(1/2/4/6 kernels, with and without projected gradient, the single-kernel mean shift baseline
and the paper's eps_J = 0.7N), our full tracker (the multiple-kernel refinement inside the
Kalman filter of :class:`mk_tracker.tracking.multi_object_tracker.MultiObjectTracker`, Chu et al.
Sec. IV-D, one target started by hand, no detector) with its defaults for tracks started by
hand (``MultiObjectTrackerConfig.manual_track``) and two experimental variants of them, and
OpenCV's model-free trackers (CamShift and meanShift from the main package; MIL; KCF and CSRT
when opencv-contrib is installed) on

* the synthetic occlusion scenes of :mod:`mk_tracker.synthetic.presets` (lower-body wall, full
  pillar, crossing people, approach = scale change),
* ``../shared/data/otb/Crossing``,
* every person of ``../shared/data/mot/TUD-Campus`` as a single target, initialised from its
  first ground-truth box and scored on the frames where it has a box (Table I protocol).

It prints and writes ``docs/benchmark_single_target.md``: a check of issue #3's goals, per
sequence the mean centre error (px), precision at 20 px, success AUC (IoU), the median
milliseconds per frame per target (including the colour conversion of the search region; one
thread) and how often each tracker said it did not see the target (against the synthetic
truth's hidden frames), and where the error on the lower-body wall scene comes from.

KCF/CSRT need ``opencv-contrib-python-headless`` which conflicts with the main package, so run
the benchmark from a separate environment (see ``benchmarks/requirements.txt``)::

    python3 -m venv /tmp/bench_venv
    /tmp/bench_venv/bin/pip install -r benchmarks/requirements.txt
    PYTHONPATH=. OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 \
        /tmp/bench_venv/bin/python benchmarks/bench_single_target.py

A subset (no report is written unless ``--output`` is given)::

    ... bench_single_target.py --trackers 'MK 2 kernels (PG),CSRT' --sequences 'pillar,person 2'
    ... bench_single_target.py --list
    ... bench_single_target.py --sequences held-out --held-out-seeds 31,32,33,34

With the project's own .venv the contrib trackers are reported as unavailable.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Iterator

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from mk_tracker.boxes import clip_box  # noqa: E402
from mk_tracker.bags.datasets import (DEFAULT_FRAME_RATE, read_mot_sequence,  # noqa: E402
                                      subsampled)
from mk_tracker.evaluation.metrics import read_box_list, read_mot_file, single_target_metrics  # noqa: E402
from mk_tracker.tracking.multi_kernel import (MultiKernelConfig, MultiKernelTracker,  # noqa: E402
                                     TrackingInputError, mean_shift_baseline_config,
                                     paper_config)
from mk_tracker.tracking.manual_track import (ManualTrackConfig,  # noqa: E402
                                              manual_track_multi_kernel)
from mk_tracker.tracking.multi_object_tracker import (MultiObjectTracker,  # noqa: E402
                                              MultiObjectTrackerConfig, TrackerInputError)
from mk_tracker.tracking.track import TrackState  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from setting_values import setting_changes, setting_value  # noqa: E402
from mk_tracker.synthetic.presets import (approach_scene, crossing_scene,  # noqa: E402
                                          crowd_scene, occlusion_scene)

DATA = REPO.parent / "shared" / "data"
#: a synthetic target counts as hidden in a frame when less than this share of its
#: silhouette is visible (ObjectTruth.visible_fraction) or it is outside the image
HIDDEN_FRACTION = 0.1


@dataclass
class Sequence:
    name: str
    frames: Callable[[], Iterator[np.ndarray]]   # BGR uint8 frames, in order
    truth: list                                  # box or None per frame
    init_box: tuple
    fps: float = DEFAULT_FRAME_RATE
    # per frame: share of the target's silhouette that is visible (0 outside the image);
    # None when the data set does not say (real sequences)
    visible: list | None = None

    @property
    def hidden(self) -> list | None:
        """Per frame: visible fraction below :data:`HIDDEN_FRACTION` (or out of the image)."""
        return None if self.visible is None else [v < HIDDEN_FRACTION for v in self.visible]


@dataclass
class Step:
    """A tracker's answer for one frame: the box that is scored, and whether the tracker
    itself said it does not see the target (MK: lost/occluded; OpenCV: ``ok=False``)."""

    box: tuple
    said_hidden: bool = False


# ------------------------------------------------------------------------------------------
# sequences

def synthetic_sequence(name: str, scene, object_id: int) -> Sequence:
    truth, visible = [], []
    for i in range(len(scene)):
        obj = scene.ground_truth(i)
        o = next(t for t in obj if t.id == object_id)
        box = clip_box(o.box_rgb, scene.config.width, scene.config.height) \
            if o.in_frame_rgb else None
        truth.append(box)
        visible.append(0.0 if box is None else float(o.visible_fraction))
    return Sequence(name, lambda: (scene.frame(i).rgb for i in range(len(scene))), truth,
                    truth[0], fps=scene.config.fps, visible=visible)


def synthetic_sequences() -> list[Sequence]:
    return [
        synthetic_sequence("synthetic lower-body wall", occlusion_scene(full=False), 1),
        synthetic_sequence("synthetic full pillar", occlusion_scene(full=True), 1),
        synthetic_sequence("synthetic crossing (near)", crossing_scene(), 1),
        synthetic_sequence("synthetic crossing (far)", crossing_scene(), 2),
        synthetic_sequence("synthetic approach (scale)", approach_scene(), 1),
    ]


HELD_OUT_SEEDS = (11, 12)


def held_out_sequences(seeds: tuple[int, ...] = HELD_OUT_SEEDS) -> list[Sequence]:
    """Every person of two generator crowd scenes (5 people, 150 frames, random turns,
    crossings, 2 pillars; seeds not used anywhere else) as a single target: sequences that
    played no part in choosing any setting of this benchmark (the experimental rows' settings
    were chosen on the other sequences).  Not part of issue #3's goal.  ``seeds``
    (``--held-out-seeds``) gives other scenes for a fresh check."""
    out = []
    for seed in seeds:
        scene = crowd_scene(n_people=5, seed=seed, frames=150)
        for pid in range(1, 6):
            seq = synthetic_sequence(f"held-out crowd seed {seed} person {pid}", scene, pid)
            if seq.truth[0] is not None:
                out.append(seq)
    return out


def _image_reader(paths: list[Path]) -> Callable[[], Iterator[np.ndarray]]:
    return lambda: (cv2.imread(str(p), cv2.IMREAD_COLOR) for p in paths)


def otb_sequences() -> list[Sequence]:
    root = DATA / "otb" / "Crossing"
    if not root.is_dir():
        return []
    paths = sorted((root / "img").glob("*.jpg"))
    truth = read_box_list(root / "groundtruth_rect.txt")[:len(paths)]
    return [Sequence("OTB Crossing", _image_reader(paths), truth, truth[0])]


def tud_sequences() -> list[Sequence]:
    root = DATA / "mot" / "TUD-Campus"
    if not root.is_dir():
        return []
    paths = sorted((root / "img1").glob("*.jpg"))
    rows = read_mot_file(root / "gt" / "gt.txt", ground_truth=True)
    out = []
    for pid in sorted({r.id for r in rows}):
        mine = {r.frame: tuple(r.box) for r in rows if r.id == pid}
        first, last = min(mine), max(mine)
        sub = paths[first - 1:last]
        truth = [mine.get(f) for f in range(first, last + 1)]
        out.append(Sequence(f"TUD-Campus person {pid}", _image_reader(sub), truth, truth[0]))
    return out


# ------------------------------------------------------------------------------------------
# trackers: each is a factory make(seq) returning (init(frame, box), update(frame) -> Step)

def multi_kernel_factory(config: MultiKernelConfig):
    """The bare multiple-kernel refinement (Algorithm 1), each frame from the last result."""
    def make(seq: Sequence):
        tracker = MultiKernelTracker(config)
        holder = {}

        def init(frame, box):
            holder["state"] = tracker.start(frame, box)

        def update(frame):
            # a lost result leaves the state where it was: report that last known box
            res = tracker.refine(frame, holder["state"])
            return Step(holder["state"].box, True) if res.lost else Step(res.box)
        return init, update
    return make


def full_tracker_factory(config: MultiObjectTrackerConfig):
    """Our full tracker (Chu et al. Sec. IV-D): :class:`MultiObjectTracker` with one track
    started by hand on the first box, as ``tracker_node``'s ``initial_box`` / ``~/start_track``
    and ``mk_tracker process --init-from-gt`` do, and no detector input, so the track runs with
    ``config.manual_track``.  Each frame the Kalman prediction initialises the multiple-kernel
    search, whose result is the measurement; below ``manual_track.occlusion_similarity`` the
    track coasts (state ``occluded``) on the prediction.  The scored box is the track's box in
    every state (the prediction while it coasts)."""
    def make(seq: Sequence):
        tracker = MultiObjectTracker(config)
        holder = {"frame": 0}

        def stamp():
            return holder["frame"] / seq.fps

        def init(frame, box):
            holder["id"] = tracker.start_track(frame, stamp(), box)
            tracker.step(frame, stamp())        # the start frame, as the pipeline does

        def update(frame):
            holder["frame"] += 1
            res = tracker.step(frame, stamp())
            mine = [t for t in res.tracks if t.id == holder["id"]]
            if not mine:                        # deleted (left the image long ago)
                return Step(holder["last"], True)
            t = mine[0]
            holder["last"] = t.box
            return Step(t.box, t.state != TrackState.CONFIRMED.value)
        return init, update
    return make


def camshift_factory(use_camshift: bool):
    """OpenCV's CamShift / meanShift on a hue back-projection (the OpenCV tutorial recipe)."""
    def make(seq: Sequence):
        holder = {}
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 1)

        def init(frame, box):
            box = clip_box(box, frame.shape[1], frame.shape[0])
            x, y, w, h = (int(round(v)) for v in box)
            hsv = cv2.cvtColor(frame[y:y + h, x:x + w], cv2.COLOR_BGR2HSV)
            mask = cv2.inRange(hsv, (0, 40, 30), (180, 255, 255))
            hist = cv2.calcHist([hsv], [0], mask, [16], [0, 180])
            cv2.normalize(hist, hist, 0, 255, cv2.NORM_MINMAX)
            holder.update(hist=hist, window=(x, y, max(w, 1), max(h, 1)))

        def update(frame):
            hsv = cv2.cvtColor(frame, cv2.COLOR_BGR2HSV)
            back = cv2.calcBackProject([hsv], [0], holder["hist"], [0, 180], 1)
            if use_camshift:
                rot, window = cv2.CamShift(back, holder["window"], crit)
            else:
                _, window = cv2.meanShift(back, holder["window"], crit)
            collapsed = window[2] <= 0 or window[3] <= 0
            if collapsed:                               # keep the last window
                window = holder["window"]
            holder["window"] = window
            return Step(tuple(float(v) for v in window), collapsed)
        return init, update
    return make


def opencv_tracker_factory(create: Callable):
    """An OpenCV tracker; when it reports failure its last box stands (as for a lost MK)."""
    def make(seq: Sequence):
        tracker = create()
        holder = {}

        def init(frame, box):
            box = clip_box(box, frame.shape[1], frame.shape[0])   # OpenCV needs it inside
            tracker.init(frame, tuple(int(round(v)) for v in box))
            holder["last"] = tuple(float(v) for v in box)

        def update(frame):
            ok, box = tracker.update(frame)
            ok = bool(ok) and box[2] > 0 and box[3] > 0
            if ok:
                holder["last"] = tuple(float(v) for v in box)
            return Step(holder["last"], not ok)
        return init, update
    return make


def _contrib(name: str):
    for owner in (cv2, getattr(cv2, "legacy", None)):
        if owner is not None and hasattr(owner, f"Tracker{name}_create"):
            return getattr(owner, f"Tracker{name}_create")
    return None


HEADLINE = "MK 2 kernels (PG)"
FULL_TRACKER = "MK full tracker, started by hand (Kalman + 6 kernels, Sec. IV-D)"
FULL_AS_DETECTED = "MK full tracker, started by hand with the detection-born settings (exp.)"
FULL_TWO_KERNELS = "MK full tracker, started by hand, 2 kernels (exp.)"
BARE_SIX = "MK 6 kernels (PG), scale gate mean > 0.7"


def detection_born_settings() -> MultiObjectTrackerConfig:
    """Experiment: a track started by hand with exactly the settings of tracks born from
    detections (``manual_track`` set to the values it replaces) -- the full tracker as it was
    before tracks started by hand had their own settings."""
    d = MultiObjectTrackerConfig()
    return replace(d, manual_track=ManualTrackConfig(
        initial_velocity_var=d.kalman.initial_velocity_var,
        occlusion_similarity=d.lifecycle.occlusion_similarity,
        visibility_statistic=d.lifecycle.visibility_statistic,
        refinement_similarity_range=d.refinement_similarity_range,
        undetected_quality_factor=d.undetected_quality_factor,
        num_kernels=d.multi_kernel.num_kernels,
        scale_gate_statistic=d.multi_kernel.scale_gate_statistic,
        scale_similarity_gate=d.multi_kernel.scale_similarity_gate))


def two_kernel_settings() -> MultiObjectTrackerConfig:
    """Experiment: the defaults for tracks started by hand, but with the 2-kernel layout and
    scale gate of tracks born from detections (shows what the 6-kernel layout adds)."""
    d = MultiObjectTrackerConfig()
    return replace(d, manual_track=replace(
        d.manual_track, num_kernels=d.multi_kernel.num_kernels,
        scale_gate_statistic=d.multi_kernel.scale_gate_statistic,
        scale_similarity_gate=d.multi_kernel.scale_similarity_gate))


def tracker_table(include_paper: bool = True) -> list[tuple[str, Callable | None]]:
    mk = MultiKernelConfig
    out = [
        ("MK 2 kernels (PG)", multi_kernel_factory(mk(num_kernels=2))),
        (FULL_TRACKER, full_tracker_factory(MultiObjectTrackerConfig())),
        (FULL_AS_DETECTED, full_tracker_factory(detection_born_settings())),
        (FULL_TWO_KERNELS, full_tracker_factory(two_kernel_settings())),
        ("MK 2 kernels, no PG", multi_kernel_factory(mk(num_kernels=2,
                                                         use_projected_gradient=False))),
        ("MK 2 kernels, no scale", multi_kernel_factory(mk(num_kernels=2, scale_update=False))),
        ("MK 4 kernels (PG)", multi_kernel_factory(mk(num_kernels=4))),
        ("MK 4 kernels, no PG", multi_kernel_factory(mk(num_kernels=4,
                                                         use_projected_gradient=False))),
        (BARE_SIX, multi_kernel_factory(manual_track_multi_kernel(MultiObjectTrackerConfig()))),
        ("MK 1 kernel (K-L)", multi_kernel_factory(mk(num_kernels=1))),
        ("Mean shift (Comaniciu)", multi_kernel_factory(mean_shift_baseline_config())),
    ]
    if include_paper:
        out.append(("MK 2 kernels, eps_J=0.7N (paper)", multi_kernel_factory(paper_config())))
    out += [
        ("OpenCV CamShift", camshift_factory(True)),
        ("OpenCV meanShift", camshift_factory(False)),
    ]
    for name in ("MIL", "KCF", "CSRT"):
        create = _contrib(name)
        out.append((f"OpenCV {name}", opencv_tracker_factory(create) if create else None))
    return out


# ------------------------------------------------------------------------------------------

def run(seq: Sequence, factory) -> tuple[dict, float]:
    """Runs one tracker on one sequence: metrics (plus ``said_hidden``, the frames where the
    tracker said it does not see the target, and ``hidden_agree``, those of them where the
    truth says hidden) and the median CPU ms per frame."""
    init, update = factory(seq)
    predicted, said, times = [], [], []
    frames = seq.frames()
    first = next(frames)
    try:
        init(first, seq.init_box)
    except (TrackingInputError, TrackerInputError, cv2.error) as exc:
        print(f"  init failed on {seq.name}: {exc}", file=sys.stderr)
        return {"mean_center_error": float("inf"), "precision_at_20px": 0.0,
                "success_auc": 0.0, "said_hidden": 0, "hidden_agree": 0}, float("nan")
    predicted.append(seq.init_box)
    said.append(False)
    for frame in frames:
        t0 = time.process_time()
        try:
            step = update(frame)
        except cv2.error:
            step = Step(predicted[-1], True)
        times.append(time.process_time() - t0)
        predicted.append(step.box)
        said.append(step.said_hidden)
    metrics = single_target_metrics(predicted[1:], seq.truth[1:])
    metrics["boxes"] = predicted
    metrics["said_hidden"] = int(sum(said[1:]))
    if seq.hidden is not None:
        metrics["hidden_agree"] = int(sum(s and h for s, h in zip(said[1:], seq.hidden[1:])))
    return metrics, float(np.median(times) * 1e3) if times else float("nan")


#: trackers whose result differs from run to run (MIL samples at random, and
#: ``cv2.setRNGSeed`` does not make it repeatable): run this many times, report the mean
REPEATS = {"OpenCV MIL": 3}


def run_repeated(seq: Sequence, factory, repeats: int) -> tuple[dict, float]:
    """:func:`run` ``repeats`` times: the mean of each metric, the median of the times, and
    ``error_range`` (lowest, highest mean centre error) when repeated."""
    runs = [run(seq, factory) for _ in range(max(int(repeats), 1))]
    if len(runs) == 1:
        return runs[0]
    first = dict(runs[0][0])
    for key in ("mean_center_error", "precision_at_20px", "success_auc", "said_hidden",
                "hidden_agree"):
        if key in first:
            first[key] = float(np.mean([r[0][key] for r in runs]))
    errors = [r[0]["mean_center_error"] for r in runs]
    first["error_range"] = (min(errors), max(errors))
    return first, float(np.median([r[1] for r in runs]))


def warm_up(trackers) -> None:
    """Runs every tracker on a few frames of a small scene, untimed, so one-off costs (numba
    compilation or cache loading, OpenCV's first calls, imports) are not timed."""
    scene = crossing_scene(frames=8)
    seq = synthetic_sequence("warm-up", scene, 1)
    for _, factory in trackers:
        if factory is not None:
            run(seq, factory)


def fast_path() -> str:
    """Which multiple-kernel code path this run measured."""
    from mk_tracker.tracking.search_region import resolve_backend
    try:
        import numba
        have = f"numba {numba.__version__} importable"
    except ImportError:
        have = "numba not importable"
    env = os.environ.get("MK_TRACKER_NO_NUMBA")
    if env:
        have += f", MK_TRACKER_NO_NUMBA={env}"
    backend = resolve_backend("auto")
    return (f"`{backend}` kernel evaluation (`MultiKernelTracker(backend='auto')`; {have})")


def _names(option: str) -> list[str]:
    return [p.strip().lower() for p in option.split(",") if p.strip()]


def _selected(name: str, wanted: list[str]) -> bool:
    return not wanted or any(w in name.lower() for w in wanted)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default=None,
                        help="markdown report (default: docs/benchmark_single_target.md for "
                        "a full run; a filtered run writes no report unless given)")
    parser.add_argument("--sequences", "--only", dest="sequences", default="",
                        help="comma-separated substrings of sequence names, e.g. "
                        "'pillar,TUD-Campus person 2'")
    parser.add_argument("--trackers", default="",
                        help="comma-separated substrings of tracker names, e.g. 'MK 2,CSRT'")
    parser.add_argument("--list", action="store_true", help="list trackers and sequences")
    parser.add_argument("--held-out-seeds", default=",".join(map(str, HELD_OUT_SEEDS)),
                        help="comma-separated generator seeds of the held-out crowd scenes "
                        "(default %(default)s; others give a fresh check, e.g. 31,32,33,34)")
    parser.add_argument("--json", default=None,
                        help="also write every tracker's figures per sequence as JSON")
    parser.add_argument("--legacy", action="store_true",
                        help="the older in-sample tables of every tracker variant instead of "
                        "the leave-one-clip-out protocol (writes a report only with --output)")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a parameter of our tracker (YAML value) under every "
                        "grid setting, e.g. multi_kernel.scale.acceptance=lower")
    args = parser.parse_args(argv)
    BASE_CHANGES.update(setting_changes(args.set))
    if not args.legacy:
        return loso_main(args, argv)
    try:
        seeds = tuple(int(v) for v in args.held_out_seeds.split(",") if v.strip())
    except ValueError:
        parser.error(f"--held-out-seeds {args.held_out_seeds!r} is not a list of integers")
    cv2.setNumThreads(1)
    load_before = os.getloadavg()

    seqs = synthetic_sequences() + otb_sequences() + tud_sequences() + \
        held_out_sequences(seeds)
    trackers = tracker_table()
    if args.list:
        print("trackers:\n  " + "\n  ".join(n for n, _ in trackers))
        print("sequences:\n  " + "\n  ".join(s.name for s in seqs))
        return 0
    seqs = [s for s in seqs if _selected(s.name, _names(args.sequences))]
    trackers = [(n, f) for n, f in trackers if _selected(n, _names(args.trackers))]
    output = args.output
    print(f"load average {load_before}; measured path: {fast_path()}", flush=True)
    warm_up(trackers)
    results: dict[str, dict[str, tuple[dict, float]]] = {}
    for seq in seqs:
        print(f"{seq.name} ({len(seq.truth)} frames"
              + (f", hidden {sum(seq.hidden[1:])}" if seq.hidden else "") + ")", flush=True)
        # render / read the frames once for all trackers (one sequence in memory at a time)
        frames = list(seq.frames())
        cached = replace(seq, frames=lambda: iter(frames))
        for name, factory in trackers:
            if factory is None:
                continue
            m, ms = run_repeated(cached, factory, REPEATS.get(name, 1))
            results.setdefault(name, {})[seq.name] = (m, ms)
            print(f"  {name:52s} err {m['mean_center_error']:8.2f}  P@20 "
                  f"{m['precision_at_20px']:.3f}  AUC {m['success_auc']:.3f}  {ms:7.2f} ms"
                  f"  said hidden {m['said_hidden']:5g}", flush=True)
    if output:
        write_markdown(Path(output), seqs, trackers, results, argv,
                       (load_before, os.getloadavg()), fast_path())
    return 0


NOTES = """Notes.
* "synthetic full pillar" and "synthetic crossing (far)" hide the target completely for
  ~20 and ~11 frames; the bare refinement (MK rows without Kalman) and OpenCV's trackers lose
  it there (the paper's own limitation, Sec. V-D), and those two sequences dominate the
  synthetic group mean.
* "MK full tracker, started by hand (Kalman + 6 kernels, Sec. IV-D)" is `MultiObjectTracker`
  with its defaults (`MultiObjectTrackerConfig()`), one track started by hand on the first
  box (`start_track`, as `tracker_node`'s `initial_box` / `~/start_track` and
  `mk_tracker process --init-from-gt` do), no detector input, frame stamps `i / fps`
  (25 fps for the real sequences, `datasets.DEFAULT_FRAME_RATE`).  A track started by hand
  runs with the `manual_track` section of the config: 6 kernels (3 rows x 2 columns, Fig.
  14b) with the scale gated on their mean similarity > 0.7, velocity prior
  `initial_velocity_var` 40000 (px/s)^2, visibility = `sum_i W_i rho_i / N` (adaptive
  weights (7)-(8)), occluded below 0.4, and that visibility mapped to measurement quality
  over 0.2-0.8 (tracks born from detections: 2 kernels, 2500, plain mean, 0.6, 0.5-0.95
  times 0.5); a result that sees the target with one kernel column only (best kernel of the
  other column < 0.2) is searched again from the box moved 0.45 w towards the seeing column,
  and that result is kept if both its columns see the target (`column_recentre`; 2-kernel
  layouts have no columns, so the "(exp.)" rows below never do this).  Each frame
  the Kalman prediction initialises the multiple-kernel search and
  the result is the Kalman measurement; below the occlusion threshold the track is
  `occluded` and coasts on the prediction.  Its box is scored in every state (while it
  coasts: the predicted box).  The two "(exp.)" full-tracker rows change only
  `manual_track`: back to every setting of detection-born tracks (the full tracker as it
  was before this section existed), or back to their 2-kernel layout and scale gate only.
* "held-out crowd persons": every person of two generator crowd scenes
  (`crowd_scene(5, seed=11 / 12, frames=150)`: random turns, crossings, pillars),
  each as a single target from its first box.  No setting was chosen on them (the
  `manual_track` defaults were chosen on the synthetic occlusion scenes and TUD-Campus), so
  they show whether those settings carry over.  Not part of the goal.
* "said hidden" = frames in which the tracker itself said it does not see the target: MK
  `lost` (its last box is scored), the full tracker's state other than `confirmed`, OpenCV
  `ok=False` (its last box is scored), CamShift's collapsed window.  "truly hidden" (synthetic
  scenes only; the real sequences carry no visibility) = frames where less than
  10 % of the target's silhouette is visible or it is outside the image.  "both" = frames
  in both sets.  A tracker that says hidden while the truth is visible (said > both) is
  dropping a visible target; one that says nothing while the truth is hidden reports a box
  it cannot have seen.
* "MK 2 kernels, eps_J=0.7N (paper)" is the paper's stopping threshold: with this K-L cost
  (J_i ~ 0.01-0.3 around the target) Algorithm 1 stops before the first step, so the default
  of `MultiKernelConfig.epsilon_j_factor` is 0 (see mk_tracker/tracking/multi_kernel.py).
* The bare MK rows use the defaults of `MultiKernelConfig` (2 kernels unless stated): scale
  update gated on the minimum kernel similarity > 0.8 (the 6-kernel row: mean > 0.7, as the
  full tracker's hand-started tracks) and verified against the cost, no model update.
* OpenCV MIL samples at random and gives a different result on every run (`cv2.setRNGSeed`
  does not make it repeatable; e.g. 0.9-6.6 px on "crossing (near)" across runs): its row is
  the mean of 3 runs, with the range of the mean centre error in brackets per sequence.
* Timing: every tracker first runs untimed on 8 frames of a small scene (warm-up: numba
  compilation or cache loading, OpenCV's first calls).  Then `time.process_time` around each
  update call; the median over the frames of a sequence; a group's figure is the median of
  its sequences' medians."""

SPEED_GOAL_MS = 2.0
HELD_OUT = "held-out crowd persons (not a goal)"
SPEED_GOAL_FACTOR = 5.0


def _group_mean(results, name, names):
    vals = [results[name][n] for n in names if n in results.get(name, {})]
    if not vals:
        return None
    return ({k: float(np.mean([v[0][k] for v in vals])) for k in
             ("mean_center_error", "precision_at_20px", "success_auc")},
            float(np.median([v[1] for v in vals])))


def _verdict(ok: bool) -> str:
    return "**MET**" if ok else "**NOT MET**"


def goal_check(trackers, results, groups) -> list[str]:
    """The issue's goals, checked on this run's figures, for the headline row and for the
    full tracker: speed (<= 2 ms median per target, >= 5x faster than CSRT) and accuracy
    (lower mean centre error than every OpenCV tracker per synthetic scene, on the synthetic
    group mean and on the TUD-Campus group mean)."""
    opencv = [n for n, f in trackers if n.startswith("OpenCV") and f is not None
              and n in results]
    ours = [n for n in (HEADLINE, FULL_TRACKER) if n in results]
    if not ours or not opencv:
        return ["(goal check needs the headline MK row and the OpenCV rows: not in this run)",
                ""]
    lines = ["## Goal check (issue #3)", ""]
    syn = dict(groups).get("synthetic occlusion scenes", [])
    tud = dict(groups).get("TUD-Campus persons", [])
    for name in ours:
        lines += [f"**{name}**", ""]
        # speed
        per_group = []
        for gname, names in groups:
            gm = _group_mean(results, name, names)
            csrt = _group_mean(results, "OpenCV CSRT", names) if "OpenCV CSRT" in results \
                else None
            if gm is not None:
                per_group.append((gname, gm[1], None if csrt is None else csrt[1]))
        all_ms = [results[name][n][1] for n in results[name]]
        overall = float(np.median(all_ms)) if all_ms else float("nan")
        csrt_all = [results["OpenCV CSRT"][n][1] for n in results.get("OpenCV CSRT", {})]
        csrt_overall = float(np.median(csrt_all)) if csrt_all else float("nan")
        worst = max(ms for _, ms, _ in per_group)
        lines.append(f"* Speed, <= {SPEED_GOAL_MS:g} ms per target per frame (median): "
                     f"{_verdict(worst <= SPEED_GOAL_MS)} -- median over all sequences "
                     f"{overall:.2f} ms; per group " +
                     ", ".join(f"{g} {ms:.2f} ms" for g, ms, _ in per_group) + ".")
        if csrt_all:
            ratios = [(g, c / ms) for g, ms, c in per_group if c is not None and ms > 0]
            lowest = min(r for _, r in ratios)
            lines.append(f"* Speed, >= {SPEED_GOAL_FACTOR:g}x faster than CSRT: "
                         f"{_verdict(lowest >= SPEED_GOAL_FACTOR)} -- CSRT median "
                         f"{csrt_overall:.2f} ms ({csrt_overall / overall:.1f}x overall); per "
                         "group " + ", ".join(f"{g} {r:.1f}x" for g, r in ratios) + ".")
        # accuracy
        for label, names, per_scene in (("synthetic occlusion scenes", syn, True),
                                        ("TUD-Campus persons", tud, False)):
            if not names:
                continue
            mine = _group_mean(results, name, names)[0]["mean_center_error"]
            others = {o: _group_mean(results, o, names)[0]["mean_center_error"]
                      for o in opencv}
            best_o = min(others, key=others.get)
            ok = all(mine < v for v in others.values())
            lines.append(f"* Accuracy, {label}, group mean centre error: {_verdict(ok)} -- "
                         f"{mine:.1f} px vs best OpenCV ({best_o.replace('OpenCV ', '')}) "
                         f"{others[best_o]:.1f} px.")
            if per_scene:
                lost = []
                for n in names:
                    m = results[name][n][0]["mean_center_error"]
                    beaten = [(o, results[o][n][0]["mean_center_error"]) for o in opencv
                              if results[o][n][0]["mean_center_error"] <= m]
                    if beaten:
                        lost.append(f"{n.replace('synthetic ', '')}: {m:.2f} px vs " +
                                    ", ".join(f"{o.replace('OpenCV ', '')} {v:.2f}"
                                              for o, v in sorted(beaten, key=lambda t: t[1])))
                lines.append(f"* Accuracy, every synthetic scene: {_verdict(not lost)} -- " +
                             ("lower than every OpenCV tracker on all "
                              f"{len(names)} scenes." if not lost else
                              f"{len(names) - len(lost)} of {len(names)} scenes; not lower on "
                              + "; ".join(lost) + "."))
        lines.append("")
    lines += accuracy_table(trackers, results, opencv, syn, tud)
    return lines


def accuracy_table(trackers, results, opencv, syn, tud) -> list[str]:
    """Accuracy goal for every MK row: its mean centre error per synthetic scene and per
    group against the best OpenCV tracker there (yes = lower than every OpenCV tracker)."""
    cols = [(n.replace("synthetic ", ""), [n]) for n in syn]
    cols += [("synthetic mean", syn), ("TUD-Campus mean", tud)]
    cols = [(c, names) for c, names in cols if names]
    n_goal = len(cols)
    held = [n for n in next(iter(results.values())) if "held-out" in n]
    if held:
        cols.append(("held-out crowd mean (not a goal)", held))

    def err(name, names):
        return float(np.mean([results[name][n][0]["mean_center_error"] for n in names]))

    best = []
    for _, names in cols:
        o = min(opencv, key=lambda o: err(o, names))
        best.append((o.replace("OpenCV ", ""), err(o, names)))
    lines = ["Accuracy goal, every MK row (mean centre error in px; yes = lower than every "
             "OpenCV tracker on that scene or group; the held-out column is not part of the "
             "goal and not of \"all met\"):", "",
             "| tracker | " + " | ".join(c for c, _ in cols) + " | all met |",
             "|---|" + "---|" * (len(cols) + 1),
             "| best OpenCV | " + " | ".join(f"{v:.2f} ({o})" for o, v in best) + " | |"]
    for name, f in trackers:
        if f is None or not name.startswith("MK") or name not in results:
            continue
        cells, met = [], True
        for k, ((_, names), (_, b)) in enumerate(zip(cols, best)):
            e = err(name, names)
            ok = e < b
            if k < n_goal:
                met &= ok
            cells.append(f"{e:.2f} {'yes' if ok else 'no'}")
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {'**yes**' if met else 'no'} |")
    return lines + [""]


def _centre(box) -> np.ndarray:
    return np.array([box[0] + box[2] / 2.0, box[1] + box[3] / 2.0])


def error_breakdown(seq: Sequence, trackers, results) -> list[str]:
    """Where a tracker's error on a partly occluded scene comes from: frames with the target
    fully visible vs partly occluded, horizontal vs vertical offset, box height vs truth."""
    if seq.visible is None:
        return []
    lines = [f"## Where the error is: {seq.name}", "",
             "Frames 1.. split by the truth's visible fraction: fully visible (>= 0.99) and "
             "partly occluded (< 0.99).  dx, dy = predicted minus true centre (px; the person "
             "walks towards +x at 2 px/frame, so dx < 0 is lagging); |dx|, |dy| their means of "
             "absolute values; h = predicted / true box height over all frames.", "",
             "| tracker | error all | visible: frames, error, mean dx, mean dy | partly "
             "occluded: frames, error, mean abs dx, mean abs dy | h mean [min, max] |",
             "|---|---|---|---|---|"]
    keep = [i for i in range(1, len(seq.truth)) if seq.truth[i] is not None]
    vis = np.array([seq.visible[i] for i in keep])
    for name, f in trackers:
        if f is None or seq.name not in results.get(name, {}):
            continue
        boxes = results[name][seq.name][0].get("boxes")
        if boxes is None:
            continue
        err = np.array([_centre(boxes[i]) - _centre(seq.truth[i]) for i in keep])
        h = np.array([boxes[i][3] / seq.truth[i][3] for i in keep])
        dist = np.hypot(err[:, 0], err[:, 1])
        full, part = vis >= 0.99, vis < 0.99
        lines.append(
            f"| {name} | {dist.mean():.2f} | {full.sum()}, {dist[full].mean():.2f}, "
            f"{err[full, 0].mean():+.2f}, {err[full, 1].mean():+.2f} | {part.sum()}, "
            f"{dist[part].mean():.2f}, {np.abs(err[part, 0]).mean():.2f}, "
            f"{np.abs(err[part, 1]).mean():.2f} | {h.mean():.3f} [{h.min():.2f}, "
            f"{h.max():.2f}] |")
    return lines + [""]


def write_markdown(path: Path, seqs, trackers, results, argv, loads=None,
                   measured_path: str = "") -> None:
    cmd = ("PYTHONPATH=. OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 "
           "/tmp/bench_venv/bin/python benchmarks/bench_single_target.py")
    args = list(argv) if argv else sys.argv[1:]
    if args:
        cmd += " " + " ".join(f"'{a}'" if " " in a else a for a in args)
    groups = [("synthetic occlusion scenes", [s.name for s in seqs if "synthetic" in s.name]),
              ("TUD-Campus persons", [s.name for s in seqs if "TUD" in s.name]),
              ("OTB Crossing", [s.name for s in seqs if "OTB" in s.name]),
              (HELD_OUT, [s.name for s in seqs if "held-out" in s.name])]
    groups = [(g, names) for g, names in groups if names]
    lines = ["# Single-target benchmark: multiple-kernel tracker vs OpenCV trackers", "",
             "Produced by:", "", "```", cmd, "```", ""]
    if loads is not None:
        (b1, b5, b15), (e1, e5, e15) = loads
        lines += [f"Machine: {os.cpu_count()} cores, load average (1/5/15 min) "
                  f"{b1:.1f}/{b5:.1f}/{b15:.1f} at the start and {e1:.1f}/{e5:.1f}/{e15:.1f} "
                  "at the end of the run (this run itself keeps one core busy; above 2, other "
                  "jobs were running). "
                  f"Run finished {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.", ""]
    if measured_path:
        lines += [f"Multiple-kernel code path measured: {measured_path}.", ""]
    lines += goal_check(trackers, results, groups)
    lines += [f"OpenCV {cv2.__version__}, one thread (`cv2.setNumThreads(1)`), numpy "
              f"{np.__version__}. Error = mean centre error in px over frames with a box "
              "(lower is better); P@20 = fraction of frames with centre error <= 20 px; AUC = "
              "success AUC of IoU; ms = median time per frame for this one target "
              "(MK: includes HSV conversion of its search region; CamShift/meanShift convert "
              "the whole frame), measured as process CPU time (`time.process_time`) so that "
              "other load on the machine inflates it less than wall-clock time would. "
              "MK = multiple-kernel tracker (this package), PG = projected gradient. Every "
              "tracker starts from the first ground-truth box (clipped to the image for the "
              "OpenCV trackers, which cannot take a box reaching outside it; the MK tracker "
              "takes it as is and simply sees no pixels outside the image); when a "
              "tracker reports failure (MK: `lost`; OpenCV: `ok=False`) its last box is "
              "scored for that frame.", ""]
    missing = [n for n, f in trackers if f is None]
    if missing:
        lines += [f"Not available in this environment (opencv-contrib missing): "
                  f"{', '.join(missing)}.", ""]
    lines += ["## Summary (mean over the sequences of a group)", "",
              "| tracker | " + " | ".join(f"{g} err / P@20 / AUC / ms" for g, _ in groups) +
              " |", "|---|" + "---|" * len(groups)]
    for name, f in trackers:
        if f is None or name not in results:
            continue
        cells = []
        for _, names in groups:
            gm = _group_mean(results, name, names)
            cells.append("-" if gm is None else
                         f"{gm[0]['mean_center_error']:.1f} / {gm[0]['precision_at_20px']:.2f}"
                         f" / {gm[0]['success_auc']:.2f} / {gm[1]:.2f}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", NOTES, ""]
    if FINDINGS:
        lines += [FINDINGS, ""]
    for seq in seqs:
        if "lower-body wall" in seq.name:
            lines += error_breakdown(seq, trackers, results)
    lines += ["## Per sequence", ""]
    for seq in seqs:
        hidden = seq.hidden is not None
        title = f"### {seq.name} ({len(seq.truth)} frames"
        if hidden:
            title += f"; truly hidden in {sum(seq.hidden[1:])} of the {len(seq.truth) - 1} " \
                     "scored frames"
        lines += [title + ")", "",
                  "| tracker | mean centre error (px) | precision@20 | success AUC | "
                  "median ms/frame | said hidden" + (" / both" if hidden else "") + " |",
                  "|---|---|---|---|---|---|"]
        for name, f in trackers:
            if f is None or seq.name not in results.get(name, {}):
                continue
            m, ms = results[name][seq.name]
            said = f"{m['said_hidden']:g}" + (f" / {m['hidden_agree']:g}" if hidden else "")
            spread = m.get("error_range")
            err = f"{m['mean_center_error']:.2f}" + (
                "" if spread is None else f" ({spread[0]:.2f}-{spread[1]:.2f})")
            lines.append(f"| {name} | {err} | "
                         f"{m['precision_at_20px']:.3f} | {m['success_auc']:.3f} | {ms:.2f} | "
                         f"{said} |")
        lines.append("")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {path}")


#: hand-written findings of the investigation (issue #3); kept next to the code that
#: produced them, regenerated into the report
FINDINGS = """## Findings (hand-written for issue #3 with the defaults of that time)

*Historical: written for the `--legacy` tables when tracks started by hand had 6 kernels and
no search additions; the defaults are now chosen by the leave-one-clip-out protocol
(docs/benchmark_single_target.md).*

* **Goal.**  The full tracker with the defaults for tracks started by hand (one shipped
  configuration, `MultiObjectTrackerConfig()`) is below every OpenCV tracker on each of the
  five synthetic occlusion scenes (wall 1.44 px vs CSRT 2.78; pillar 4.26 vs CSRT 53.6;
  crossing near 1.21 vs CSRT 3.20; crossing far 1.23 vs KCF 31.3; approach 1.01 vs KCF
  7.91), on the synthetic mean (1.8 vs 24.9 px) and on the TUD-Campus mean (8.65 vs CSRT
  32.1 px; lower than CSRT on 6 of the 8 persons, persons 6 and 8 are 4.7 / 4.1 vs 3.9 /
  3.9 px).  The `manual_track` settings were chosen on these same sequences (optimistic);
  the held-out persons below are the check.  It is slower than the bare refinement (6
  kernels: see the goal check for the measured medians) but within 2 ms.
* **Why tracks started by hand needed their own settings** (row "... with the
  detection-born settings (exp.)", the full tracker as it was: wall 11.8, TUD-Campus 56.5,
  held-out 46.1 px).  The settings of tracks born from detections assume a detection
  corrects the track every frame: (1) the velocity prior (`kalman.initial_velocity_var`
  2500, 50 px/s) is far below the ~250 px/s of the TUD-Campus walkers; (2) on real video a
  matching target's plain-mean kernel similarity is 0.45-0.65, below
  `lifecycle.occlusion_similarity` 0.6, and with the legs hidden it halves, so the track
  coasts while in plain view; (3) the refinement's similarity is mapped to a measurement
  quality over 0.5-0.95 and halved without a detection, which puts a hand-started track's
  only measurement at the quality floor (std x10): the filter runs on its own velocity and
  falls behind a walking person.  Making those settings global is not an option: the
  velocity prior, `sigma_u` 15 and occlusion threshold 0.4 cut the multi-object benchmark's
  TUD-Campus IDF1 from 0.658 to 0.521 (measured in the previous session).  So they apply to
  tracks started by hand only (`manual_track.*`; `bench_multi_object.py` gives identical
  MOTA/IDF1 on every sequence before and after, since detection-born tracks are unchanged).
* **What the 4-kernel full tracker did on TUD-Campus persons 3 and 7** (previous session:
  89 and 126 px).  Cause (3): its weighted visibility on TUD-Campus was 0.42-0.5, quality 0,
  so the filter ignored the refinement and lagged (person 3: 120-147 px/s filtered vs
  ~190 px/s true).  Once the box was about half a width behind, the left column of the 2x2
  layout lay on background (rho ~ 0, so weight W ~ 0 by (7)-(8)) and the right column on
  the person's left half, whose colours match its right half: a stable wrong optimum that
  the weighted visibility (0.42-0.46) still called visible.  With the refinement trusted
  (`manual_track.refinement_similarity_range` 0.2-0.8, `undetected_quality_factor` 1) the
  same 4-kernel track gets persons 3 / 7 to 10 / 13 px (exploration runs with this
  script's `full_tracker_factory`, not in the tables).
* **Why 6 kernels.**  The lower-body wall needs a left/right structure once the legs are
  hidden: two stacked full-width kernels place the box only by the upper-body histogram
  (row "... 2 kernels (exp.)": wall 5.13 px, |dx| 6.5 px while occluded); 6 kernels (3 rows
  x 2 columns, Fig. 14b) keep 4 kernels in two columns above the wall (1.44 px, |dx| 1.8 vs
  CSRT 2.3).  With the refinement trusted, 2 kernels also lose the person at the pillar
  (50.8 px, barely below CSRT's 53.6: the lagging measurement on the shrinking visible part
  is now believed), 6 kernels do not (4.26).  The 2x2 layout misses the wall goal (2.90 px
  vs CSRT 2.78) and is worse at the pillar (11.1 px).
  The scale is gated on the mean kernel similarity > 0.7: with 6 small kernels the default
  gate (every kernel > 0.8) almost never opens and "approach" fails (16.8 px).
* **Sensitivity** (exploration runs, one setting changed at a time from the shipped ones;
  synthetic / TUD-Campus means and held-out mean in px): occlusion threshold 0.3 or 0.5:
  2.0 / 15.9, 1.8 / 16.8 (goal still met); quality range 0.3-0.8 or 0.1-0.7: 1.8 / 8.6,
  2.1 / 9.9; quality factor 0.5: 2.0 / 9.0; velocity prior 1e4 or 1e5: 1.9 / 8.4,
  1.8 / 8.8; 5 kernels: 2.1 / 10.2; plain-mean visibility: 2.2 / 15.1 (all met; held-out
  26.5-31.7, the plain mean 44.6).  Goal missed with: the detection-born quality range
  0.5-0.95 (TUD-Campus 33.2, person 7 138 px), the detection-born velocity prior (37.3), a
  scale gate of 0.8 (approach 16.8), 4 kernels (wall 2.90) or 2 kernels (wall 5.07, pillar
  57).
* **Saying "not visible"** ("said hidden / both").  On "crossing (far)" the full tracker
  says hidden in 13 frames covering all 11 truly hidden ones, then re-acquires; on "full
  pillar" in 31 frames covering all 29 truly hidden ones (the detection-born settings: 91).
  CSRT never reports a failure on "crossing (far)" although its box ends far from the
  person (83 px); KCF and the bare refinement report failure in 65-67 frames (they lost the
  person for good).  On TUD-Campus persons 4, 5 and 7 the full tracker says hidden in
  36-63 frames with 8-13 px error: its visibility is below 0.4 while the box stays near the
  person, so it coasts on a good velocity; there the figure is a weak "visible" signal,
  not a lost track.
* **Held-out crowd persons** (no setting chosen on them): the full tracker gets 26.2 px,
  below CSRT (28.9) but above the bare 2-kernel refinement (22.5); it is better than the
  bare refinement on 5 of the 10 persons, close on 2 (seed 11 persons 1 and 5: 10.7 / 7.5
  vs 7.5 / 7.2 px) and far worse on persons 2, 3 and 4 of seed 12 (85, 58, 84 px; bare 55,
  19, 76; every tracker but MIL on person 4 is above 50 px on persons 2 and 4).
  Person 3 of seed 12 shows the remaining failure: while it is half hidden the left kernel
  column settles on the person's right half (similarities 0.9) and the right column on
  background (0), the weighted visibility says 0.86, the box stays ~27 px off, and after
  the next full occlusion the coasting prediction (on a velocity learnt from that offset
  box) never meets the person again.
* **What was tried against that failure** (exploration runs of this script's
  `full_tracker_factory`, one `manual_track` change each; synthetic mean / TUD-Campus mean
  / OTB Crossing / held-out mean in px; before: 1.83 / 8.68 / 8.89 / 26.52).  Every
  threshold was set by mechanism (0.2 = the low end of the quality range, a kernel below
  it carries no information) and judged on the goal sequences before the held-out run.
  (1) While coasting, a second search from the track's own last kernels (the bare
  refinement's start), keeping the visible / more similar result: 1.84 / 16.3 / 10.3
  (from the kernels of the last visible frame: 1.83 / 14.6 / 11.8).  On TUD-Campus it
  re-acquires on one kernel: person 7, frame 21, rho (0.06, 0.01, 0, 0.02, 0.03, 0.58),
  weighted visibility 0.48 -- `sum rho^2 / sum rho` is about the best kernel's rho, so
  one kernel matching background passes 0.4 alone -- and the track stays there (46.7 px).
  Only when the prediction's search is not visible and only if both kernel columns see
  the target (best rho >= 0.2 in each): 1.83 / 8.68 / 8.89 / 26.52 -- identical on every
  held-out person (it never re-acquires one) and 2.7-3.4 ms on the persons that coast.
  (2) Both columns required for "visible": full pillar 4.26 -> 23.4 px (TUD-Campus 8.93):
  a person whose right half is behind the pillar gives the same similarities (left
  column 0.8-0.9, right 0) as a box half on background, and the track coasts on a lagging
  velocity from the first hidden column on.  (3) At least 2 kernels >= 0.2 for "visible":
  1.83 / 8.98 / 9.38 / 27.67; with (4): 1.83 / 8.98 / 4.56 / 27.45 (rejected: held-out
  worse).  (4) Adopted (`manual_track.column_recentre`): when a visible result sees the
  target with one column only, search again from the box moved 0.45 w (the distance of
  the column centres) towards the seeing column and keep that result if both its columns
  see the target; side occlusion fails that test and keeps its result, so the goal
  sequences are unchanged (1.83 / 8.68 / 8.75) and held-out 26.52 -> 26.28 (seed 11
  person 1: 13.1 -> 10.7 px; the others unchanged).  It does not fix seed 12 person 3:
  there the re-centred search lands on the person (x 415 vs truth 411 px) but, the person
  being half hidden, its weighted visibility is 0.35 < 0.4 and it is not kept.  Lowering
  that bar for the re-centred search is the next thing to try, judged on new held-out
  scenes (seeds 11/12 have now been looked at).
* **Bounded coasting** (`manual_track.max_coast_position_std`, adopted).  A hand-started
  track is never lost by coasting time (it has no detector to come back with), so before
  this its coasting prediction extrapolated the last velocity until the box left the
  image: on generator seed 21 person 5 the track said "hidden" in 130 of 150 frames and
  its box slid away (242 px mean error).  Now, once the std of the predicted centre (sqrt
  of the larger position variance of P) exceeds 1 box width -- the reach of the search,
  whose region is the start box grown by `multi_kernel.search_margin` 0.5 on each side --
  the track stops predicting: it holds that position (state `occluded`, reported velocity
  0) and keeps searching from it until the refinement sees the target again.  The bound
  was set by that mechanism and checked on the goal sequences only: 1 box width leaves
  them unchanged except TUD-Campus person 5 (11.11 -> 10.91 px); 0.5 or 0.25 widths hold
  the box too early for a person walking through an occlusion (full pillar 4.26 -> 31.5 /
  41.8 px, TUD-Campus person 5 -> 35.3 / 72.2 px), as a fixed 1 s coast limit did earlier
  (pillar 10.8 -> 43.5 px).  Held-out means, full tracker before -> after: seeds 11/12
  26.28 -> 26.24 px (seed 12 persons 2 / 3 / 4: 83.8 -> 84.9, 59.8 -> 57.9, 84.1 -> 84.5);
  seeds 21-24 29.03 -> 24.86 px (seed 21 person 5 242 -> 171, seed 22 person 4 48.6 ->
  36.9, seed 23 person 4 32.4 -> 32.0; the rest identical); then, once, on new seeds 31-34
  (never looked at before; `--sequences held-out --held-out-seeds 31,32,33,34`): 26.87 ->
  24.66 px (seed 34 person 4 123 -> 84, seed 32 person 4 114 -> 104, seed 34 person 5 26.6
  -> 26.5, seed 32 person 1 66 -> 70 worse; the other 16 persons identical; on the same
  persons the bare 2-kernel refinement gets 35.07, CSRT 39.37, KCF 46.37 px).  Weak: after
  a long confident track the filter's velocity variance is small (`kalman.sigma_u` 30), so
  the std reaches 1 box width only after ~1-2 s of coasting, and a person who turned while
  hidden is still far from the held box (hence 171 px on seed 21 person 5): the bound
  stops the runaway, it does not find the person."""


# ------------------------------------------------------------------------------------------
# Leave-one-clip-out protocol (issue #16): the primary figures of this benchmark

from itertools import product  # noqa: E402

from mk_tracker.synthetic.scene_config import (OccluderSpec, PersonSpec,  # noqa: E402
                                               SceneConfig)
from mk_tracker.synthetic.scene import make_scene  # noqa: E402

#: seeds of the generator's 7 fps edge-entry scenes in the development set
FAST_EDGE_SEEDS = (41, 42)
#: generator crowd scenes (25 fps) in the development set
DEV_CROWD_SEEDS = (11,)
#: frame step of the low-frame-rate copies of TUD-Stadtmitte (25 fps / 4 = 6.25 fps)
LOW_FPS_STEP = 4


def fast_edge_scene(seed: int, frames: int = 40) -> "SyntheticScene":  # noqa: F821
    """A 7 fps street: 4 people ~90 px tall (~30 px wide) walking 12-20 px per frame, two
    of them entering at the left / right image edge (first box an edge-clipped sliver), two
    walking together as a group, one pillar; conditions of issue #16's unseen clips."""
    rng = np.random.default_rng([seed, 0x7F5])
    w, h = 640, 480
    people = []
    for k in range(4):
        speed = float(rng.uniform(12.0, 20.0))
        y = float(rng.uniform(0.55, 0.9)) * h
        if k == 0:        # enters at the left edge
            wps = ((4.0, y), (w + 200.0, y + float(rng.uniform(-40, 40))))
        elif k == 1:      # enters at the right edge
            wps = ((w - 4.0, y), (-200.0, y + float(rng.uniform(-40, 40))))
        else:             # a group of two walking together, crossing the others
            x = float(rng.uniform(0.2, 0.4)) * w + (k - 2) * 34.0
            wps = ((x, y), (x + float(rng.uniform(0.3, 0.5)) * w, y + float(rng.uniform(-60, 60))),
                   (x + float(rng.uniform(-0.1, 0.2)) * w, y))
        people.append(PersonSpec(waypoints=wps, speed=round(speed, 2), height=90.0,
                                 after_last="continue"))
    occ = (OccluderSpec(box=(float(rng.uniform(0.4, 0.6)) * w, 0.35 * h, 40.0, 0.5 * h),
                        color=tuple(int(v) for v in rng.integers(40, 120, 3))),)
    cfg = SceneConfig(seed=seed, frames=frames, fps=7.0, width=w, height=h, perspective=0.3,
                      people=tuple(people), occluders=occ)
    return make_scene(cfg)


def mot_person_sequences(name: str, step: int = 1, min_frames: int = 10) -> list[Sequence]:
    """Every person of ``mot/<name>`` as a single target from its first gt box (clipped to the
    image), scored on its frames with a box; ``step`` > 1 keeps every ``step``-th frame from
    the person's first (:func:`mk_tracker.bags.datasets.subsampled`: a lower frame rate with
    ``step`` times the motion per frame)."""
    root = DATA / "mot" / name
    if not root.is_dir():
        return []
    seq = read_mot_sequence(root)
    height, width = seq.image(0).shape[:2]
    out = []
    for pid in seq.identities:
        mine = seq.track(pid)
        first, last = min(mine), max(mine)
        low = subsampled(seq, step, first % step)
        kept = range(first // step, (last - first % step) // step + 1)
        if len(kept) < min_frames:
            continue
        truth = [None if low.ground_truth[k].get(pid) is None
                 else clip_box(low.ground_truth[k][pid], width, height) for k in kept]
        if truth[0] is None:
            continue
        suffix = "" if step == 1 else f" at {low.frame_rate:g} fps"
        out.append(Sequence(f"{name} person {pid}{suffix}",
                            _image_reader([low.image_paths[k] for k in kept]), truth, truth[0],
                            fps=low.frame_rate))
    return out


def otb_sequence(name: str) -> list[Sequence]:
    root = DATA / "otb" / name
    if not root.is_dir():
        return []
    paths = sorted((root / "img").glob("*.jpg"))
    truth = read_box_list(root / "groundtruth_rect.txt")[:len(paths)]
    return [Sequence(f"OTB {name}", _image_reader(paths), truth, truth[0])]


def development_set() -> list[tuple[str, Sequence]]:
    """``(clip, sequence)`` of the development set; ``clip`` is the source video, the unit
    that is held out (every person of a clip, and a clip's low-frame-rate copy, go
    together, so no setting is ever reported on a clip whose images helped choose it)."""
    out = [("OTB Crossing", s) for s in otb_sequence("Crossing")]
    out += [("OTB Woman", s) for s in otb_sequence("Woman")]
    out += [("TUD-Campus", s) for s in mot_person_sequences("TUD-Campus")]
    out += [("TUD-Stadtmitte", s) for s in mot_person_sequences("TUD-Stadtmitte")]
    out += [("TUD-Stadtmitte", s) for s in mot_person_sequences("TUD-Stadtmitte",
                                                                 step=LOW_FPS_STEP,
                                                                 min_frames=20)]
    for seed in FAST_EDGE_SEEDS:
        scene = fast_edge_scene(seed)
        for pid in range(1, len(scene.config.people) + 1):
            seq = synthetic_sequence(f"generator 7 fps edge/fast seed {seed} person {pid}",
                                     scene, pid)
            if seq.truth[0] is not None:
                out.append((f"generator 7 fps seed {seed}", seq))
    for seed in DEV_CROWD_SEEDS:
        scene = crowd_scene(n_people=5, seed=seed, frames=150)
        for pid in range(1, 6):
            seq = synthetic_sequence(f"generator crowd 25 fps seed {seed} person {pid}",
                                     scene, pid)
            if seq.truth[0] is not None:
                out.append((f"generator crowd seed {seed}", seq))
    return out


#: the settings of tracks started by hand that the protocol chooses between (a small grid:
#: the coarse-to-fine start, the failure re-search, the bounded coasting).  ``num_kernels``
#: stays at 2, which the previous run of this protocol chose on every fold over 6.  The
#: failure level learnt from the track's history (``similarity_reference_rate``,
#: ``failure_sigmas``, ``similarity_spread_prior``) and the growing re-detection window
#: (``recovery_growth``) were run through this protocol and lost held out
#: (docs/benchmark_single_target.md, "Findings"); they stay off and out of the grid.
#: The contrast of the peak to a ring around it as the failure test (``failure_test``,
#: issue #16 item 3, at commit e43c509) lost held out too and was deleted, as did a model
#: update in confident frames only (``model_update``, at commit 9024b07), and a coasting
#: velocity that decays to 0 while the track is unseen (``coast_velocity_time_constant``,
#: an integrated Ornstein-Uhlenbeck prediction, at commit 7a344b0), and a graded
#: measurement below ``occlusion_similarity`` with its noise inflated by the colour
#: likelihood ratio (``graded_measurement``, at commit b717bb5), also with a chi-square
#: validation gate on its below-level results (``graded_validation_gate``, at commit a6c869e),
#: and distractor-aware kernel models (Possegger et al. 2015's DAT, ``distractor_rate``, at
#: commit ace72c3).
GRID = {
    "multi_start_radius": (0.0, 0.5, 1.0),
    "recovery_similarity": (0.0, 0.25, 0.4),
    "max_coast_position_std": (0.0, 1.0),
}

#: the background weighting of the kernel models (issue #16 item 3; Ning et al. 2012's
#: corrected background-weighted histogram, mk_tracker.tracking.background_weighting), each
#: choice crossed with :data:`GRID`: today's plain models, and ``cbwh`` with the weights of
#: the paper (floor 0) or floored at 0.25.  A key with a dot is a path of the whole tracker's
#: configuration (``--set`` syntax), the others are ``manual_track`` fields.
WEIGHTINGS = (
    {"background_weighting": "none"},
    {"background_weighting": "cbwh", "multi_kernel.background_weight_floor": 0.0},
    {"background_weighting": "cbwh", "multi_kernel.background_weight_floor": 0.25},
)


def _label_value(v) -> str:
    return v if isinstance(v, str) else f"{v:g}"


def grid_configs() -> list[tuple[str, dict]]:
    keys = list(GRID)
    out = []
    for weighting in WEIGHTINGS:
        for values in product(*(GRID[k] for k in keys)):
            setting = dict(zip(keys, values))
            setting.update(weighting)
            label = ", ".join(f"{k}={_label_value(v)}" for k, v in setting.items())
            out.append((label, setting))
    return out


#: ``--set NAME=VALUE`` overrides of the tracker's defaults, applied under every grid setting
BASE_CHANGES: dict = {}


def manual_config(setting: dict) -> MultiObjectTrackerConfig:
    d = updated(MultiObjectTrackerConfig(), BASE_CHANGES)
    paths = {k: v for k, v in setting.items() if "." in k}
    fields = {k: v for k, v in setting.items() if "." not in k}
    d = updated(d, paths) if paths else d
    return replace(d, manual_track=replace(d.manual_track, **fields))


def _mean_of(results: dict, names: list[str], key: str) -> float:
    return float(np.mean([results[n][0][key] for n in names]))


def choose(results: dict[str, dict], train: dict[str, list[str]]) -> str:
    """The grid label with the highest success AUC on ``train`` (clip -> sequence names):
    the mean over clips of each clip's mean, so a clip with many persons counts once."""
    def score(label):
        return float(np.mean([_mean_of(results[label], names, "success_auc")
                              for names in train.values()]))
    return max(results, key=score)


def loso_main(args, argv) -> int:
    cv2.setNumThreads(1)
    load_before = os.getloadavg()
    dev = development_set()
    dev = [(c, s) for c, s in dev if _selected(s.name, _names(args.sequences))]
    clips: dict[str, list[str]] = {}
    for clip, seq in dev:
        clips.setdefault(clip, []).append(seq.name)
    grid = grid_configs()
    peers = [(f"OpenCV {n}", _contrib(n)) for n in ("CSRT", "KCF")]
    if args.list:
        print("clips and sequences:")
        for clip, names in clips.items():
            print(f"  {clip}: " + "; ".join(names))
        print("grid:\n  " + "\n  ".join(label for label, _ in grid))
        return 0
    factories = [(label, full_tracker_factory(manual_config(s))) for label, s in grid]
    factories += [(n, opencv_tracker_factory(c)) for n, c in peers if c is not None]
    print(f"load average {load_before}; measured path: {fast_path()}", flush=True)
    warm_up(factories)
    results: dict[str, dict] = {}
    for clip, seq in dev:
        frames = list(seq.frames())
        cached = replace(seq, frames=lambda: iter(frames))
        print(f"{clip} / {seq.name} ({len(seq.truth)} frames, {seq.fps:g} fps)", flush=True)
        for name, factory in factories:
            m, ms = run(cached, factory)
            m.pop("boxes", None)
            results.setdefault(name, {})[seq.name] = (m, ms)
        best = min((n for n, _ in grid), key=lambda n: results[n][seq.name][0][
            "mean_center_error"])
        print("  " + "  ".join(f"{n.split()[-1]} {results[n][seq.name][0]['mean_center_error']:.1f}"
                               for n, c in peers if c is not None)
              + f"  grid best {results[best][seq.name][0]['mean_center_error']:.1f} ({best})",
              flush=True)
    grid_results = {label: results[label] for label, _ in grid}
    folds = {}
    for clip in clips:
        train = {c: n for c, n in clips.items() if c != clip}
        folds[clip] = choose(grid_results, train) if train else grid[0][0]
    shipped = choose(grid_results, clips)
    output = args.output or (None if args.sequences else
                             str(REPO / "docs" / "benchmark_single_target.md"))
    if args.json:        # first: a failing report must not lose the run
        Path(args.json).write_text(json.dumps({"folds": folds, "shipped": shipped,
                                               "clips": clips, "results": results}, indent=1))
    lines = loso_report(dev, clips, grid, peers, results, folds, shipped, argv,
                        (load_before, os.getloadavg()))
    print("\n".join(lines))
    if output:
        Path(output).write_text("\n".join(lines) + "\n", encoding="utf-8")
        print(f"wrote {output}")
    return 0


def _cells(m: dict) -> str:
    return (f"{m['mean_center_error']:.1f} | {m['precision_at_20px']:.2f} | "
            f"{m['success_auc']:.2f}")


def loso_report(dev, clips, grid, peers, results, folds, shipped, argv, loads) -> list[str]:
    cmd = ("PYTHONPATH=. OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 "
           "/tmp/bench_venv/bin/python benchmarks/bench_single_target.py"
           + ("" if not argv else " " + " ".join(argv)))
    peer_names = [n for n, c in peers if c is not None]
    lines = ["# Single-target benchmark: hand-started tracker, held-out (leave-one-clip-out)",
             "", "Produced by:", "", "```", cmd, "```", "",
             f"Machine: 2 cores, load average {loads[0][0]:.1f} at the start and "
             f"{loads[1][0]:.1f} at the end. Run finished "
             f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. OpenCV {cv2.__version__}"
             f" (one thread); multiple-kernel code path: {fast_path()}.", "",
             "## Protocol", "",
             "* **Tracker**: `MultiObjectTracker` with one track started by hand on the first "
             "ground-truth box (clipped to the image, the same box for every tracker), no "
             "detector, no re-initialisation; frame stamps `i / fps`.  Scored in every frame "
             "with a truth box; a tracker that reports failure is scored on its last box.",
             "* **Grid** (the settings of tracks started by hand, `manual_track.*`; everything "
             "else at its default): " + "; ".join(f"`{k}` in {{{', '.join(_label_value(v) for v in vs)}}}"
                                                   for k, vs in GRID.items())
             + "; each with the kernel models' background weighting "
             + " / ".join("`" + ", ".join(f"{k}={_label_value(v)}" for k, v in w.items()) + "`"
                          for w in WEIGHTINGS)
             + f" ({len(grid)} settings).",
             "* **Leave one clip out**: for every clip (source video) the setting with the "
             "highest success AUC on all *other* clips (mean over clips of the clip's mean over "
             "its sequences) is chosen, and only that setting's figures on the held-out clip's "
             "sequences are reported below.  A clip's persons and its low-frame-rate copy are "
             "held out together, so no figure comes from a setting chosen with its images.",
             "* **Shipped defaults** = the setting chosen on all clips: "
             f"`{shipped}`.  Its own figures on these clips are in-sample (last table).",
             "* Metrics: mean centre error (px, lower is better), precision@20 px, success AUC "
             "(IoU).  Peers: " + (", ".join(peer_names) or "none (opencv-contrib missing)")
             + " on the same frames and first box.",
             "", "## Held-out figures (primary)", ""]
    names_all = [s.name for _, s in dev]
    held = {}
    for clip, names in clips.items():
        for n in names:
            held[n] = results[folds[clip]][n]
    head = "| sequence | clip | ours err | P@20 | AUC | ms | " + " | ".join(
        f"{p} err | P@20 | AUC" for p in peer_names) + " |"
    lines += [head, "|" + "---|" * (5 + 1 + 3 * len(peer_names))]
    for clip, seq in dev:
        m, ms = held[seq.name]
        row = f"| {seq.name} | {clip} | {_cells(m)} | {ms:.2f} |"
        for p in peer_names:
            row += f" {_cells(results[p][seq.name][0])} |"
        lines.append(row)

    def summary(label, names):
        ours = {k: float(np.mean([held[n][0][k] for n in names]))
                for k in ("mean_center_error", "precision_at_20px", "success_auc")}
        row = f"| {label} | {len(names)} | {_cells(ours)} | " \
              f"{float(np.median([held[n][1] for n in names])):.2f} |"
        for p in peer_names:
            pm = {k: float(np.mean([results[p][n][0][k] for n in names]))
                  for k in ("mean_center_error", "precision_at_20px", "success_auc")}
            row += f" {_cells(pm)} |"
        return row
    lines += ["", "Means per clip and overall (each sequence counts once; ms = median):", "",
              "| clip | sequences | ours err | P@20 | AUC | ms | " + " | ".join(
                  f"{p} err | P@20 | AUC" for p in peer_names) + " |",
              "|" + "---|" * (6 + 3 * len(peer_names))]
    for clip, names in clips.items():
        lines.append(summary(clip, names))
    real = [n for c, ns in clips.items() if not c.startswith("generator") for n in ns]
    if real:
        lines.append(summary("**all real sequences**", real))
    lines.append(summary("**all sequences**", names_all))
    wins = sum(held[n][0]["mean_center_error"] < results["OpenCV CSRT"][n][0][
        "mean_center_error"] for n in real) if "OpenCV CSRT" in peer_names else 0
    if "OpenCV CSRT" in peer_names:
        lines += ["", f"Lower mean centre error than CSRT on {wins} of {len(real)} real "
                  "sequences (issue #16 asks for all)."]
    lines += ["", "## Setting chosen per held-out clip", "",
              "| held-out clip | chosen on the other clips |", "|---|---|"]
    for clip in clips:
        lines.append(f"| {clip} | `{folds[clip]}` |")
    lines += ["", "## Every grid setting (in-sample: mean over clips of clip means)", "",
              "| setting | err | P@20 | AUC | median ms |", "|---|---|---|---|---|"]
    for label, _ in grid:
        r = results[label]
        vals = {k: float(np.mean([_mean_of(r, ns, k) for ns in clips.values()]))
                for k in ("mean_center_error", "precision_at_20px", "success_auc")}
        ms = float(np.median([r[n][1] for n in names_all]))
        mark = " (shipped)" if label == shipped else ""
        lines.append(f"| `{label}`{mark} | {_cells(vals)} | {ms:.2f} |")
    lines += ["", LOSO_NOTES, "", LOSO_FINDINGS]
    return lines


LOSO_FINDINGS = """## Findings (hand-written from the run of 2026-11-27 15:40 UTC)

The tables above are the evidence.

* **Corrected background-weighted histograms** (issue #16 item 3; Ning, Zhang, Zhang & Wu,
  IET Computer Vision 2012; `manual_track.background_weighting` cbwh with
  `multi_kernel.background_weight_floor` 0.25, the default for tracks started by hand since
  this run; `mk_tracker/tracking/background_weighting.py`).  Each kernel's model is
  weighted by how rare its colours are in a ring of background around the first box
  (half a box size on every side), on the model only; decisions use the cost above the
  first box's, so every similarity level keeps its scale; the scale step (9)-(11) uses the
  plain models.  **Held out, the 26 real sequences: 50.9 px / P@20 0.59 / AUC 0.45 before
  (the 13:40 run), 42.5 / 0.60 / 0.46 now; lower error than CSRT on 12 of 26 (13 before).**
  All 39: 35.5 / 0.72 / 0.56 -> 29.5 / 0.73 / 0.57.  Six of seven folds chose cbwh with
  floor 0.25 (and `recovery_similarity` 0.25, which matters with the weighting: 19.4 against
  32.3 px in-sample with floor 0); the TUD-Stadtmitte fold chose the plain models, so its
  17 held-out rows did not change.  Per sequence, held out: OTB Woman 251.7 -> 36.1 px
  (mostly the fold's choice of `max_coast_position_std` 1 coming with cbwh: the plain models
  give 40.4 px there), OTB Crossing 5.9 -> 5.7 px (AUC 0.60 -> 0.54), TUD-Campus persons
  1, 2, 3 14.2 / 17.0 / 12.1 -> 9.5 / 10.2 / 10.9 px, persons 4, 5, 7, 8 13.1 / 12.5 / 11.1 /
  5.6 -> 15.1 / 17.7 / 12.6 / 7.0 px (person 5 now above CSRT's 14.9: the lost win).
  At the setting chosen on all clips (in-sample on TUD-Stadtmitte, where its fold did not
  choose it): person 3, the look-alike passer-by, 310.6 -> 15.3 px (CSRT 13.0), at 6.25 fps
  57.8 -> 9.0 (CSRT 16.8), person 8 108.6 -> 57.6 (CSRT 75.0), but person 9 at 6.25 fps
  36.0 -> 145.4 and person 8 at 6.25 fps 76.1 -> 117.9; the clip 57.6 -> 43.6 px, AUC 0.38 ->
  0.43.  Median time per frame 0.55 -> 0.78 ms (the ring's histogram at the start, one more
  evaluation for the scale step).
* **The back-projection extent as the scale measurement: lost held out, deleted**
  (issue #16 item 3, 2026-11-27 16:16 UTC; `manual_track.extent_scale_rate` in
  `mk_tracker/tracking/scale_estimation.py` at commit cd30249, where this run reproduces).  Seven of the 14 losses to CSRT are box
  accuracy without a failure (failure_analysis.md, "The 14 losses to CSRT after the
  background weighting").  With cbwh, the samples around the box whose colour is more
  frequent in the target's model than in the ring (`q_u > o_u`, and at least the uniform
  share) give the person's height by their second moment, as CAMShift sizes its window from
  the back-projection's moments (Bradski 1998); where that height is usable (at least 0.3
  of the box's samples, within 1.25x of the box's height) the scale moves `extent_scale_rate`
  of the way to it instead of taking the step (9)-(11).  (Taken after (9)-(11) instead of
  in its place, the two fought on a person started with background above the head: (10)
  grew the box back every frame; test/tracking/test_back_projection_extent.py.)  Run once:
  this protocol with two more weighting entries, cbwh floor 0.25 with `extent_scale_rate`
  0.05 / 0.2 (90 settings; `/tmp/bench_venv_s3`, built from benchmarks/requirements.txt, in a
  copy of the worktree, `--output`; load 3.0 -> 2.7).  Six of seven folds and the choice on
  all clips took rate 0.05 (OTB Woman's fold took today's setting).  **Held out, the 26 real
  sequences: 48.8 px / P@20 0.58 / AUC 0.46 against 42.5 / 0.60 / 0.46 without it; lower
  error than CSRT on 13 of 26** (TUD-Stadtmitte person 7 and person 3 at 6.25 fps won, person
  9 at 6.25 fps lost: 36.0 -> 144.2 px against CSRT's 71.2); all 39: 33.6 / 0.72 / 0.57
  against 29.5 / 0.73 / 0.57.  The error and P@20 are worse and a win is lost, so it stays
  off.  At the shipped grid point, in-sample, rate 0.05 against 0: TUD-Campus person 8 7.0
  -> 4.7 px (AUC 0.75 -> 0.80), TUD-Stadtmitte person 5 18.1 -> 11.4 (0.65 -> 0.72), person 2
  10.5 -> 6.6, person 7 17.0 -> 14.4, person 8 at 6.25 fps 117.9 -> 76.0; but person 3 15.3 ->
  308.7 (the passer-by takes the track again; not traced), person 1 17.5 ->
  28.1 (the box settles 0.13 of its height low), person 8 57.6 -> 80.8, TUD-Campus person 3
  10.9 -> 14.2, OTB Woman 36.1 -> 39.1; mean of clip means 15.3 -> 17.9 px, AUC 0.59 both.
  Rate 0.2: 18.8 px / AUC 0.56.  Most of the accuracy gap is not the size: on TUD-Stadtmitte
  the box sits 0.12-0.19 box widths behind the walker, which a scale cannot fix.
* **Left/right centring by a 2 x 2 layout: lost held out, deleted** (issue #16 item 3,
  2026-11-27 16:54 UTC; `manual_track.column_centring` at commit b6db266, where this run
  reproduces).  The measurement first (`benchmarks/diagnose_box_bias.py`, kept; median
  offset along the walking direction in truth widths, shipped defaults): the 2-kernel
  optimum itself sits behind (TUD-Stadtmitte 4: kernels -0.125, reported -0.146; 4 at 6.25
  fps -0.135 / -0.158; TUD-Campus 3 and 5 -0.06 / -0.05), and the peak of the mean kernel
  similarity along that direction lies where the kernels stopped (-0.124 on TUD-Stadtmitte
  4), so it is the colour optimum, not a search that stops short.  The Kalman update
  (Sec. IV-D) takes the measurement with a gain of 0.19-0.46 on x (`sigma_w` 2-9.5 px) and
  lags it only on the 22-frame TUD-Stadtmitte 1 (kernels -0.04, reported -0.21: the
  velocity is still being learnt); with a 4x smaller measurement noise the kernels stay
  behind (-0.144), so a measurement noise from the fit's precision would not move them.
  With a 2 x 2 layout (`num_kernels` 4) the optimum is on the person (TUD-Stadtmitte 4,
  5, 1: +0.002, +0.007, -0.003): the two stacked full-width kernels have no left/right
  structure.  But 4 kernels alone lose the track more often (26 real sequences, shipped
  setting, in-sample: 51.5 px against 33.3).  So the fix kept the 2 kernels for
  visibility, y and size and let a 2 x 2 layout, started on the first box, re-centre x from
  their result (bounded to 0.25 widths, both columns must see the target, no scale step).
  It does what it was built for: the reported offsets fall to -0.057 (TUD-Stadtmitte 4),
  -0.002 (5), -0.044 / -0.027 (TUD-Campus 3, 5), and held out TUD-Campus 3 10.9 -> 9.1 px
  (now below CSRT's 9.7), 8 7.0 -> 4.6, TUD-Stadtmitte 4 11.2 -> 8.6, 4 at 6.25 fps 11.3
  -> 7.7.  Run once: this protocol with `column_centring` 0 / 0.25 crossed with the grid (108
  settings, the .venv without opencv-contrib, so no peers: the CSRT figures are this
  document's; load 1.8 -> 3.0).  Every fold chose 0.25 (with `multi_start_radius` 1).
  **Held out, the 26 real sequences: 54.9 px / P@20 0.61 / AUC 0.47 against 42.5 / 0.60 /
  0.46; lower error than CSRT on 14 of 26 against 12**; all 39: 37.6 / 0.74 / 0.58 against
  29.5 / 0.73 / 0.57.  The error is worse, so it stays off and the code is deleted: OTB
  Woman 36.1 -> 323.0 px (its fold now chose `recovery_similarity` 0 and
  `max_coast_position_std` 0: the track runs away), TUD-Stadtmitte 8 at 6.25 fps 76.1 ->
  163.4, 9 at 6.25 fps 36.0 -> 61.4, person 2 7.8 -> 15.8, person 1 13.4 -> 17.0 (the
  Kalman lag above, untouched).  At the shipped grid point, in-sample, 0.25 against 0:
  26 real sequences 44.7 / 0.62 / 0.48 against 33.3 / 0.64 / 0.49, all of it TUD-Stadtmitte
  person 3 15.3 -> 310.8 px (the passer-by takes the track again: a re-centred x pulls the
  box onto her side; a bound of 0.1 widths does the same, 312.1); median CPU time 0.67 ->
  1.00 ms per frame.
* **A template (spatial-structure) cue after the search: lost held out, deleted** (issue
  #16 item 3, 2026-11-27 19:13 UTC; `manual_track.template_cue` in
  `mk_tracker/tracking/template_cue.py` at commit 958f28e, where the second run below
  reproduces; the first variant at bf8c950).  CSRT wins on box accuracy and look-alikes by
  matching spatial structure, which the colour histograms lack.  After Algorithm 1 a grey
  template of the first box (its central 0.7 of the width, resampled to 24 px wide) was
  matched by OpenCV's normalised cross-correlation (`cv2.matchTemplate`,
  `TM_CCOEFF_NORMED`) over the search's box shifted by up to 0.3 box widths, and a peak of
  at least 0.5 that was 0.05 above the correlation at the box itself moved the measured
  centre to it (the Kalman update (4.4)-(4.5) then blends it as before); the scale stayed
  the kernels'.  Cost: 0.09 ms per call for a 40 x 100 px person (median of 3000 calls),
  +0.12-0.15 ms in the median ms per frame of the grid.  Run twice with the cue as a
  choice crossed with the whole grid (`/tmp/bench_venv_tmpl`, built from
  benchmarks/requirements.txt; `--output` elsewhere).  In both runs the cue-off settings
  reproduce this report's held-out figures exactly (42.5 px / 0.60 / 0.46, 12 of 26; a
  separate run of this report's grid at 18:43 UTC too).
  (1) Off / on, moving x and y (108 settings; load 5.8 -> 3.7): every fold chose the cue.
  **Held out, the 26 real sequences: 48.9 px / P@20 0.60 / AUC 0.47 against 42.5 / 0.60 /
  0.46; lower error than CSRT on 13 of 26 against 12.**  On TUD-Campus 2 the cue followed
  maxima on the window's corners (0.3 widths off in x and y, peak 0.55-0.6) frame after
  frame, so (2) rejects a maximum on the correlation map's rim, and offers x only (the
  window reaching 0.1 widths in y; the stacked kernels place the person vertically) and x
  and y (162 settings; load 3.9 -> 3.9): every fold chose x and y; **held out 67.0 px / 0.53
  / 0.43, 13 of 26**; with the folds choosing among the x-only settings, 55.5 / 0.57 / 0.44,
  12 of 26.  The error is worse in both, so it stays out and the code is deleted.
  It does what it was built for on some walkers (held out, run 2): TUD-Campus 3 10.9 -> 8.9
  px (below CSRT's 9.7), 4 15.1 -> 10.2, 8 7.0 -> 5.1, TUD-Stadtmitte 1 13.4 -> 9.6, 4 11.2
  -> 8.4, 4 at 6.25 fps 11.3 -> 8.2.  But with the cue the folds choose
  `recovery_similarity` 0 and other weightings: OTB Woman 36.1 -> 267.7 px, TUD-Campus 5
  17.7 -> 135.9, TUD-Stadtmitte 3 at 6.25 fps 57.8 -> 325.3, person 9 22.4 -> 60.6.  At the
  shipped grid point, in-sample, cue off / x / x and y: 33.3 / 44.5 / 45.0 px over the 26
  real sequences (P@20 0.64 / 0.62 / 0.61, AUC 0.49 / 0.48 / 0.48, below CSRT on 13 / 14 /
  14), the whole rise being TUD-Stadtmitte person 3, the look-alike (15.3 -> 308.1 /
  309.8 px): a 3.6 px move of the standing woman's third measurement gives the filter a
  small velocity, the passer-by hides her from frame 4, the coasting box drifts 14 px in
  15 frames and the re-search finds him at frame 19.  A grey template of a person in dark
  clothes on a light background correlates with any person in dark clothes, so it does not
  tell the look-alike apart either.  Without that sequence 34.0 / 34.0 / 34.4 px: gains on
  single walkers, losses in groups (x and y: TUD-Stadtmitte 7 17.0 -> 26.8, 7 at 6.25 fps
  20.4 -> 28.5, TUD-Campus 2 10.2 -> 16.5), where a neighbour's or occluder's structure in
  the window correlates at 0.5-0.6.  Paired over all 54 grid points the cue changes the
  mean real error by -0.3 px (x only) and +0.7 px (x and y).
* **Diagnosis of OTB Woman and TUD-Stadtmitte person 3** (2026-11-28, per frame with
  `benchmarks/diagnose_single_target.py --trace --all`, each clip at its held-out setting;
  person 3 with `--set background_weighting=none --set recovery_similarity=0`).
  *OTB Woman* (36.1 px): seen in frames 2-7 only (weighted level 0.63 -> 0.44, error at most
  3.3 px); from frame 8 the level is below `occlusion_similarity` 0.4 (0.31) and the track
  is unseen in 590 of 596 frames.  Frames 8-27 the box coasts on the velocity of frames 2-7
  (about -1 px per frame in x and y: she walked up-left, then turns right with the pan),
  error 2 -> 26 px; at frame 28 the position std passes one box width (21 px) and the box is
  held at (196, 90) for the last 570 frames, where no search scores above 0.36 (above 0.1 in
  74 frames).  The 36.1 px are her wandering around the held box (x 114-233).  Not scale:
  her truth box stays 18-25 x 81-101 px until frame ~550 against the box's 21 x 95 (the
  scale step (9)-(11) never runs after frame 7, the gate is not passed); the last 40 frames
  (up to 37 x 157) add a little.  Cause: the colour model against the absolute level
  (failure_analysis.md: exp(-J) 0.02-0.15 on her), then a coast on a stale velocity.
  *TUD-Stadtmitte person 3* (310.6 px): she stands still (truth x 183-184 in frames 1-30).
  In frames 2-5 the track is seen (0.57 -> 0.44) but the measured box walks right 2-4 px per
  frame as the passer-by in dark clothes comes up beside her (error 2.4 -> 11.9 px), so the
  filter (initial velocity std 200 px/s) learns about +75 px/s; frames 6-17 unseen (0.21-0.39),
  the box coasts +3 px per frame (error 15 -> 49 px); at frame 18 the search from the drifted
  prediction scores 0.41 on the passer-by and the track follows him out of the image.  At
  6.25 fps the first measurement is already 12 px right, the coast carries the box 68 px off
  by frame 6, where it is held (57.8 px).  Not scale (box 35-36 x 154, truth 35.5-44 x 154).
  Cause: drift onto a similar neighbour, then a velocity learnt from 3-4 pulled
  measurements extrapolated by (2.2) while unseen.  In both clips the box leaves the person
  while coasting on a velocity learnt in a handful of frames.
* **A decaying velocity while unseen: lost held out, deleted** (2026-11-28;
  `manual_track.coast_velocity_time_constant` at commit 7a344b0).  Chu et al. Sec. IV-D start
  Algorithm 1 ((5)/(8)) from the Kalman prediction and give no motion model; the filter is
  (2.1)-(2.3), (4.2)-(4.3) of `mk_tracker/kalman.py`.  While a hand-started track is unseen
  its prediction used an integrated Ornstein-Uhlenbeck velocity instead of (2.2): `v' = e v`,
  `x' = x + tau (1 - e) v`, `e = exp(-dt / tau)` (the Singer model one order down;
  Bar-Shalom, Li & Kirubarajan 2001, Sec. 8.2), so a coast travels at most `tau v`;
  `Sigma_u` of (2.3) unchanged; seen frames unchanged.  Quick checks on the diagnosed clips:
  person 3 at its fold's setting 310.6 -> 21.1 px (tau 0.2 s) / 298.2 (1 s), at 6.25 fps
  57.8 -> 35.5 / 301.1; Woman 36.1 -> 35.2 / 35.3 (no search passes 0.4 anyway).  Run once:
  `PYTHONPATH=. OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 nice -n 10
  /tmp/bench_venv_B/bin/python benchmarks/bench_single_target.py --output /tmp/wtB_tau.md
  --json /tmp/wtB_tau.json` at 7a344b0 (tau 0 / 0.2 / 1 s crossed with the grid without
  `multi_start_radius` 0 and the unfloored cbwh, chosen by no fold: 72 settings;
  `/tmp/bench_venv_B` from benchmarks/requirements.txt; load 2.6 -> 1.7, 8 min).  The tau 0
  settings reproduce this report's held-out figures exactly (42.5 / 0.60 / 0.46, 12 of 26,
  recomputed from the JSON).  Only the TUD-Stadtmitte fold chose it (tau 1, plain models).
  **Held out, the 26 real sequences: 55.6 px / P@20 0.54 / AUC 0.42 against 42.5 / 0.60 /
  0.46; lower error than CSRT on 12 of 26, as before**; all 39: 38.2 / 0.69 / 0.54 against
  29.5 / 0.73 / 0.57.  Worse on every figure, so it is deleted.  Held-out rows that moved
  (TUD-Stadtmitte, 57.6 -> 77.7 px): person 8 108.6 -> 34.4 (below CSRT's 75.0: won), 9 at
  6.25 fps 36.0 -> 22.4, 3 310.6 -> 298.2; but 2 7.8 -> 43.7, 7 21.0 -> 60.5, 9 22.4 -> 71.3,
  2 at 6.25 fps 8.5 -> 39.4 (above CSRT's 9.7: lost), 7 at 6.25 fps 18.7 -> 60.4, 3 at 6.25
  fps 57.8 -> 301.1.  Paired over the 24 other grid points the mean real error changes by
  -0.6 px (tau 0.2; -16.1 to +15.6) and -0.8 px (tau 1; -12.9 to +13.0), the AUC by -0.062 /
  -0.018; at the shipped point, in-sample, 33.3 -> 43.6 / 45.4 px, AUC 0.49 -> 0.43 / 0.46
  (person 3 15.3 -> 168.8 / 294.1: with cbwh the decayed box waits beside her and the search
  from it finds him).  Why it loses, traced (TUD-Stadtmitte person 2, shipped setting): a
  walker whom the absolute level calls unseen for long stretches (frames 37-60 at 0.31-0.40)
  is carried by the constant velocity 5-9 px from her; with tau 0.2 s the box stops at x 322
  and she walks away (84 px by frame 60; 10.5 -> 69.6 px over the clip).  The constant
  velocity tracks walkers through the frames the level rejects, which matters more here
  than the spurious velocities of people standing still.  Cost: none measurable (median ms
  per frame at the shipped point 0.94 / 0.98 / 0.93 for tau 0 / 0.2 / 1, same run).  The
  root in Woman and in person 2 is the same: on-target searches scored below the absolute
  level 0.4.  The tables above were regenerated after the deletion (2026-11-28 03:38 UTC,
  from `/tmp/bench_venv_B`, built from benchmarks/requirements.txt, with `--json`): every
  accuracy figure is the same as in the run of 2026-11-27 15:40; only the ms column is new.
* **A graded measurement below the level: lost held out on the mean error, deleted**
  (2026-11-28; `manual_track.graded_measurement`, `graded_measurement_floor` 0.2,
  `graded_likelihood_sharpness` in `mk_tracker/tracking/graded_measurement.py` at commit
  b717bb5, where this run reproduces).  The diagnosis above: on-target searches scoring
  0.31-0.40, below `occlusion_similarity` 0.4, are rejected and the track coasts.  Chu et
  al. score each kernel by `rho_i = exp(-J_i)`, `J_i` the K-L distance of model and
  candidate histograms (Sec. V; the cost (3), weighted (7)); the visibility statistic is
  the weighted mean of (7)-(8).  Probabilistic colour trackers do not threshold: the match
  enters as a likelihood `exp(-lambda D)` of the histogram distance (Perez, Hue, Vermaak &
  Gangnet, ECCV 2002, `exp(-20 d^2)` on the squared Bhattacharyya distance).  So a result
  below the level and at least the floor (0.2, quality 0 of `refinement_similarity_range`)
  still corrected the Kalman filter ((4.4)-(4.5), centre only, the track stays occluded and
  is not held) with the information of a match at the level scaled by the likelihood ratio:
  `sigma(s) = sigma(0.4) (0.4 / s)^(lambda / 2)`, `J = -ln s`; lambda 5 (K-L ~ 4 d^2 near a
  match, so Perez's 20 / 4) or 20.  Run once: `PYTHONPATH=. OMP_NUM_THREADS=1
  OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 nice -n 10 /tmp/bench_venv_B/bin/python
  benchmarks/bench_single_target.py --output /tmp/wtE_graded.md --json /tmp/wtE_graded.json`
  at b717bb5 (off / lambda 5 / lambda 20 crossed with the grid without `multi_start_radius`
  0 and the unfloored cbwh: 72 settings; `/tmp/bench_venv_B` from
  benchmarks/requirements.txt; load 4.9 -> 2.5, 8 min).  The off settings reproduce this
  report's held-out figures exactly (42.5 / 0.60 / 0.46, 12 of 26, recomputed from the
  JSON).  Every fold chose lambda 5 (with `multi_start_radius` 1 and cbwh; six of seven with
  `recovery_similarity` 0); no fold chose lambda 20.  **Held out, the 26 real sequences:
  48.5 px / P@20 0.64 / AUC 0.49 against 42.5 / 0.60 / 0.46; lower error than CSRT on 15 of
  26 against 12** (won: TUD-Stadtmitte 7 21.0 -> 13.7 px, 8 108.6 -> 28.0, 8 at 6.25 fps
  76.1 -> 27.5); all 39: 33.4 / 0.76 / 0.59 against 29.5 / 0.73 / 0.57.  The mean error is
  worse, so by this project's rule it is deleted, although P@20, AUC and the wins improve:
  without TUD-Stadtmitte person 3 at 6.25 fps the 25 others go 41.9 / 0.62 / 0.47 -> 37.9 /
  0.66 / 0.51; the median per-sequence error 16.6 -> 15.7 px.  Held-out rows that moved by
  more than 2 px: better, TUD-Campus 7 12.6 -> 7.9, TUD-Stadtmitte 7 at 6.25 fps 18.7 ->
  14.6, 9 at 6.25 fps 36.0 -> 22.7, 6 at 6.25 fps 92.3 -> 77.7; worse, TUD-Stadtmitte 3 at
  6.25 fps 57.8 -> 313.9 (CSRT 16.8), 9 22.4 -> 65.6, 6 85.5 -> 113.0, 1 13.4 -> 19.1, 5
  15.6 -> 17.9, OTB Woman 36.1 -> 38.3 (the clip it was built for: its fold took
  `max_coast_position_std` 0; at `multi_start_radius` 1, `recovery_similarity` 0.25,
  coast bound 1, cbwh it gives 23.3 px, AUC 0.09 -> 0.32, in-sample).  Why person 3 at
  6.25 fps fails, traced (`benchmarks/diagnose_single_target.py --trace --sequences
  'TUD-Stadtmitte person 3 at 6.25' --set multi_start_radius=1 --set
  recovery_similarity=0 --set graded_measurement=true`, then `=false`): she stands still;
  the searches of frames 2-3 score 0.37 and 0.24 and end 7 and 24 px to her right, towards
  the passer-by; off, they are rejected and the box stays on her (0.3-18 px all clip); on,
  they pull the box right, the search of frame 4 finds him at 0.41 (a full measurement) and
  the track follows him out of the image.  Below the level a look-alike scores as high as
  the person, and the graded measurement cannot tell them apart.  Paired over the 24 grid
  points, the mean real error changes by +1.6 px (lambda 5; -15.8 to +17.4) and +5.1 px
  (lambda 20); at the shipped point, in-sample, 33.3 -> 46.9 / 53.4 px (AUC 0.49 -> 0.50 /
  0.46).  Cost: none (no extra search; median ms per frame at the same grid point 1.00x /
  0.98x of off, same run; held out 0.84 -> 0.96 ms from the folds' `multi_start_radius` 1).
* **A validation gate on the graded measurement: lost held out, deleted with it**
  (2026-11-28; `manual_track.graded_validation_gate` in
  `mk_tracker/tracking/graded_measurement.py` at commit a6c869e, on b717bb5's code).  A
  graded (below-level) result corrected the filter only if the squared Mahalanobis distance
  of its centre to the prediction, under `H P H^T` plus the *un-inflated* noise of a match at
  the level, was within a chi-square quantile for 2 dof (Bar-Shalom & Fortmann's validation
  gate; 5.99 = 95%, 9.21 = 99%); results at the level ungated.  Run once:
  `PYTHONPATH=. OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 nice -n 10
  /tmp/bench_venv_B/bin/python benchmarks/bench_single_target.py --output /tmp/wtF_gate.md
  --json /tmp/wtF_gate.json` at a6c869e (off / lambda 5 / lambda 5 + gate 5.99 / + gate 9.21
  crossed with the 24 grid settings: 96; load 1.0 -> 1.4, 9 min).  Recomputed from the JSON
  with the folds choosing among subsets: off alone reproduces 42.5 / 0.60 / 0.46 (12 of 26
  below CSRT), off + lambda 5 the previous run's 48.5 / 0.64 / 0.49 (15 of 26).  **Held out,
  the 26 real sequences: all four 54.4 px / P@20 0.63 / AUC 0.49, 15 of 26** (six folds took
  ungated lambda 5; OTB Woman's fold took gate 5.99 and lost her, 38.3 -> 191.1 px); off and
  gate 9.21 only: 49.6 / 0.65 / 0.49, 14 of 26; off and gate 5.99: 55.0 / 0.64 / 0.49, 14;
  off and both gates: 55.6 / 0.64 / 0.48, 14.  None beats 42.5 px, so it is deleted.  The
  gate misses its target: TUD-Stadtmitte person 3 at 6.25 fps stays at 313.9 px in every
  gated setting.  Traced (`benchmarks/diagnose_single_target.py --trace --sequences
  'TUD-Stadtmitte person 3 at 6.25' --set multi_start_radius=1 --set recovery_similarity=0
  --set max_coast_position_std=1 --set background_weighting=cbwh --set
  graded_measurement=true --set graded_validation_gate=5.99`): the same searches of frames
  2-3 (0.37 / 0.24, error 6.6 / 24.4 px), the box on him from frame 4.  Two frames after the
  start the prediction's covariance is still that of the start
  (`manual_track.initial_velocity_var` 40000 (px/s)^2: about 32 px std per frame at 6.25
  fps), so a pull of 7 or 24 px is well inside any such gate; a gate on the prediction
  cannot act before the
  filter has learnt where the person goes, and the passer-by must be told apart by
  appearance.  At the shipped point, in-sample, lambda 5 -> + gate 5.99 / 9.21: TUD-Stadtmitte
  person 9 65.6 -> 15.5 / 15.5 px, but person 8 28.0 -> 94.5 / 94.5 and 8 at 6.25 fps 27.5 ->
  25.1 / 39.2; real mean 48.0 -> 48.6 / 49.1 px, P@20 0.64 -> 0.66 / 0.65.  Paired over the 24
  grid points the gate changes the mean real error by +1.6 px (5.99; -3.3 to +6.6) and +4.1
  px (9.21; +0.4 to +10.0).  Cost: none (median ms at the shipped point 0.93 -> 0.94 / 0.95).
* **Not for tracks born from detections.**  `benchmarks/bench_multi_object.py --grid
  multi_kernel.background_weighting=none,cbwh` (its leave-one-sequence-out protocol, 64
  settings, floor 0.25; run once, 2026-11-27 15:48 UTC, report not committed): only the
  TUD-Campus fold chose cbwh (TUD-Campus held out 0.515 / 0.680 -> 0.515 / 0.676);
  held-out mean MOTA / IDF1 / HOTA 0.721 / 0.783 / 0.631 against
  0.721 / 0.784 / 0.632 without it in the grid (docs/benchmark_multi_object.md).  Between
  settings that differ only in it, MOTA + IDF1 changes by -0.052 on TUD-Campus, -0.010 on
  TUD-Stadtmitte, +0.013 on crowd-15 and -0.002 on far-7fps (mean over 32 pairs each), and
  over all four sequences the plain models are preferred.  A detection corrects those
  tracks every frame, so the refinement rarely has to tell a look-alike apart; it stays off
  there (`multi_kernel.background_weighting` none).
* **cbwh variants that lost.**  Ning et al.'s weights without a floor (floor 0): no fold chose
  them; in-sample TUD-Campus 12.2 -> 48.7 px, OTB Crossing 5.9 -> 17.5, Woman 40.4 -> 94.3
  (a target colour that is also frequent in the ring drops to ~1% of its weight, and the
  kernels slide off the person).  The scale step with the weighted models (this protocol's
  first run today): the box shrank onto the target-specific colours (generator persons' AUC
  0.65-0.71 instead of 0.84-0.89), no fold chose cbwh, held out unchanged at 50.9 / 0.59 /
  0.45.  Re-computing the ring histogram when it changed (Ning et al.): on these clips the
  Bhattacharyya coefficient between the first ring and later ones stayed at 0.74-0.97, so
  at the shipped level 0.5 it never fires; at 0.9 (a development run on the 26 real
  sequences, in-sample, floor 0.1) P@20 / AUC went 0.64 / 0.49 -> 0.57 / 0.47.
* **The image border as an occluder** (`manual_track.border_person_aspect` 0.41, on since
  the 13:40 run; docs/image_border.md).  A first box that is a sliver at the left or right image
  edge is the visible part of a person: the kernels are laid out on the whole person past
  the border, a cut kernel's mean shift is taken relative to its in-image support, its model
  is completed as it comes into view, and the reported box is clipped to the image.  Same
  session, held out, the 26 real sequences: 51.6 px / P@20 0.55 / AUC 0.41 before, 50.9 /
  0.59 / 0.45 after (all 39: 36.3 / 0.70 / 0.51 -> 35.5 / 0.72 / 0.56); 13 of 26 below CSRT
  before and after (TUD-Stadtmitte person 8 lost to CSRT, 73.7 -> 108.6 px; person 10 won,
  85.4 -> 83.1 px against CSRT's 84.9).
* **Choice (the 13:40 run, before cbwh).**  Every fold chose `multi_start_radius` 0.5 and
  `recovery_similarity` 0 (and `max_coast_position_std` 1, with OTB Woman held out 0); with
  the plain models `recovery_similarity` 0 and 0.25 give the same result on every sequence.
* **Held out, against the peers (this run).**  The 26 real sequences: 42.5 px / P@20 0.60 /
  AUC 0.46 (CSRT 58.9 / 0.58 / 0.45); lower error than CSRT on 12 of 26.  All 39: 29.5 /
  0.73 / 0.57 (CSRT 49.8 / 0.67 / 0.52).  Issue #16's single-target goals (below CSRT on
  every real sequence; <= 20 px, P@20 >= 0.75, AUC >= 0.50 over a mixed set) are **not met**.
* **Issue #16 item 3: what was tried and lost held out** (runs of this protocol on
  2026-11-27 with other grids, the rest of the settings at the shipped values; the code is
  in `mk_tracker/tracking/redetection.py`, off by default).  Failure detection against a
  level learnt from the track's own history (each kernel's Bhattacharyya coefficient `B_i`
  or negated K-L cost `-J_i` against its learnt mean and spread, `similarity_reference_rate`,
  `learnt_measure`, `failure_sigmas`, `similarity_spread_prior`) and a re-detection window
  that grows with the time lost (`recovery_growth`, `recovery_margin`).  Real sequences, held out, err / P@20 / AUC (wins over CSRT):

  | grid (each with rate 0, the shipped behaviour, as a candidate) | held out | wins |
  |---|---|---|
  | `B_i` over a learnt reference (rate 0 / 0.02 / 0.1; `recovery_similarity` 0.25 / 0.5; growth 0 / 0.5) | 72.2 / 0.49 / 0.38 | 10 of 26 |
  | `B_i` against learnt mean and spread (rate 0 / 0.05 / 0.2; 2 / 4 spreads; growth 0 / 0.5) | 81.5 / 0.49 / 0.36 | 8 of 26 |
  | the same, a confirmation level of 0 / 0.75 for re-detections, first window 0.5 / 2 box sizes (growth 0.5) | 81.5 / 0.49 / 0.36 | 8 of 26 |
  | the same, prior spread 0.1 / 0.2 (4 spreads; growth 0 / 0.5) | 85.4 / 0.49 / 0.37 | 10 of 26 |
  | `-J_i` against learnt mean and spread (rate 0 / 0.05 / 0.2; prior spread 0.5 / 1; 4 / 8 spreads) | 63.5 / **0.59** / **0.44** | 11 of 26 |
  | the same, prior spread 0.25 / 0.5; 2 / 3 / 4 spreads | 64.7 / 0.56 / 0.42 | 11 of 26 |
  | the run of 10:22 UTC (none of them, border off) | **51.6** / 0.55 / 0.41 | **13 of 26** |

  The `-J_i` level is the only variant with better held-out P@20 and AUC, and every
  fold chose it, but it raises the mean error by 12 px and loses two sequences
  to CSRT, and its in-sample figures jump between neighbouring grid points (19.7 / 66.3 /
  56.0 px at 4 / 3 / 2 spreads): kept off.  In the first `-J_i` grid it brings OTB Woman from
  226.9 to 12.3 px held out (43.5 in the second, whose Woman fold chose rate 0.05) (the track had said `occluded` in 99% of her frames) and TUD-Stadtmitte person 9 at
  6.25 fps from 70.1 to 42.2, but lets tracks on TUD-Stadtmitte follow a look-alike that the
  absolute level made them coast through (person 6 85.5 -> 172.1 px, person 7 at 6.25 fps
  18.7 -> 260.2, person 3 at 6.25 fps 57.8 -> 305.8).  `B_i` separates the target from a
  neighbour or background too little (they score 0.5-0.85 of its coefficient; TUD-Campus
  person 5 12.5 -> 129.9 px).  A growing window at the absolute level raised the in-sample
  error from 19.5 to 42.7 px (a wider scan finds look-alikes more often than the lost
  person); a confirmation level of 0.75 for re-detections brought that back to 21.5 px, still
  above the shipped 19.5, and no fold chose it, so it was deleted.  Per sequence:
  failure_analysis.md.
* **The failures** (failure_analysis.md, "Single target"): none comes from large motion (at
  most 0.45 box widths per frame at the first failure); they are a track stuck `occluded`
  (OTB Woman), a similar neighbour (TUD-Stadtmitte person 3; kept with cbwh, in-sample, as
  its clip's fold did not choose it), people at the image edge
  (TUD-Stadtmitte persons 5, 8, 10; the border as an occluder fixes TUD-Campus person 7 and
  TUD-Stadtmitte person 9, not 8 and 10, docs/image_border.md) and box accuracy without a failure (CSRT tighter on TUD-Campus 3, 8,
  TUD-Stadtmitte 1, 4).
* **Honesty about the protocol.**  The grid's values are chosen leave-one-clip-out; the
  mechanisms themselves (and the grid's candidate values) were designed while looking at
  failures on these development clips, so these figures are not a test on unseen video.
  Issue #16's own unseen clips are that test.
* **Speed.**  Median CPU time per frame of the shipped setting over all 39 sequences:
  0.49 ms in the 13:40 run (load 2.8 -> 2.6; 0.78 ms with cbwh in
  this one, load 2.7 -> 5.5) and in the run of 10:22 UTC, at load average
  1.9-6.3 on 2 cores (the rest of this bullet is from that run; without the searches: 0.39 ms;
  CSRT 19.5 ms); the slowest held-out sequence (TUD-Stadtmitte person 8, hidden in a group,
  the scan running in most frames) 0.88 ms.  The previous run's 1.84 ms was at load
  6.5-7.5.  The code before (commit 1809775) and after moving the searches to
  `redetection.py`, shipped defaults, the 26 real sequences, timed back to back twice
  (old, new, old, new): median of the per-sequence medians 0.58 / 0.56 / 0.55 / 0.52 ms,
  the same mean centre error (44.4 px) in all four.
* **"Lost".**  A hand-started track never becomes `lost` by time: the tracker passes it an
  unseen time of 0 (`multi_object_tracker.py`), so it stays `occluded` and keeps searching
  until its box has left the image (with the border as an occluder, the whole box; before,
  its centre)."""


LOSO_NOTES = """Notes.
* Development clips: OTB Crossing; OTB Woman (legs hidden by cars, camera pans);
  TUD-Campus and TUD-Stadtmitte persons (each person a sequence; TUD-Stadtmitte also at
  6.25 fps, every 4th frame, 4x the motion per frame); generator scenes at 7 fps with people
  ~30 px wide walking 12-20 px per frame, entering at the image edges (first box a clipped
  sliver), a group of two and a pillar (`fast_edge_scene`, seeds 41, 42); a 25 fps generator
  crowd (seed 11).  Persons with fewer than 10 frames are left out.
* Real sequences run at their stated rate (TUD: `seqinfo.ini` or 25 fps; OTB: 25 fps).
* `num_kernels` is 2 in every setting: the run of 2026-11-25 chose 2 over 6 on every fold.
* The older tables (bare refinement variants, CamShift, MIL, the synthetic occlusion scenes)
  are produced with `--legacy --output FILE`; they are in-sample figures."""


if __name__ == "__main__":
    raise SystemExit(main())
