"""Automatic gain control (issue #19): the thermal detector and the pipeline when an 8-bit
LWIR camera changes its gain and offset, on the real clip and on generated crowds.

    nice -n 10 .venv/bin/python benchmarks/bench_thermal_gain.py \
        --models off affine --out docs/benchmark_thermal_gain.md

Uncooled LWIR cameras with 8-bit output run automatic gain control: the whole image's
brightness and contrast move when something hot or cold enters, slowly or in jumps.  The
kernel covariance (3.5) of Schizas et al. sees such a change as temporal change of every
pixel.  The perturbations applied to every thermal frame ``x`` (uint8, frame ``k`` of
``n``, ``t = k / (n - 1)``), each result rounded and clipped to [0, 255]:

* ``drift``: ``g(t) x + o(t)``, the gain linear 1.0 -> 0.8 (t = 1/2) -> 1.1 (t = 1), the
  offset ``20 sin(2 pi t)`` grey levels;
* ``steps``: gain x0.85 and offset +15 from t ~ 1/4 to 1/2 and from t ~ 3/4 on, as AGC
  reacts when something hot enters the view and leaves it (each switch two frames before
  a full-frame pass of the detector, :func:`step_frames`);
* ``jumps``: as ``steps`` with gain x0.7 and offset +40 (a larger AGC jump);
* ``gamma``: ``255 (x / 255)^gamma(t)``, gamma linear 1.0 -> 1.4 (t = 1/2) -> 0.8 (t = 1),
  a brightness-dependent change no affine map undoes;
* ``constant``: gain 0.93 in every frame, no temporal change at all: a control that shows
  how far the figures move without any AGC event (BU-TIV-lab's figures switch between two
  regimes on such a change, see docs/benchmark_thermal_gain.md).

Two sources:

* BU-TIV-lab (../shared/data/thermal, 562 frames, 512x512; no ground truth), imported and
  processed thermal-only with the burned-in counter masked, as benchmarks/bench_real_thermal.py
  does (its helpers are imported): detections / frame, detections larger than half the frame
  (count), tracks / frame, distinct ids (~7 people), duplicate pairs (IoU > 0.5) / frame, the
  detector's gain resets and its median CPU ms / frame;
* generated crowds (held-out seeds, 640x480), the pipeline of benchmarks/bench_groups.py:
  the detector's recall / precision (centroid rule and IoU 0.5, warm-up frames not scored),
  its gain resets, and the pipeline's MOTA / IDF1 against the RGB ground truth.

``--models`` names the detector's ``gain.model`` settings to compare (``default``: the
package's config as it is).  Not a test: nothing is asserted.
"""

from __future__ import annotations

import argparse
import math
import platform
import shlex
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_groups import iou_matches  # noqa: E402
from bench_real_thermal import COUNTER_REGION, DEFAULT_CLIP, run_pipeline  # noqa: E402
from bench_thermal_detector import match_frame  # noqa: E402

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.bag_writer import BagWriter  # noqa: E402
from mk_tracker.bags.recording_import import import_recording, open_recording  # noqa: E402
from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402
from mk_tracker.evaluation.identity_figures import identity_figures  # noqa: E402
from mk_tracker.frame_processing import build_detector  # noqa: E402
from mk_tracker.messages.image_conversion import image_to_numpy, numpy_to_image  # noqa: E402
from mk_tracker.messages.message_types import bag_message_types  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402

THERMAL_TOPIC = "/thermal/image_raw"
PERTURBATIONS = ("none", "drift", "steps", "jumps", "gamma", "constant")


def _ramp(t: float, start: float, middle: float, end: float) -> float:
    """Piecewise linear: ``start`` at t = 0, ``middle`` at t = 1/2, ``end`` at t = 1."""
    if t <= 0.5:
        return start + (middle - start) * 2.0 * t
    return middle + (end - middle) * (2.0 * t - 1.0)


def step_frames(n: int) -> tuple[int, int, int]:
    """The frames near t = 1/4, 1/2, 3/4 at which ``steps`` and ``jumps`` switch: two frames
    before a full-frame pass of the default detector (F_s = 6, T_c = 25: passes at frames
    5, 30, 55, ...), the worst case; a step long before a full pass is seen only in the
    (5.2) windows of the tracked objects, for F frames."""
    return tuple(25 * round(f * (n - 1) / 25.0) + 3 for f in (0.25, 0.5, 0.75))


