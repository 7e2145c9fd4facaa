"""Scoring of tracking results.

Multi-object: the CLEAR-MOT metrics (MOTA, MOTP, false positives, misses, ID switches,
fragmentations) and the identity metrics (IDF1, IDP, IDR), plus mostly tracked / partially
tracked / mostly lost, computed with the ``motmetrics`` package from MOTChallenge text files.
A ground-truth box and a hypothesis box can match when their IoU is at least 0.5 (the
MOTChallenge convention); the distance given to motmetrics is ``1 - IoU``.  The IoU matrix is
:func:`mk_tracker.boxes.iou_matrix` (motmetrics 1.4.0's own ``iou_matrix`` calls
``np.asfarray``, removed in NumPy 2).

Single-target (OTB protocol, as in Chu et al. 2013 Sec. IV): the centre location error per
frame, the precision at 20 px (fraction of frames with error <= 20 px), and the success curve
(fraction of frames with IoU above each threshold in [0, 1]) with its area under the curve.
Frames with no prediction count as failures (infinite error, zero overlap); frames without a
valid ground-truth box are left out.

MOTChallenge text format, one line per box: ``frame,id,x,y,w,h,conf,x3d,y3d,z3d`` with 1-based
frames and a top-left box in pixels.  Ground-truth files of MOT16 and later have
``frame,id,x,y,w,h,consider,class,visibility``: rows with ``consider == 0`` or a class other
than 1 (pedestrian) are dropped.  :mod:`mk_tracker.bags.datasets` reads sequence folders with the
parsers of this module (:func:`parse_mot_lines`, :func:`parse_box_lines`), so a file means
the same to the dataset readers and to the scoring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Iterator, Mapping, Sequence

import numpy as np

from mk_tracker.boxes import iou_matrix


class EvaluationError(ValueError):
    """A result or ground-truth file that cannot be read, or inputs that do not fit."""


#: Metrics reported by :func:`mot_metrics`, motmetrics names.
MOT_METRICS = ("mota", "motp", "idf1", "idp", "idr", "precision", "recall",
               "num_switches", "num_fragmentations", "num_false_positives", "num_misses",
               "mostly_tracked", "partially_tracked", "mostly_lost", "num_unique_objects",
               "num_frames")


@dataclass(frozen=True)
class MotRow:
    """One box of a MOTChallenge file."""

    frame: int
    id: int
    box: tuple[float, float, float, float]
    score: float = 1.0
    #: 1-based line of the file it was read from (0 when not read from a file); not compared
    line: int = field(default=0, compare=False, repr=False)


# -- text files of numbers ----------------------------------------------------------------

def read_text_lines(path: str | Path) -> list[str]:
    """The lines of a text file; :class:`EvaluationError` for a missing, unreadable or
    binary file."""
    p = Path(path)
    if not p.is_file():
        raise EvaluationError(f"{p}: no such file")
    try:
        return p.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError as exc:
        raise EvaluationError(f"{p}: not a text file ({exc})") from None
    except OSError as exc:
        raise EvaluationError(f"{p}: cannot read ({exc.strerror})") from None


def numeric_lines(lines: Iterable[str], minimum: int, source: str = "<text>",
                  what: str = "") -> Iterator[tuple[int, list[float]]]:
    """``(line number, values)`` of every line that is not blank or a ``#`` comment; values
    are separated by commas and/or whitespace.  :class:`EvaluationError` naming the line
    when it has fewer than ``minimum`` values or one is not a number."""
    for n, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.replace(",", " ").split()
        if len(parts) < minimum:
            raise EvaluationError(f"{source}:{n}: expected at least {minimum} values{what}, "
                                  f"got {len(parts)}: {line!r}")
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise EvaluationError(f"{source}:{n}: not a number in {line!r}") from None
        yield n, values


def _integer(source: str, n: int, name: str, value: float) -> int:
    if not math.isfinite(value) or value != int(value):
        raise EvaluationError(f"{source}:{n}: {name} {value:g} is not an integer")
    return int(value)


# -- MOTChallenge files -------------------------------------------------------------------

def parse_mot_lines(lines: Iterable[str], *, ground_truth: bool = False,
                    source: str = "<text>", require_score: bool = False) -> list[MotRow]:
    """Parse MOTChallenge lines (comma- or whitespace-separated); blank and ``#`` lines are
    skipped.  Each row keeps its line number (:attr:`MotRow.line`).

    With ``ground_truth``, rows with 7 or more columns whose 7th column ("consider") is 0
    are dropped, and with exactly 9 columns (MOT16+) so are classes other than 1.  A
    non-finite 7th column reads as score 1, unless ``require_score`` (public detections,
    ``det.txt``), which needs a finite score in it.  Raises :class:`EvaluationError` naming
    the line for anything unparsable: too few values, not a number, a frame or id that is
    not an integer, a box that is not finite with a positive size.
    """
    minimum = 7 if require_score else 6
    what = " (frame,id,x,y,w,h,score)" if require_score else " (frame,id,x,y,w,h)"
    rows: list[MotRow] = []
    for n, values in numeric_lines(lines, minimum, source, what):
        frame = _integer(source, n, "frame", values[0])
        ident = _integer(source, n, "identity", values[1])
        if ground_truth and len(values) >= 7 and values[6] == 0:
            continue                    # MOT16+ "ignore" row
        if ground_truth and len(values) == 9 and int(values[7]) != 1:
            continue                    # MOT16+ class other than pedestrian
        x, y, w, h = values[2:6]
        if not all(math.isfinite(v) for v in (x, y, w, h)) or w <= 0 or h <= 0:
            raise EvaluationError(f"{source}:{n}: invalid box {(x, y, w, h)} (needs finite "
                                  "values and positive size)")
        if require_score and not math.isfinite(values[6]):
            raise EvaluationError(f"{source}:{n}: score {values[6]} is not finite")
        score = values[6] if len(values) > 6 and math.isfinite(values[6]) else 1.0
        rows.append(MotRow(frame=frame, id=ident, box=(x, y, w, h), score=score, line=n))
    return rows


def read_mot_file(path: str | Path, *, ground_truth: bool = False,
                  require_score: bool = False) -> list[MotRow]:
    """Read a MOTChallenge result, ground-truth or detection file (see
    :func:`parse_mot_lines`)."""
    return parse_mot_lines(read_text_lines(path), ground_truth=ground_truth,
                           source=str(Path(path)), require_score=require_score)


def format_mot_row(row: MotRow) -> str:
    x, y, w, h = row.box
    return f"{row.frame},{row.id},{x:.2f},{y:.2f},{w:.2f},{h:.2f},{row.score:.4f},-1,-1,-1"


def write_mot_file(path: str | Path, rows: Iterable[MotRow]) -> int:
    """Write rows sorted by frame then id; returns the number of lines written."""
    ordered = sorted(rows, key=lambda r: (r.frame, r.id))
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with p.open("w", encoding="utf-8") as fh:
        for r in ordered:
            fh.write(format_mot_row(r) + "\n")
    return len(ordered)


def group_by_frame(rows: Iterable[MotRow]) -> dict[int, list[MotRow]]:
    out: dict[int, list[MotRow]] = {}
    for r in rows:
        out.setdefault(r.frame, []).append(r)
    return out


# -- CLEAR-MOT and identity metrics --------------------------------------------------------

def mot_accumulator(gt: Iterable[MotRow], hyp: Iterable[MotRow], *,
                    iou_threshold: float = 0.5, frames: Sequence[int] | None = None):
    """A ``motmetrics.MOTAccumulator`` filled frame by frame.

    ``frames`` defaults to every frame that appears in ``gt`` or ``hyp``.  A hypothesis id
    repeated within one frame is an error (it would corrupt the identity metrics).
    """
    import motmetrics as mm

    if not 0.0 < iou_threshold <= 1.0:
        raise EvaluationError(f"iou_threshold must be in (0, 1], got {iou_threshold}")
    gt_by = group_by_frame(gt)
    hyp_by = group_by_frame(hyp)
    for f, rows in hyp_by.items():
        ids = [r.id for r in rows]
        if len(ids) != len(set(ids)):
            raise EvaluationError(f"frame {f}: a hypothesis id occurs twice")
    all_frames = sorted(set(gt_by) | set(hyp_by)) if frames is None else list(frames)
    acc = mm.MOTAccumulator(auto_id=False)
    max_distance = 1.0 - iou_threshold
    for f in all_frames:
        g = gt_by.get(f, [])
        h = hyp_by.get(f, [])
        gb = np.array([r.box for r in g], dtype=np.float64).reshape(-1, 4)
        hb = np.array([r.box for r in h], dtype=np.float64).reshape(-1, 4)
        dist = 1.0 - iou_matrix(gb, hb)
        dist[dist > max_distance + 1e-12] = np.nan
        acc.update([r.id for r in g], [r.id for r in h], dist, frameid=int(f))
    return acc


def mot_metrics(gt: Iterable[MotRow], hyp: Iterable[MotRow], *,
                iou_threshold: float = 0.5) -> dict[str, float]:
    """CLEAR-MOT + identity metrics of one sequence as ``{motmetrics name: value}``.

    ``motp`` is the mean ``1 - IoU`` of matched pairs (motmetrics' convention: lower is
    better).  Counts are returned as ints.
    """
    import motmetrics as mm

    acc = mot_accumulator(gt, hyp, iou_threshold=iou_threshold)
    summary = mm.metrics.create().compute(acc, metrics=list(MOT_METRICS), name="seq")
    out: dict[str, float] = {}
    for name in MOT_METRICS:
        v = summary.loc["seq", name]
        out[name] = int(v) if name.startswith("num_") or name in (
            "mostly_tracked", "partially_tracked", "mostly_lost") else float(v)
    return out


def mot_summary(accumulators: Mapping[str, object]) -> "object":
    """A pandas DataFrame of the metrics per named accumulator plus an OVERALL row."""
    import motmetrics as mm

    if not accumulators:
        raise EvaluationError("nothing to summarise")
    mh = mm.metrics.create()
    return mh.compute_many(list(accumulators.values()), metrics=list(MOT_METRICS),
                           names=list(accumulators.keys()),
                           generate_overall=len(accumulators) > 1)


def render_summary(summary: "object") -> str:
    """The MOTChallenge-style text table of :func:`mot_summary`."""
    import motmetrics as mm

    mh = mm.metrics.create()
    return mm.io.render_summary(summary, formatters=mh.formatters,
                                namemap=mm.io.motchallenge_metric_names)


# -- single-target metrics -----------------------------------------------------------------

def _boxes_array(boxes: Sequence[Sequence[float] | None], name: str) -> np.ndarray:
    out = np.full((len(boxes), 4), np.nan)
    for i, b in enumerate(boxes):
        if b is None:
            continue
        arr = np.asarray(b, dtype=np.float64).reshape(-1)
        if arr.shape != (4,):
            raise EvaluationError(f"{name}[{i}] is not a box of 4 values")
        out[i] = arr
    return out


def _valid(boxes: np.ndarray) -> np.ndarray:
    return np.all(np.isfinite(boxes), axis=1) & (boxes[:, 2] > 0) & (boxes[:, 3] > 0)


def _paired(predicted, ground_truth) -> tuple[np.ndarray, np.ndarray]:
    p = _boxes_array(list(predicted), "predicted")
    g = _boxes_array(list(ground_truth), "ground_truth")
    if p.shape[0] != g.shape[0]:
        raise EvaluationError(f"{p.shape[0]} predictions for {g.shape[0]} ground-truth frames")
    keep = _valid(g)
    return p[keep], g[keep]


def center_errors(predicted: Sequence[Sequence[float] | None],
                  ground_truth: Sequence[Sequence[float] | None]) -> np.ndarray:
    """Centre distance (px) per frame with a valid ground-truth box; inf where no prediction."""
    p, g = _paired(predicted, ground_truth)
    err = np.full(g.shape[0], np.inf)
    ok = _valid(p)
    if np.any(ok):
        pc = p[ok, :2] + p[ok, 2:] / 2.0
        gc = g[ok, :2] + g[ok, 2:] / 2.0
        err[ok] = np.hypot(*(pc - gc).T)
    return err


def overlaps(predicted: Sequence[Sequence[float] | None],
             ground_truth: Sequence[Sequence[float] | None]) -> np.ndarray:
    """IoU per frame with a valid ground-truth box; 0 where there is no prediction."""
    p, g = _paired(predicted, ground_truth)
    out = np.zeros(g.shape[0])
    for i in range(g.shape[0]):
        if _valid(p[i:i + 1])[0]:
            out[i] = iou_matrix(p[i:i + 1], g[i:i + 1])[0, 0]
    return out


def precision_at(errors: Sequence[float], threshold: float = 20.0) -> float:
    """Fraction of frames with centre error <= ``threshold`` px (OTB precision; 20 px)."""
    e = np.asarray(errors, dtype=np.float64)
    if e.size == 0:
        raise EvaluationError("no frames to score")
    return float(np.mean(e <= threshold))


def success_curve(ious: Sequence[float], thresholds: Sequence[float] | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``(thresholds, rates)``: fraction of frames with IoU > t for t in 0, 0.05, ..., 1."""
    o = np.asarray(ious, dtype=np.float64)
    if o.size == 0:
        raise EvaluationError("no frames to score")
    t = np.linspace(0.0, 1.0, 21) if thresholds is None else np.asarray(thresholds, float)
    rates = np.array([np.mean(o > th) for th in t])
    return t, rates


