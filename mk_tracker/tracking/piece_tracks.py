"""Piece tracks: a track whose box lies inside a larger track's box is a piece of that
person, not a person (issues #15 / #19).

A detector that splits footprints (``detector.split_by_valleys`` with
``detector.valley_columns``) raises the generator's crowds from a tracker of groups to one
of people, but on real LWIR it also cuts one near person into pieces, differently from one
full-frame pass to the next: a head, the legs, one half of the body.  Each piece starts a
track, and the multiple-kernel refinement (Chu et al. 2013, Sec. IV-D) keeps it on its
piece, which is the same warm person as the whole-body track around it; the duplicate rule
(:mod:`~mk_tracker.tracking.duplicate_tracks`) does not see them, since a piece and its
person overlap at IoU well below 0.5 (a box a third of the other's area inside it has IoU
0.33).  On BU-TIV-lab, counter masked, that made 19 ids for about 7 people
(docs/benchmark_real_thermal.md, "Piece tracks").

The rule here is a containment test over time, the piece-level counterpart of the
duplicate rule:

* a reported track (confirmed or occluded, not started by hand) is *nested* in another
  reported track when at least ``min_coverage`` of its box's area lies inside the other's
  box (:func:`~mk_tracker.tracking.group_measurement.coverage_matrix`) and the other box
  is at least ``min_area_ratio`` times its area (the *container*: the whole person around
  a piece; two boxes of about one size are the duplicate rule's);
* a nested track is not reported (``FrameResult.suppressed_ids``): the person is already
  reported by its container;
* a track nested for ``min_time`` seconds without a break is deleted: it follows a part of
  a person whom its container follows whole.  A break (a frame in which it is not nested)
  restarts its clock.

A person who walks behind a nearer one and is hidden by more than ``min_coverage`` of the
box is suppressed too while hidden; the rule cannot tell that person from a piece, which is
why it ships off where the measurements say so (docs/benchmark_real_thermal.md).

Pure functions on ids, boxes and stamps; the tracker
(:class:`~mk_tracker.tracking.multi_object_tracker.MultiObjectTracker`) calls them once per
frame after the duplicate rule.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from mk_tracker.parameters import parameter
from mk_tracker.tracking.group_measurement import coverage_matrix

__all__ = ["PieceConfig", "nested_in", "update_nested_since", "due_pieces"]


@dataclass(frozen=True)
class PieceConfig:
    """When a track is a piece of the person of a larger track (``pieces.*``)."""

    enabled: bool = parameter(
        False, "A reported track whose box lies inside a larger reported track's box "
        "(min_coverage, min_area_ratio) is not reported, and is deleted after min_time "
        "seconds nested: a piece (head, legs, half) of the person the larger track "
        "follows whole (tracking/piece_tracks.py)")
    min_coverage: float = parameter(
        0.8, "Fraction of a track's box area inside the other track's box for it to be "
        "nested", minimum=0.05, maximum=1.0)
    min_area_ratio: float = parameter(
        1.5, "The container's box is at least this many times the nested track's box area "
        "(about equal boxes are duplicates, duplicates.*)", minimum=1.0, maximum=100.0)
    min_time: float = parameter(
        0.3, "Seconds a track must stay nested, without a break, before it is deleted",
        minimum=0.0, maximum=1e4)


def nested_in(ids: Sequence[int], boxes, config: PieceConfig) -> dict[int, int]:
    """``{nested id: container id}`` for the tracks ``ids`` with ``(x, y, w, h)`` boxes.

    A track is nested in the track that covers most of its box, when that coverage is at
    least ``min_coverage`` and that track's box area is at least ``min_area_ratio`` times
    its own.  A container that is itself nested passes its nested tracks on to its own
    container (head in legs in body: both inner tracks are the body's).  Boxes with a non-positive or
    non-finite size are neither nested nor containers.
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