def perturbed(frame: np.ndarray, k: int, n: int, kind: str, gain: float = 0.93
              ) -> np.ndarray:
    """Frame ``k`` of ``n`` (uint8) as a camera whose AGC does ``kind`` would deliver it
    (``gain``: the factor of ``constant``)."""
    if kind == "none":
        return frame
    t = k / max(n - 1, 1)
    x = frame.astype(np.float64)
    if kind == "drift":
        y = _ramp(t, 1.0, 0.8, 1.1) * x + 20.0 * math.sin(2.0 * math.pi * t)
    elif kind in ("steps", "jumps"):
        a, b, c = step_frames(n)
        stepped = a <= k < b or k >= c
        y = (0.85 * x + 15.0 if kind == "steps" else 0.7 * x + 40.0) if stepped else x
    elif kind == "constant":
        y = gain * x
    elif kind == "gamma":
        y = 255.0 * (x / 255.0) ** _ramp(t, 1.0, 1.4, 0.8)
    else:
        raise ValueError(f"unknown perturbation {kind!r}")
    return np.clip(np.rint(y), 0, 255).astype(np.uint8)


def perturbed_bag(src: Path, dst: Path, kind: str, gain: float = 0.93) -> None:
    """A copy of ``src`` whose thermal images went through :func:`perturbed`."""
    with open_bag(src) as reader:
        n = sum(1 for _ in reader.messages([THERMAL_TOPIC]))
    with open_bag(src) as reader, BagWriter(dst, typestore=reader.typestore) as writer:
        types = bag_message_types(reader.typestore)
        k = 0
        for m in reader.messages():
            writer.add_topic(m.topic, m.msgtype)
            if m.topic != THERMAL_TOPIC:
                writer.write_raw(m.topic, m.timestamp_ns, m.data)
                continue
            msg = reader.deserialize(m)
            frame = perturbed(image_to_numpy(msg), k, n, kind, gain)
            writer.write(m.topic, m.timestamp_ns,
                         numpy_to_image(frame, msg.encoding, msg.header, types=types))
            k += 1


def model_params(tmp: Path, model: str) -> tuple[Path, ...]:
    """Parameter files that set ``detector.gain.model`` (none for ``default``)."""
    if model == "default":
        return ()
    path = tmp / f"gain_{model}.yaml"
    path.write_text("detector_node:\n  ros__parameters:\n    detector:\n      gain:\n"
                    f"        model: \"{model}\"\n", encoding="utf-8")
    return (path,)


class ChangedPixels:
    """The largest fraction of pixels whose value, as the detector stores it (after any
    compensation), moved by more than the similarity radius of (3.6) (30 grey levels of a
    mono8 frame) from one frame to the next: how much of the frame (3.5) sees as change."""

    def __init__(self) -> None:
        self.previous: np.ndarray | None = None
        self.largest = 0.0

    def update(self, detector) -> None:
        inner = getattr(detector, "detector", detector)      # an ignore-region wrapper
        if not len(inner._window):
            self.previous = None
            return
        stored = inner._newest()
        if self.previous is not None and stored.shape == self.previous.shape:
            moved = np.abs(stored - self.previous) > 30.0
            self.largest = max(self.largest, float(np.count_nonzero(moved)) / moved.size)
        self.previous = stored.copy()


def detector_alone(bag: Path, regions: tuple, extra: tuple) -> tuple[float, int, int, float]:
    """``(median CPU ms / frame, gain resets, detections larger than half the frame, largest
    fraction of changed pixels)`` of the configured detector over ``bag``'s thermal frames
    (the last one measured in a second pass, outside the timing)."""
    cfg = load_pipeline_config(list(extra))
    out = []
    for timed in (True, False):
        det = build_detector(cfg.method, cfg.detector, cfg.threshold, regions)
        times, large, changed = [], 0, ChangedPixels()
        with open_bag(bag) as reader:
            for m in reader.messages([THERMAL_TOPIC]):
                msg = reader.deserialize(m)
                frame = image_to_numpy(msg)
                t0 = time.thread_time()
                found = det.process(frame, m.timestamp_ns * 1e-9, encoding=msg.encoding)
                times.append(time.thread_time() - t0)
                if timed:
                    continue
                changed.update(det)
                half = 0.5 * frame.shape[0] * frame.shape[1]
                large += sum(1 for d in found if d.box[2] * d.box[3] > half)
        out.append((times, large, changed.largest, int(getattr(det, "gain_resets", 0))))
    times = out[0][0]
    _, large, changed, resets = out[1]
    return 1000.0 * float(np.median(times[10:] or times)), resets, large, changed


