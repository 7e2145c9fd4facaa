"""Per-frame error plots of a tracking run (matplotlib, Agg backend: no display needed).

* :func:`mot_frame_errors` turns a ``motmetrics`` accumulator
  (:func:`mk_tracker.evaluation.metrics.mot_accumulator`) into per-frame counts of ground-truth
  objects, matches, misses, false positives and identity switches, and the mean IoU of the
  matches (motmetrics stores the distance ``1 - IoU``);
* :func:`plot_mot_errors` draws them (the frames where a CLEAR-MOT error happens);
* :func:`plot_single_target_errors` draws the centre-location error and the overlap per
  frame (OTB protocol of Chu et al. 2013, Sec. V; scores by :mod:`mk_tracker.evaluation.metrics`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np


class ErrorPlotError(ValueError):
    """Nothing to plot, or inputs of different lengths."""


@dataclass
class MotFrameErrors:
    """Per-frame CLEAR-MOT event counts, aligned on ``frames``."""

    frames: np.ndarray
    objects: np.ndarray
    matches: np.ndarray
    misses: np.ndarray
    false_positives: np.ndarray
    switches: np.ndarray
    mean_iou: np.ndarray = field(default_factory=lambda: np.zeros(0))


def mot_frame_errors(accumulator: object) -> MotFrameErrors:
    """Per-frame counts from a filled ``motmetrics.MOTAccumulator``."""
    events = accumulator.mot_events  # DataFrame indexed by (FrameId, Event)
    if len(events) == 0:
        raise ErrorPlotError("the accumulator holds no frame")
    frame_ids = events.index.get_level_values(0).to_numpy()
    types = events["Type"].to_numpy()
    dist = events["D"].to_numpy(dtype=float)
    frames = np.unique(frame_ids)
    pos = {f: i for i, f in enumerate(frames)}
    n = len(frames)
    counts = {k: np.zeros(n, dtype=int) for k in ("MATCH", "SWITCH", "MISS", "FP")}
    iou_sum = np.zeros(n)
    for f, t, d in zip(frame_ids, types, dist):
        if t in counts:
            counts[t][pos[f]] += 1
        if t in ("MATCH", "SWITCH") and np.isfinite(d):
            iou_sum[pos[f]] += 1.0 - d
    matched = counts["MATCH"] + counts["SWITCH"]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_iou = np.where(matched > 0, iou_sum / np.maximum(matched, 1), np.nan)
    return MotFrameErrors(frames=frames.astype(int), objects=matched + counts["MISS"],
                          matches=matched, misses=counts["MISS"],
                          false_positives=counts["FP"], switches=counts["SWITCH"],
                          mean_iou=mean_iou)


def _pyplot():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def _save(fig, overlap_axis, ylabel: str, xlabel: str, title: str, path: str | Path) -> Path:
    """Both plots end alike: an overlap panel on [0, 1] at the bottom, the title, a PNG."""
    overlap_axis.set_ylim(0.0, 1.0)
    overlap_axis.set_ylabel(ylabel)
    overlap_axis.set_xlabel(xlabel)
    fig.suptitle(title)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=90)
    return out


def plot_mot_errors(errors: MotFrameErrors, path: str | Path, title: str = "") -> Path:
    """A PNG with per-frame objects/matches, errors (misses, FP, ID switches) and mean IoU."""
    plt = _pyplot()
    f = errors.frames
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    try:
        axes[0].step(f, errors.objects, where="mid", label="ground-truth objects")
        axes[0].step(f, errors.matches, where="mid", label="matched")
        axes[0].set_ylabel("count")
        axes[0].legend(loc="upper right", fontsize=8)
        axes[1].step(f, errors.misses, where="mid", label="misses", color="tab:red")
        axes[1].step(f, errors.false_positives, where="mid", label="false positives",
                     color="tab:orange")
        sw = errors.switches > 0
        axes[1].plot(f[sw], errors.switches[sw], "kx", label="ID switches")
        axes[1].set_ylabel("errors")
        axes[1].legend(loc="upper right", fontsize=8)
        axes[2].plot(f, errors.mean_iou, ".-", ms=3)
        return _save(fig, axes[2], "mean IoU of matches", "frame",
                     title or "per-frame tracking errors", path)
    finally:
        plt.close(fig)


def plot_single_target_errors(center_errors: Sequence[float], ious: Sequence[float],
                              path: str | Path, title: str = "",
                              threshold: float = 20.0) -> Path:
    """A PNG with the per-frame centre error (px, inf = no box drawn at the top) and IoU."""
    e = np.asarray(center_errors, dtype=float)
    o = np.asarray(ious, dtype=float)
    if e.size == 0 or e.shape != o.shape:
        raise ErrorPlotError(f"need equally long non-empty error and IoU sequences, got "
                             f"{e.size} and {o.size}")
    plt = _pyplot()
    frames = np.arange(1, e.size + 1)
    finite = np.isfinite(e)
    top = max(float(e[finite].max()) if finite.any() else threshold, threshold) * 1.1
    fig, axes = plt.subplots(2, 1, figsize=(9, 5), sharex=True)
    try:
        axes[0].plot(frames[finite], e[finite], ".-", ms=3, label="centre error")
        if (~finite).any():
            axes[0].plot(frames[~finite], np.full((~finite).sum(), top), "rx", label="no box")
        axes[0].axhline(threshold, color="gray", ls="--", lw=1, label=f"{threshold:g} px")
        axes[0].set_ylabel("centre error (px)")
        axes[0].legend(loc="upper right", fontsize=8)
        axes[1].plot(frames, o, ".-", ms=3)
        axes[1].axhline(0.5, color="gray", ls="--", lw=1)
        return _save(fig, axes[1], "IoU", "frame (with ground truth)",
                     title or "single-target errors per frame", path)
    finally:
        plt.close(fig)
