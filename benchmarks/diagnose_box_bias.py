"""Where the box of a hand-started track sits along the walking direction, and why.

docs/failure_analysis.md ("The 14 losses to CSRT ...") finds the boxes of seven sequences
behind the walker without any failure.  This script splits that offset into its two parts,
the coupling of Chu et al. 2013, Sec. IV-D: the multiple-kernel search (Algorithm 1 from the
Kalman prediction) measures a centre, and the Kalman update (4.4)-(4.5) moves the prediction
towards it with the gain ``K = P / (P + sigma_w^2)`` (per axis, position block of ``P``).

For every frame in which the track is corrected by its search (``Track.correct`` is wrapped;
the tracker itself is not changed) it records the Kalman prior, the kernels' measured centre,
the posterior and the gain on x, and prints per sequence the median signed offset from the
truth's centre along the walking direction (the truth's own centre motion over +-2 frames;
frames where the truth moves less than 0.5 px per frame are left out), in truth box widths
(negative = behind the walker):

* ``prior``: the Kalman prediction that starts Algorithm 1;
* ``kernels``: the search's optimum (the measurement);
* ``reported``: the posterior (the reported box's centre);
* ``similarity peak`` (``--surface``): where the mean kernel similarity of the track's
  models is highest along that direction, around the kernels' box (a colour optimum
  behind the truth vs. a search that stops short of it);
* ``K_x``: the median Kalman gain on x, and ``sigma_w`` the median measurement std (px).

If ``reported`` is behind ``kernels`` the filter lags its own measurement; if ``kernels``
is behind the truth the colour optimum is (or the search stops short of it)::

    nice -n 10 .venv/bin/python benchmarks/diagnose_box_bias.py \\
        --sequences 'Crossing,TUD-Campus person 3,TUD-Campus person 5,TUD-Campus person 8,\
TUD-Stadtmitte person 1,TUD-Stadtmitte person 4,TUD-Stadtmitte person 5' --surface

``--set NAME=VALUE`` changes a setting of the whole tracker (``--set`` of
bench_single_target.py, e.g. ``manual_track.background_weighting=none``).
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from bench_single_target import _names, _selected, development_set  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tracking import track as track_module  # noqa: E402
from mk_tracker.tracking.multi_object_tracker import (MultiObjectTracker,  # noqa: E402
                                                      MultiObjectTrackerConfig)
from setting_values import setting_changes  # noqa: E402


def _centre(box) -> np.ndarray:
    return np.array([box[0] + box[2] / 2.0, box[1] + box[3] / 2.0])


#: shifts of the kernels' box along the walking direction at which the similarity surface
#: is read (box widths)
SHIFTS = np.round(np.arange(-0.4, 0.4001, 0.02), 3)


def record(seq, config: MultiObjectTrackerConfig, surface: bool = False) -> dict[int, dict]:
    """Frame index -> prior, measured and posterior centre, gain on x and sigma_w of the
    hand-started track's corrections by its own search (frames it coasted are absent); with
    ``surface`` also the centre of the highest mean kernel similarity
    (``MultiKernelTracker.appearance_similarity`` with the track's models) among the kernels'
    box moved by :data:`SHIFTS` widths along the truth's walking direction."""
    rows: dict[int, dict] = {}
    frame_no = [0]
    image = [None]
    tracker_ref = [None]
    original = track_module.Track.correct

    def correct(self, box, quality, use_size=True, size_weight=1.0):
        prior = np.array(self.kf.center, dtype=float)
        p = float(self.kf.covariance[0, 0])
        q = min(max(float(quality), 0.0), 1.0) if np.isfinite(quality) else 0.0
        sigma = track_module.measurement_sigma(float(box[3]), q, self.config)
        peak = None
        u = walking_direction(seq.truth, frame_no[0])
        if surface and u is not None:
            refiner = tracker_ref[0].manual_refiner
            b = np.asarray(box, dtype=float)
            sims = []
            for s in SHIFTS:
                moved = b.copy()
                moved[:2] += s * b[2] * u
                sims.append(refiner.appearance_similarity(image[0], self.target, moved))
            peak = _centre(b) + SHIFTS[int(np.argmax(sims))] * b[2] * u
        original(self, box, quality, use_size=use_size, size_weight=size_weight)
        rows[frame_no[0]] = {"peak": peak,"prior": prior, "measured": _centre(box),
                             "posterior": np.array(self.kf.center, dtype=float),
                             "gain": p / (p + sigma * sigma), "sigma": sigma}

    track_module.Track.correct = correct
    try:
        tracker = MultiObjectTracker(config)
        tracker_ref[0] = tracker
        frames = seq.frames()
        first = next(frames)
        image[0] = first
        tracker.start_track(first, 0.0, seq.init_box)
        tracker.step(first, 0.0)
        for i, frame in enumerate(frames, start=1):
            frame_no[0] = i
            image[0] = frame
            tracker.step(frame, i / seq.fps)
    finally:
        track_module.Track.correct = original
    return rows


def walking_direction(truth: list, i: int, half: int = 2, min_px: float = 0.5):
    """Unit vector of the truth's centre motion from frame ``i - half`` to ``i + half``, or
    None when it is shorter than ``min_px`` per frame or a box is missing."""
    a, b = max(0, i - half), min(len(truth) - 1, i + half)
    if b <= a or truth[a] is None or truth[b] is None:
        return None
    d = _centre(truth[b]) - _centre(truth[a])
    n = float(np.linalg.norm(d))
    return None if n < min_px * (b - a) else d / n


def offsets(seq, rows: dict[int, dict]) -> dict[str, list[float]]:
    """Per corrected frame: signed offsets along the walking direction in truth widths."""
    out: dict[str, list[float]] = {"prior": [], "measured": [], "posterior": [], "peak": [],
                                   "gain": [], "sigma": []}
    for i, r in rows.items():
        truth = seq.truth[i] if i < len(seq.truth) else None
        u = walking_direction(seq.truth, i)
        if truth is None or u is None:
            continue
        c, w = _centre(truth), float(truth[2])
        for key in ("prior", "measured", "posterior"):
            out[key].append(float((r[key] - c) @ u) / w)
        if r["peak"] is not None:
            out["peak"].append(float((r["peak"] - c) @ u) / w)
        out["gain"].append(r["gain"])
        out["sigma"].append(r["sigma"])
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sequences", default="", help="substrings of sequence names")
    parser.add_argument("--surface", action="store_true",
                        help="also the peak of the similarity along the walking direction")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="a setting of the tracker, e.g. "
                        "manual_track.background_weighting=none")
    args = parser.parse_args(argv)
    config = updated(MultiObjectTrackerConfig(), setting_changes(args.set))
    print("| sequence | frames used | prior | kernels | reported | similarity peak | K_x | "
          "sigma_w px |")
    print("|---|---|---|---|---|---|---|---|")
    for clip, seq in development_set():
        if clip.startswith("generator") or not _selected(seq.name, _names(args.sequences)):
            continue
        frames = list(seq.frames())
        seq = replace(seq, frames=lambda: iter(frames))
        o = offsets(seq, record(seq, config, surface=args.surface))
        if not o["gain"]:
            print(f"| {seq.name} | 0 | | | | | | |")
            continue
        med = {k: float(np.median(v)) if v else float("nan") for k, v in o.items()}
        print(f"| {seq.name} | {len(o['gain'])} | {med['prior']:+.3f} | {med['measured']:+.3f} | "
              f"{med['posterior']:+.3f} | {med['peak']:+.3f} | {med['gain']:.2f} | "
              f"{med['sigma']:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