def control_rows(bag: Path, gains: list[float], extra: tuple = (), tmp: Path | None = None
                 ) -> list[tuple]:
    """The detector alone (counter masked; defaults, then the ``extra`` parameter files) on
    BU-TIV-lab with a constant gain ``g`` (``rint(g x)`` clipped to [0, 255], no temporal
    change at all): ``(g, detections / frame, detections larger than half the frame)``,
    and with ``tmp`` the pipeline's ``tracks / frame, distinct ids, duplicate pairs /
    frame`` on a bag of those frames."""
    cfg = load_pipeline_config(list(extra))
    with open_bag(bag) as reader:
        frames = [(m.timestamp_ns * 1e-9, image_to_numpy(reader.deserialize(m)))
                  for m in reader.messages([THERMAL_TOPIC])]
    rows = []
    for g in gains:
        det = build_detector(cfg.method, cfg.detector, cfg.threshold, COUNTER_REGION)
        count = large = 0
        for stamp, frame in frames:
            scaled = np.clip(np.rint(g * frame.astype(np.float64)), 0, 255).astype(np.uint8)
            found = det.process(scaled, stamp)
            count += len(found)
            large += sum(1 for d in found if d.box[2] * d.box[3] > 0.5 * frame.size)
        row = (g, count / max(len(frames), 1), large)
        if tmp is not None:
            src = tmp / f"butiv_gain_{g:.3f}"
            perturbed_bag(bag, src, "constant", g)
            tracks, dets, _ = run_pipeline(src, tmp / f"run_butiv_gain_{g:.3f}",
                                           COUNTER_REGION, extra)
            f = identity_figures(tracks, dets)
            row += (f["tracks"], f["ids"], f["duplicates"])
        rows.append(row)
        print(rows[-1], file=sys.stderr, flush=True)
    return rows


def real_rows(args, tmp: Path) -> list[tuple]:
    source = open_recording(args.clip, None)
    bag = tmp / "butiv"
    import_recording(source, bag, thermal=True)
    if args.constant_gains:
        args.controls = control_rows(bag, args.constant_gains, tuple(args.params),
                                     tmp if args.control_pipeline else None)
    rows = []
    for kind in args.perturbations:
        src = bag
        if kind != "none":
            src = tmp / f"butiv_{kind}"
            perturbed_bag(bag, src, kind)
        for model in args.models:
            extra = model_params(tmp, model)
            tracks, dets, _ = run_pipeline(src, tmp / f"run_butiv_{kind}_{model}",
                                           COUNTER_REGION, extra)
            f = identity_figures(tracks, dets)
            ms, resets, large, changed = detector_alone(src, COUNTER_REGION, extra)
            rows.append((kind, model, f["detections"], large, changed, f["tracks"], f["ids"],
                         f["duplicates"], resets, ms))
            print(rows[-1], file=sys.stderr, flush=True)
    return rows


class _PerturbedScene:
    """A generated scene whose thermal frames go through :func:`perturbed`."""

    def __init__(self, scene, kind: str) -> None:
        self.scene, self.kind = scene, kind

    def __len__(self) -> int:
        return len(self.scene)

    def frame(self, i: int):
        fr = self.scene.frame(i)
        return replace(fr, thermal=perturbed(fr.thermal, i, len(self.scene), self.kind))


def detector_scores(scene, config) -> tuple[float, float, float, float, int, float]:
    """Recall / precision (centroid rule, IoU 0.5) of the detector alone, as
    bench_groups.detector_pass scores them, its gain resets and the largest fraction of
    changed pixels (:class:`ChangedPixels`)."""
    detector = ThermalDetector(config)
    counts = np.zeros(6)
    changed = ChangedPixels()
    for i in range(len(scene)):
        fr = scene.frame(i)
        dets = detector.process(fr.thermal, fr.stamp)
        changed.update(detector)
        if detector.last_mode == "warming_up":
            continue
        counts += (*match_frame(dets, fr.objects)[:3], *iou_matches(dets, fr.objects))
    tp, fp, fn, itp, ifp, ifn = counts
    return (tp / max(tp + fn, 1), tp / max(tp + fp, 1), itp / max(itp + ifn, 1),
            itp / max(itp + ifp, 1), int(getattr(detector, "gain_resets", 0)), changed.largest)


