"""Duplicate tracks: two tracks that follow one person become one (issues #15, #19).

A detector that finds only what moves (Schizas et al. 2018) gives one box per person in one
frame and none in the next; the multiple-kernel refinement (Chu et al. 2013, Sec. IV-D)
keeps an undetected track on its person, so when a second track is born on that person (or
the detection is assigned to the other one of two nearby tracks) both live on, stacked.
Nothing in association retires either: each is matched now and then.

The rule here is a track-level non-maximum suppression over time (the box-level NMS of a
detector, applied to tracks, with the persistence test of "two tracks are one target"):

* two reported tracks (confirmed or occluded, not started by hand) are *stacked* while their
  boxes overlap by more than ``min_iou`` (:func:`stacked_pairs`);
* a stacked pair is *separated* in a frame in which both tracks were given detections
  that are not stacked themselves (IoU at most ``min_iou``): the detector then sees two
  people, and the pair's clock restarts (:func:`update_stacked_since`).  Two detections
  that overlap that much are the detector's two boxes of one person (the thermal
  detector's person cover can give one person twice, from two neighbouring group boxes:
  docs/benchmark_thermal_frame_rate.md), not two people;
* a pair stacked for at least ``min_time`` seconds without being separated is one person,
  provided that each track's appearance model (the kernel-weighted histograms of Chu et al.
  Sec. III-A) matches the other track's box with a similarity of at least
  ``min_similarity`` (two people in different clothes who occlude each other are not
  merged); the older track keeps its id (:func:`survivor`) and takes the newer one's
  Kalman state when the newer one was detected more recently (:func:`merge_into`); the
  other track is deleted;
* while a stacked pair waits for ``min_time`` (and passes the appearance test), only one of
  its tracks is *published* (``report_one``, :func:`published_of_pair`): by default the one
  detected last, the box a detector-level non-maximum suppression would keep.  The other is
  tracked on, unreported; if the pair is then detected as two people both are reported
  again.  A detector that sees only what moves (Schizas et al. 2018) lets the one
  detection of a person go to either of two stacked tracks from frame to frame, and their
  boxes' overlap drifts around ``min_iou``, so the clock restarts again and again and the
  merge comes late or never (docs/benchmark_real_thermal.md, "Where the duplicate pairs
  come from"); the pair is then published as one all the while.

Pure functions on ids, boxes and stamps; the tracker
(:class:`mk_tracker.tracking.multi_object_tracker.MultiObjectTracker`) calls them once per
frame after its updates.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from mk_tracker.boxes import iou_matrix
from mk_tracker.parameters import parameter

__all__ = ["DuplicateConfig", "stacked_pairs", "update_stacked_since", "due_pairs",
           "survivor", "published_of_pair", "publish_one_of_each", "merge_into"]

Pair = tuple[int, int]


@dataclass(frozen=True)
class DuplicateConfig:
    """When two tracks are one person (``duplicates.*``)."""

    enabled: bool = parameter(
        True, "Merge two reported tracks whose boxes stay stacked (IoU > min_iou) for "
        "min_time seconds without both being detected in one frame by detections that are "
        "not stacked themselves: the older id stays, the other track ends")
    min_iou: float = parameter(
        0.5, "Overlap (IoU) above which two tracks' boxes are stacked", minimum=0.0,
        maximum=1.0)
    min_time: float = parameter(
        0.3, "Seconds two tracks must stay stacked, never detected as two people, before "
        "they are merged", minimum=0.0, maximum=1e4)
    min_similarity: float = parameter(
        0.3, "Appearance similarity (kernel histograms, Chu et al. Sec. III-A) each track's "
        "model must reach on the other track's box for a merge (0 = no appearance test; "
        "without a multiple-kernel refiner and min_similarity > 0 nothing is merged)",
        minimum=0.0, maximum=1.0)
    report_one: str = parameter(
        "detected", "While a stacked pair waits for min_time (and passes the appearance test), "
        "publish only one of its tracks: none (both), survivor (the one that will keep its "
        "id), detected (the one detected last) or merged (the survivor's id with the box "
        "of the one detected last, as the merge would make it); the other is tracked on "
        "but not reported",
        choices=("none", "survivor", "detected", "merged"))


def _key(a: int, b: int) -> Pair:
    return (a, b) if a < b else (b, a)


def stacked_pairs(ids: Sequence[int], boxes, min_iou: float) -> dict[Pair, float]:
    """``{(smaller id, larger id): IoU}`` of the tracks whose ``(x, y, w, h)`` boxes overlap
    by more than ``min_iou``."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if len(ids) != len(b):
        raise ValueError(f"{len(ids)} ids for {len(b)} boxes")
    if len(b) < 2:
        return {}
    overlap = iou_matrix(b, b)
    out = {}
    for i in range(len(b)):
        for j in range(i + 1, len(b)):
            if overlap[i, j] > min_iou:
                out[_key(int(ids[i]), int(ids[j]))] = float(overlap[i, j])
    return out