def success_auc(ious: Sequence[float]) -> float:
    """Area under the success curve (mean success rate over 21 thresholds, OTB)."""
    _, rates = success_curve(ious)
    return float(np.mean(rates))


def single_target_metrics(predicted: Sequence[Sequence[float] | None],
                          ground_truth: Sequence[Sequence[float] | None],
                          precision_threshold: float = 20.0) -> dict[str, float]:
    """Mean centre error (over frames with a prediction), precision@20px and success AUC."""
    err = center_errors(predicted, ground_truth)
    ov = overlaps(predicted, ground_truth)
    finite = err[np.isfinite(err)]
    return {"frames": int(err.size),
            "mean_center_error": float(finite.mean()) if finite.size else float("inf"),
            "precision_at_20px" if precision_threshold == 20.0 else
            f"precision_at_{precision_threshold:g}px": precision_at(err, precision_threshold),
            "success_auc": success_auc(ov),
            "missing_frames": int(np.sum(~np.isfinite(err)))}


def parse_box_lines(lines: Iterable[str], source: str = "<text>"
                    ) -> list[tuple[float, float, float, float] | None]:
    """OTB ``groundtruth_rect.txt`` lines: one ``x y w h`` per line (commas, tabs or spaces;
    blank and ``#`` lines skipped).  A line with a NaN or a non-positive size is a frame
    without a box (None).  :class:`EvaluationError` naming the line otherwise."""
    out: list[tuple[float, float, float, float] | None] = []
    for n, values in numeric_lines(lines, 4, source):
        if len(values) != 4:
            raise EvaluationError(f"{source}:{n}: expected 4 values x y w h, got {len(values)}")
        x, y, w, h = values
        if not all(math.isfinite(v) for v in values) or w <= 0 or h <= 0:
            out.append(None)
        else:
            out.append((x, y, w, h))
    return out


def read_box_list(path: str | Path) -> list[tuple[float, float, float, float] | None]:
    """Read an OTB ``groundtruth_rect.txt``-style file (see :func:`parse_box_lines`)."""
    return parse_box_lines(read_text_lines(path), str(Path(path)))


def boxes_from_mot(rows: Iterable[MotRow], num_frames: int, track_id: int | None = None
                   ) -> list[tuple[float, float, float, float] | None]:
    """Per-frame boxes (frames 1..num_frames) of one id (default: the first id present)."""
    rows = list(rows)
    if track_id is None and rows:
        track_id = min(rows, key=lambda r: (r.frame, r.id)).id
    out: list[tuple[float, float, float, float] | None] = [None] * num_frames
    for r in rows:
        if r.id == track_id and 1 <= r.frame <= num_frames:
            out[r.frame - 1] = r.box
    return out