def generated_rows(args, tmp: Path) -> list[tuple]:
    width, height = (int(v) for v in args.size.split("x"))
    rows = []
    for people in args.people:
        for seed in args.seeds:
            scene = build_preset("crowd", seed=seed, people=people, frames=args.frames,
                                 width=width, height=height)
            bag = tmp / f"scene_{people}_{seed}"
            write_scene_bag(scene, bag, preset="crowd")
            for kind in args.perturbations:
                src = bag
                if kind != "none":
                    src = tmp / f"scene_{people}_{seed}_{kind}"
                    perturbed_bag(bag, src, kind)
                for model in args.models:
                    config = load_pipeline_config(list(model_params(tmp, model)))
                    scores = detector_scores(_PerturbedScene(scene, kind), config.detector)
                    result = process_bag(src, tmp / f"run_{people}_{seed}_{kind}_{model}",
                                         config, PipelineOptions(progress=False,
                                                                 write_video=False,
                                                                 write_plots=False,
                                                                 write_bag=False))
                    m = result.metrics
                    rows.append((people, seed, kind, model, *scores, m["mota"], m["idf1"]))
                    print(rows[-1], file=sys.stderr, flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--models", nargs="+", default=["default"],
                        help="detector gain.model settings to compare (default: the config)")
    parser.add_argument("--perturbations", nargs="*", default=list(PERTURBATIONS),
                        choices=PERTURBATIONS)
    parser.add_argument("--people", type=int, nargs="+", default=[8, 15])
    parser.add_argument("--seeds", type=int, nargs="+", default=[201, 202])
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--no-real", dest="real", action="store_false")
    parser.add_argument("--no-generated", dest="generated", action="store_false")
    parser.add_argument("--constant-gains", type=float, nargs="*", default=[],
                        help="also run the default detector alone on BU-TIV-lab at these "
                             "constant gains (a control: no temporal change)")
    parser.add_argument("--control-pipeline", action="store_true",
                        help="the constant-gain rows also run the pipeline (tracks / frame, "
                             "ids, duplicate pairs)")
    parser.add_argument("--params", type=Path, nargs="*", default=[],
                        help="parameter files for the constant-gain rows")
    parser.add_argument("--out", type=Path, default=None, help="markdown report to write")
    args = parser.parse_args(argv)
    args.controls = []
    real, generated = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.real:
            if args.clip.exists():
                real = real_rows(args, tmp)
            else:
                print(f"{args.clip} not found: the real clip is left out", file=sys.stderr)
        if args.generated:
            generated = generated_rows(args, tmp)
    lines = []
    if real:
        lines += ["| BU-TIV-lab AGC | gain.model | detections / frame | detections > half "
                  "the frame | most pixels changed > 30 levels | tracks / frame | distinct "
                  "ids (~7) | duplicate pairs / frame | gain resets | detector CPU ms / frame |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        lines += [f"| {k} | {m} | {d:.2f} | {big} | {100 * ch:.0f} % | {t:.2f} | {ids} | "
                  f"{dup:.2f} | {r} | {ms:.1f} |"
                  for k, m, d, big, ch, t, ids, dup, r, ms in real]
        lines.append("")
    if args.controls:
        pipe = len(args.controls[0]) > 3
        lines += ["| BU-TIV-lab, constant gain (no AGC event), gain.model off | detections / "
                  "frame | detections > half the frame |"
                  + (" tracks / frame | distinct ids (~7) | duplicate pairs / frame |"
                     if pipe else ""), "|---:|---:|---:|" + ("---:|---:|---:|" if pipe else "")]
        lines += [f"| {r[0]:.2f} | {r[1]:.2f} | {r[2]} |"
                  + (f" {r[3]:.2f} | {r[4]} | {r[5]:.2f} |" if pipe else "")
                  for r in args.controls]
        lines.append("")
    if generated:
        lines += ["| people | seed | AGC | gain.model | det. recall / precision (centroid) | "
                  "det. recall / precision (IoU 0.5) | most pixels changed > 30 levels | gain "
                  "resets | MOTA | IDF1 |",
                  "|---:|---:|---|---|---:|---:|---:|---:|---:|---:|"]
        lines += [f"| {p} | {s} | {k} | {m} | {r:.2f} / {pr:.2f} | {ir:.2f} / {ipr:.2f} | "
                  f"{100 * ch:.0f} % | {g} | {mota:.3f} | {idf1:.3f} |"
                  for p, s, k, m, r, pr, ir, ipr, g, ch, mota, idf1 in generated]
    table = "\n".join(lines)
    print(table)
    if args.out is not None:
        command = ("nice -n 10 .venv/bin/python benchmarks/bench_thermal_gain.py "
                   + shlex.join(argv if argv is not None else sys.argv[1:]))
        args.out.write_text(
            f"# Automatic gain control (issue #19)\n\nProduced by:\n\n```\n{command}\n```\n\n"
            f"Machine: {platform.machine()}, Python {platform.python_version()}.  "
            "Perturbations and columns: the docstring of benchmarks/bench_thermal_gain.py.\n\n"
            f"{table}\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