def update_stacked_since(since: dict[Pair, float], stacked: Iterable[Pair],
                         detected_apart: Iterable[Pair], stamp: float) -> dict[Pair, float]:
    """The new ``{pair: first stamp of its current stacking}``.

    A pair stacked now keeps its start stamp (or starts at ``stamp``); a pair no longer
    stacked, or ``detected_apart`` this frame (both tracks given detections that are not
    stacked themselves), is forgotten, so its clock restarts the next time it is stacked."""
    apart = {_key(*p) for p in detected_apart}
    return {p: since.get(p, float(stamp)) for p in (_key(*q) for q in stacked)
            if p not in apart}


def due_pairs(since: dict[Pair, float], stamp: float, min_time: float) -> list[Pair]:
    """Pairs stacked for at least ``min_time`` seconds at ``stamp``, longest first (ties
    by ids)."""
    due = [(float(stamp) - t0, p) for p, t0 in since.items() if stamp - t0 >= min_time]
    return [p for _, p in sorted(due, key=lambda x: (-x[0], x[1]))]


def survivor(created_a: float, id_a: int, created_b: float, id_b: int) -> int:
    """Id of the track that keeps its identity: the older one (earlier ``created``; equal
    ages: the smaller id, which was given first)."""
    if created_a != created_b:
        return id_a if created_a < created_b else id_b
    return min(id_a, id_b)


def published_of_pair(a, b, mode: str):
    """Which track of a stacked pair waiting for ``min_time`` is published, and whose box
    it shows (``duplicates.report_one``): ``(published, hidden, box from)`` of tracks ``a``
    and ``b`` (anything with ``id``, ``created`` and ``last_detection``), or None for mode
    ``none``.

    ``survivor``: the track that keeps its id at the merge (:func:`survivor`), with its own
    box; ``detected``: the one detected last (equal: the survivor), with its own box;
    ``merged``: the survivor's id with the box of the one detected last, what
    :func:`merge_into` will make of the pair."""
    if mode == "none":
        return None
    keep = a if survivor(a.created, a.id, b.created, b.id) == a.id else b
    other = b if keep is a else a
    latest = other if other.last_detection > keep.last_detection else keep
    if mode == "survivor":
        return keep, other, keep
    if mode == "detected":
        return latest, (other if latest is keep else keep), latest
    if mode == "merged":
        return keep, other, latest
    raise ValueError(f"unknown report_one mode {mode!r}")


def publish_one_of_each(pairs: Iterable[Pair], tracks: dict, look_alike, mode: str
                        ) -> tuple[set[int], dict[int, np.ndarray]]:
    """The tracks not to report, and the boxes to report instead of a track's own, for the
    stacked ``pairs`` still waiting for ``min_time`` (:func:`published_of_pair` per pair).

    ``tracks`` maps an id to its track (with ``state``, ``box``); a pair with a deleted track
    (merged this frame), a track already hidden by another pair, or that fails
    ``look_alike(a, b)`` (two people by appearance) is left alone."""
    hidden: set[int] = set()
    boxes: dict[int, np.ndarray] = {}
    if mode == "none":
        return hidden, boxes
    for a_id, b_id in pairs:
        a, b = tracks[a_id], tracks[b_id]
        if "deleted" in (a.state, b.state) or a.id in hidden or b.id in hidden \
                or not look_alike(a, b):
            continue
        shown, gone, box_from = published_of_pair(a, b, mode)
        hidden.add(gone.id)
        if box_from is not shown:
            boxes[shown.id] = np.array(box_from.box, dtype=float)
    return hidden, boxes


def merge_into(keep, gone) -> None:
    """Fold track ``gone`` into track ``keep`` (both :class:`~mk_tracker.tracking.track.Track`).

    ``keep`` keeps its id, age and appearance model.  When ``gone`` was detected more
    recently its estimate is the better one: ``keep`` takes its Kalman filter, size and last
    detected box.
    ``keep``'s detection count and last detection / sighting become the larger of the
    two."""
    if gone.last_detection > keep.last_detection:
        keep.kf = copy.deepcopy(gone.kf)
        keep.size = np.array(gone.size, dtype=float)
        keep.detected_box = np.array(gone.detected_box, dtype=float)
    keep.hits = max(keep.hits, gone.hits)
    keep.last_detection = max(keep.last_detection, gone.last_detection)
    keep.last_seen = max(keep.last_seen, gone.last_seen)
