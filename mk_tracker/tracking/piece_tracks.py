"""Piece tracks: tracks on pieces of one person, under a detector that splits footprints
(issues #15 / #19).  Both rules are off by default.

A detector that splits footprints (``detector.split_by_valleys`` with
``detector.valley_columns``) raises the generator's crowds from a tracker of groups to one
of people, but on real LWIR it also cuts one near person into pieces, differently from one
full-frame pass to the next: a head, the legs, one half of the body, squat blocks stacked
in one column.  Each piece starts a track, gets detections of its own now and then, and
the multiple-kernel refinement (Chu et al. 2013, Sec. IV-D) keeps it on its piece between
them.  On BU-TIV-lab, counter masked, that made 19 ids for about 7 people
(docs/benchmark_real_thermal.md, "Piece tracks under the column valley split").

Two rules, each with its own switch:

* **Confirmation beside live tracks** (``min_hits_beside`` > 0): a track born on a
  detection that live tracks' boxes (tentative, confirmed or occluded) already cover by at
  least ``beside_coverage`` (:func:`~mk_tracker.tracking.group_measurement.
  explained_fraction`, :func:`born_beside`) is confirmed only after ``min_hits_beside``
  detections (:func:`hits_to_confirm`), and a tentative track ends at its first frame
  without one (``lifecycle.max_tentative_misses``), so those detections come in
  consecutive frames.  The split cuts a near person differently at each pass, so a piece
  is seldom detected that steadily and ends before it is ever reported; a person beside
  another one whom the detector keeps finding is confirmed that much later.  On the clip
  with the column split (15 hits, coverage 0.01): 19 -> 13 ids.
* **Nested tracks** (``enabled``): a reported track (confirmed or occluded, not started by
  hand) is *nested* in another when at least ``min_coverage`` of its box lies inside the
  other's box (:func:`~mk_tracker.tracking.group_measurement.coverage_matrix`) and the
  other is at least ``min_area_ratio`` times its area (two boxes of about one size are the
  duplicate rule's, :mod:`~mk_tracker.tracking.duplicate_tracks`); a nested track is not
  reported (``FrameResult.suppressed_ids``), and is deleted after ``min_time`` seconds
  nested without a break.  On the clip it does not pay: deleting gives more ids (19 ->
  23: the next split starts a new piece track in the freed place), hiding alone leaves 19
  (each piece is reported before it drifts inside its person's box).  It cannot tell a
  person hidden behind a nearer one from a piece either.

Pure functions on ids, boxes and stamps; the tracker
(:class:`~mk_tracker.tracking.multi_object_tracker.MultiObjectTracker`) calls
:func:`born_beside` at each birth, :func:`hits_to_confirm` in the lifecycle, and the nested
rule once per frame after the duplicate rule.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from mk_tracker.parameters import parameter
from mk_tracker.tracking.group_measurement import coverage_matrix, explained_fraction

__all__ = ["PieceConfig", "nested_in", "update_nested_since", "due_pieces", "born_beside",
           "hits_to_confirm"]


@dataclass(frozen=True)
class PieceConfig:
    """When a track is a piece of the person of a larger track (``pieces.*``)."""

    enabled: bool = parameter(
        False, "A reported track whose box lies inside a larger reported track's box "
        "(min_coverage, min_area_ratio) is not reported, and is deleted after min_time "
        "seconds nested: a piece (head, legs, half) of the person the larger track "
        "follows whole (tracking/piece_tracks.py; off: on BU-TIV-lab with the column "
        "valley split it gives more ids, not fewer)")
    min_coverage: float = parameter(
        0.8, "Fraction of a track's box area inside the other track's box for it to be "
        "nested", minimum=0.05, maximum=1.0)
    min_area_ratio: float = parameter(
        1.5, "The container's box is at least this many times the nested track's box area "
        "(about equal boxes are duplicates, duplicates.*)", minimum=1.0, maximum=100.0)
    min_time: float = parameter(
        0.3, "Seconds a track must stay nested, without a break, before it is deleted",
        minimum=0.0, maximum=1e4)
    min_hits_beside: int = parameter(
        0, "A track born on a detection whose box is covered by live tracks' boxes "
        "(tentative, confirmed or occluded) by at least beside_coverage needs this many "
        "detections, in consecutive frames (lifecycle.max_tentative_misses), to be "
        "confirmed: a piece the split cuts anew at each pass is not detected that "
        "steadily; 0 = lifecycle.min_hits for every track (off: with the default detector "
        "15 costs thermal-only still people; docs/benchmark_real_thermal.md)",
        minimum=0, maximum=1000)
    beside_coverage: float = parameter(
        0.2, "Fraction of a new track's birth box covered by live tracks' boxes for it to "
        "be born beside them (min_hits_beside)", minimum=0.0, maximum=1.0)


def nested_in(ids: Sequence[int], boxes, config: PieceConfig) -> dict[int, int]:
    """``{nested id: container id}`` for the tracks ``ids`` with ``(x, y, w, h)`` boxes.

    A track is nested in the track that covers most of its box, when that coverage is at
    least ``min_coverage`` and that track's box area is at least ``min_area_ratio`` times
    its own.  A container that is itself nested passes its nested tracks on to its own
    container (head in legs in body: both inner tracks are the body's).  Boxes with a
    non-positive or non-finite size are neither nested nor containers.
    """
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if len(b) < 2 or not config.enabled:
        return {}
    ok = np.all(np.isfinite(b), axis=1) & (b[:, 2] > 0) & (b[:, 3] > 0)
    area = np.where(ok, b[:, 2] * b[:, 3], 0.0)
    cover = np.where(ok[:, None] & ok[None, :], coverage_matrix(np.where(ok[:, None], b, 0.0),
                                                                np.where(ok[:, None], b, 0.0)),
                     0.0)
    np.fill_diagonal(cover, 0.0)
    big = area[None, :] >= config.min_area_ratio * area[:, None]
    cover = np.where(big, cover, 0.0)
    candidates = {}
    for i in range(len(b)):
        j = int(np.argmax(cover[i]))
        if cover[i, j] >= config.min_coverage:
            candidates[i] = j
    out = {}
    for i, j in candidates.items():
        for _ in range(len(b)):            # areas grow along a chain: it ends
            if j not in candidates or candidates[j] == i:
                break
            j = candidates[j]
        out[int(ids[i])] = int(ids[j])
    return out


def update_nested_since(since: dict[int, float], nested: dict[int, int],
                        stamp: float) -> dict[int, float]:
    """Each nested id with the stamp since which it has been nested without a break (a
    track nested now for the first time starts at ``stamp``; one not nested now is
    dropped)."""
    return {tid: since.get(tid, stamp) for tid in nested}


def due_pieces(since: dict[int, float], stamp: float, min_time: float) -> list[int]:
    """Ids nested for at least ``min_time`` seconds (sorted)."""
    return sorted(tid for tid, t0 in since.items() if stamp - t0 >= min_time)


def born_beside(box, track_boxes, config: PieceConfig) -> bool:
    """Whether a track born on ``box`` is born beside the live tracks of ``track_boxes``:
    at least ``beside_coverage`` of its area lies under their boxes (False when
    ``min_hits_beside`` is 0)."""
    if config.min_hits_beside <= 0:
        return False
    b = np.asarray(box, dtype=np.float64)
    if not np.all(np.isfinite(b)) or b[2] <= 0 or b[3] <= 0:
        return False
    return explained_fraction(b, track_boxes) >= config.beside_coverage


def hits_to_confirm(min_hits: int, beside: bool, config: PieceConfig) -> int:
    """Detections a tentative track needs to be confirmed: ``min_hits``, or
    ``min_hits_beside`` when it is larger and the track was born beside live ones."""
    return max(min_hits, config.min_hits_beside) if beside else min_hits
