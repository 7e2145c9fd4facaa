"""What ``mk_tracker process`` leaves after a run: scores against the ground truth, and files.

* :func:`write_outputs` -- after the run: ``tracks.txt`` (MOTChallenge), ``gt.txt`` when the
  bag has ground truth, the scores (CLEAR MOT, identity scores and HOTA; or, for a single target,
  the centre error and overlap of Chu et al. 2013 Table I, with ``target.txt`` /
  ``target_gt.txt`` box lists), ``errors.png`` and ``summary.json``.
* :func:`format_metrics` -- the scores on one line (ratios as percentages).

The run itself (and the tracks bag and the video, written while it goes) is
:mod:`mk_tracker.tools.pipeline`; the metrics are :mod:`mk_tracker.evaluation.metrics`.
:func:`format_metrics` stays importable from :mod:`mk_tracker.tools.pipeline`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

from mk_tracker.evaluation.hota import hota
from mk_tracker.evaluation.metrics import (center_errors, mot_accumulator, mot_metrics, overlaps,
                                           single_target_metrics, write_mot_file)

if TYPE_CHECKING:
    from mk_tracker.tools.pipeline import PipelineOptions, PipelineResult


def write_outputs(result: PipelineResult, bag: Path, out: Path, options: PipelineOptions,
                  has_truth: bool) -> None:
    """Score ``result`` and write its files into ``out`` (listed in ``result.files``)."""
    from mk_tracker.evaluation.error_plots import (ErrorPlotError, mot_frame_errors,
                                                   plot_mot_errors, plot_single_target_errors)

    r, opts = result, options
    write_mot_file(out / "tracks.txt", r.mot_rows)
    r.files["tracks"] = str(out / "tracks.txt")
    if opts.write_bag:
        r.files["bag"] = str(out / "bag")
    if opts.write_video and r.video_frames:
        r.files["video"] = str(out / "video.mp4")
    if has_truth and r.frames:
        # the ground truth as a MOTChallenge file: ``mk_tracker eval --gt gt.txt tracks.txt``
        # scores any result of this bag the same way
        write_mot_file(out / "gt.txt", r.gt_rows)
        r.files["ground_truth"] = str(out / "gt.txt")
        if opts.single_target:
            tid, gid = r.single_target_id, r.single_target_gt_id
            predicted = [None] * r.frames
            for row in r.mot_rows:
                if row.id == tid:
                    predicted[row.frame - 1] = row.box
            truth = [None] * r.frames
            for row in r.gt_rows:
                if row.id == gid:
                    truth[row.frame - 1] = row.box
            if gid is not None and any(b is not None for b in truth):
                # OTB-style box lists for ``mk_tracker eval --single-target``
                _write_box_list(out / "target.txt", predicted)
                _write_box_list(out / "target_gt.txt", truth)
                r.files["target"] = str(out / "target.txt")
                r.files["target_ground_truth"] = str(out / "target_gt.txt")
                r.metrics = single_target_metrics(predicted, truth)
                r.metrics["target_id"], r.metrics["ground_truth_id"] = tid, gid
                if opts.write_plots:
                    plot_single_target_errors(center_errors(predicted, truth),
                                              overlaps(predicted, truth),
                                              out / "errors.png",
                                              title=f"{bag.name}: target {gid}")
                    r.files["plot"] = str(out / "errors.png")
        else:
            frames = list(range(1, r.frames + 1))
            r.metrics = {**mot_metrics(r.gt_rows, r.mot_rows), **hota(r.gt_rows, r.mot_rows)}
            if opts.write_plots:
                acc = mot_accumulator(r.gt_rows, r.mot_rows, frames=frames)
                try:
                    plot_mot_errors(mot_frame_errors(acc), out / "errors.png",
                                    title=f"{bag.name}: per-frame errors")
                    r.files["plot"] = str(out / "errors.png")
                except ErrorPlotError as exc:
                    r.problem(f"no error plot: {exc}")
    summary = {
        "bag": str(bag), "detection_source": r.detection_source,
        "tracker_profile": r.tracker_profile, "thermal_only": r.thermal_only,
        "frames": r.frames, "tracked_frames": r.tracked_frames, "bad_frames": r.bad_frames,
        "bad_messages": r.bad_messages, "problems": r.problems,
        "detector_events": r.detector_events,
        "detections": r.detections, "detection_frames": r.detection_frames,
        "rejected_detector_frames": r.rejected_detector_frames,
        "unknown_frame_batches": r.unknown_frame_batches,
        "tracks": len(r.track_ids), "video_frames": r.video_frames,
        "seconds": round(r.seconds, 3),
        "frames_per_second": round(r.frames / r.seconds, 2) if r.seconds > 0 else None,
        "homography": list(r.homography), "metrics": r.metrics, "files": r.files,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    r.files["summary"] = str(out / "summary.json")


def _write_box_list(path: Path, boxes: Sequence[Sequence[float] | None]) -> None:
    """One ``x,y,w,h`` line per frame (``nan,nan,nan,nan`` without a box), the OTB layout
    :func:`mk_tracker.evaluation.metrics.read_box_list` reads."""
    lines = ["nan,nan,nan,nan" if b is None else ",".join(f"{float(v):.2f}" for v in b)
             for b in boxes]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def format_metrics(metrics: Mapping[str, Any]) -> str:
    """One line of scores (ratios as percentages)."""
    parts = []
    for k, v in metrics.items():
        if isinstance(v, float) and k in ("mota", "motp", "idf1", "idp", "idr", "precision",
                                          "recall", "precision_at_20px", "success_auc",
                                          "hota", "deta", "assa"):
            parts.append(f"{k} {100 * v:.1f}%")
        elif isinstance(v, float):
            parts.append(f"{k} {v:.2f}")
        else:
            parts.append(f"{k} {v}")
    return ", ".join(parts)
