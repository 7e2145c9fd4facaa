"""Body parts: a detection of a tracked person's other half starts no track (issue #19).

The kernel covariance detector (Schizas et al. 2018) finds what moves, and on real thermal
video a walking person often moves as two blobs: the torso and the legs (the arms and the
belt line break the silhouette), so a person is reported as an upper and a lower box
(docs/benchmark_groups.md, "Box quality").  When one half is tracked, a detection of the
other half, directly above or below it, was an unexplained detection and started a second
track on the same person.  That track is detected as often as the first one (the detector
keeps cutting the person there), so neither the duplicate rule (it needs a pair never
detected as two) nor the lifecycle ends it: on BU-TIV-lab 3 of the 8 ids of the
counter-masked run are such part tracks, living to the end of the clip
(``benchmarks/diagnose_ids.py``; docs/benchmark_real_thermal.md, "Where each id comes
from").

A detection is the *other part* of a live track's person when, with ``T`` the track's box
and ``D`` the detection's:

* they share a column: the overlap of their x-ranges is at least ``min_column_overlap`` of
  the narrower width, and their widths differ by at most ``max_width_ratio`` (the torso and
  the legs of one upright person are about as wide; a farther person above a nearer one in
  the image is narrower);
* they are stacked, not side by side or one behind the other: their y-ranges overlap by at
  most ``max_row_overlap`` of the shorter height, and the gap between them is at most
  ``max_gap`` of the taller height;
* together they have the shape of one upright person: the union box is at least
  ``min_person_aspect`` and at most ``max_person_aspect`` times as tall as wide (two
  whole people one above the other, as a high camera sees a queue, make a taller union).

Such a detection starts no track, as a detection mostly covered by live tracks does not
(:func:`~mk_tracker.tracking.group_measurement.explained_fraction`): the person is already
tracked.  It does not touch association: a detection of a part can still be assigned to a
track in step 4 of the tracker (its own person's, when that track is the part's).

**Short parts** (``short_fraction`` > 0, off by default): the rule above needs two halves of
about one height and width, so it misses a legs box under a wider torso-and-arms box, or a
legs box born before a track stood above it (docs/benchmark_real_thermal.md, "Short parts").
The tracker therefore also learns the height of a whole person per image row from its own
isolated, person-shaped reported boxes (:class:`~mk_tracker.detection.person_size.
PersonHeightModel`, ``h = a + b * y_bottom``, the ground-plane prior of the detector's
``split_by_person_size``; the detector of Schizas et al. 2018 has no size prior).  A
detection is then also a part (:func:`short_stacked_part`) when it shares a column with a
reported box (``min_column_overlap`` of the detection's width), the two are stacked
(``max_row_overlap``; a gap of at most ``max_gap`` person heights), both boxes are shorter
than ``short_fraction`` of a person at their own bottom rows (two parts, not a part under a
whole tracked person), and their union is at most ``max_union_height`` persons tall at the
union's bottom row: together they are one person.  A short person part-hidden under a whole
tracked person starts a track (without the test on the track's box the generator's seed 202
lost such a person, docs/benchmark_real_thermal.md).

Pure functions on ``(x, y, w, h)`` boxes; the tracker calls :func:`is_other_part` for each
detection that would start a track.
"""

from __future__ import annotations

from dataclasses import dataclass

from typing import Callable, Optional

import numpy as np

from mk_tracker.detection.person_size import PersonHeightModel, is_person_shaped
from mk_tracker.parameters import parameter

__all__ = ["BodyPartConfig", "stacked_part", "short_stacked_part", "is_other_part",
           "height_sample", "RowHeights"]


@dataclass(frozen=True)
class BodyPartConfig:
    """When an unassigned detection is the other half of a tracked person (``parts.*``)."""

    enabled: bool = parameter(
        True, "A detection directly above or below a live track's box, in its column and "
        "together with it shaped like one upright person, starts no track (the detector "
        "cut the tracked person into torso and legs; tracking/body_parts.py)")
    min_column_overlap: float = parameter(
        0.6, "Overlap of the two boxes' x-ranges, as a fraction of the narrower width, for "
        "them to share a column", minimum=0.0, maximum=1.0)
    max_width_ratio: float = parameter(
        1.5, "Largest ratio of the two boxes' widths (torso and legs of one person are about "
        "as wide)", minimum=1.0, maximum=100.0)
    max_height_ratio: float = parameter(
        1.6, "Largest ratio of the two boxes' heights (a torso with the head and a pair of "
        "legs are each about half a person; a box much shorter than its neighbour is a "
        "person part-hidden in front, not a half)", minimum=1.0, maximum=100.0)
    max_row_overlap: float = parameter(
        0.35, "Largest overlap of the two boxes' y-ranges, as a fraction of the shorter "
        "height (more: side by side or one behind the other, not stacked)",
        minimum=0.0, maximum=1.0)
    max_gap: float = parameter(
        0.15, "Largest vertical gap between the two boxes, as a fraction of the taller "
        "height", minimum=0.0, maximum=10.0)
    min_person_aspect: float = parameter(
        1.8, "The union of the two boxes is at least this many times as tall as wide (one "
        "upright person)", minimum=0.0, maximum=100.0)
    max_part_aspect: float = parameter(
        2.0, "Each of the two boxes is at most this many times as tall as wide (a torso or "
        "a pair of legs is squatter than a whole upright person)", minimum=0.0,
        maximum=100.0)
    max_person_aspect: float = parameter(
        4.0, "The union of the two boxes is at most this many times as tall as wide (two "
        "whole people, one above the other in the image, make a taller union: about 5 for "
        "two boxes of aspect 2.5); keep it above min_person_aspect",
        minimum=0.0, maximum=100.0)
    short_fraction: float = parameter(
        0.0, "Short parts: a detection and a reported box, each shorter than this fraction "
        "of the learnt height of a person at its bottom row, stacked in one column with a "
        "union at most max_union_height persons tall: the detection starts no track (0: off)", minimum=0.0, maximum=1.0)
    max_union_height: float = parameter(
        1.25, "Short parts: largest height of the detection and the reported box together, "
        "in learnt person heights at the union's bottom row", minimum=0.0, maximum=10.0)
    person_aspect: float = parameter(
        0.45, "Short parts: width / height of one upright person; a reported box within 0.6 "
        "to 1.5 times it, overlapping no other reported box, is a height sample",
        minimum=0.01, maximum=10.0)
    height_memory: float = parameter(
        300.0, "Short parts: forgetting of the row-height fit, in samples (one per isolated "
        "reported track and frame)", minimum=1.0, maximum=1e6)
    min_height_samples: float = parameter(
        30.0, "Short parts: samples' total weight before the learnt height is used",
        minimum=2.5, maximum=1e6)


def stacked_part(track_box, detection_box, config: BodyPartConfig) -> bool:
    """Whether ``detection_box`` is the other part of the person in ``track_box`` (module
    docstring).  Boxes with a non-positive or non-finite size are not parts."""
    tx, ty, tw, th = (float(v) for v in track_box)
    dx, dy, dw, dh = (float(v) for v in detection_box)
    if not all(np.isfinite((tx, ty, tw, th, dx, dy, dw, dh))) or min(tw, th, dw, dh) <= 0:
        return False
    if dh > config.max_part_aspect * dw or th > config.max_part_aspect * tw:
        return False
    column = min(tx + tw, dx + dw) - max(tx, dx)
    if column < config.min_column_overlap * min(tw, dw):
        return False
    if max(tw, dw) > config.max_width_ratio * min(tw, dw) or \
            max(th, dh) > config.max_height_ratio * min(th, dh):
        return False
    rows = min(ty + th, dy + dh) - max(ty, dy)        # negative: a gap between them
    if rows > config.max_row_overlap * min(th, dh):
        return False
    if -rows > config.max_gap * max(th, dh):
        return False
    union_w = max(tx + tw, dx + dw) - min(tx, dx)
    union_h = max(ty + th, dy + dh) - min(ty, dy)
    return config.min_person_aspect * union_w <= union_h <= config.max_person_aspect * union_w


HeightAt = Callable[[float], Optional[float]]


def short_stacked_part(track_box, detection_box, height_at: HeightAt,
                       config: BodyPartConfig) -> bool:
    """Whether ``detection_box`` is a short part of the person in ``track_box`` (module
    docstring, "Short parts"); ``height_at(y_bottom)`` is the learnt person height at a row
    (None: not learnt, no part).  False with ``short_fraction`` 0 or invalid boxes."""
    if not config.short_fraction > 0.0:
        return False
    tx, ty, tw, th = (float(v) for v in track_box)
    dx, dy, dw, dh = (float(v) for v in detection_box)
    if not all(np.isfinite((tx, ty, tw, th, dx, dy, dw, dh))) or min(tw, th, dw, dh) <= 0:
        return False
    if min(tx + tw, dx + dw) - max(tx, dx) < config.min_column_overlap * dw:
        return False
    person = height_at(dy + dh)
    if person is None or not person > 0 or dh >= config.short_fraction * person:
        return False
    rows = min(ty + th, dy + dh) - max(ty, dy)        # negative: a gap between them
    if rows > config.max_row_overlap * min(th, dh) or -rows > config.max_gap * person:
        return False
    track_person = height_at(ty + th)
    if track_person is None or th >= config.short_fraction * track_person:
        return False
    union_bottom = max(ty + th, dy + dh)
    union_person = height_at(union_bottom)
    return union_person is not None and union_person > 0 and \
        union_bottom - min(ty, dy) <= config.max_union_height * union_person


def height_sample(index: int, boxes, aspect: float) -> bool:
    """Whether ``boxes[index]`` (``(N, 4)``) is a whole-person height sample: person-shaped
    (:func:`~mk_tracker.detection.person_size.is_person_shaped`) and overlapping no other box."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    x, y, w, h = boxes[index]
    if not (w > 0 and h > 0 and is_person_shaped(w, h, aspect)):
        return False
    others = np.delete(boxes, index, axis=0)
    apart = (others[:, 0] >= x + w) | (others[:, 0] + others[:, 2] <= x) | \
        (others[:, 1] >= y + h) | (others[:, 1] + others[:, 3] <= y)
    return bool(np.all(apart))


class RowHeights:
    """The tracker's learnt person height per image row (``parts.short_fraction``): a
    :class:`~mk_tracker.detection.person_size.PersonHeightModel` fed each frame with the
    reported boxes that are :func:`height_sample` s."""

    def __init__(self, config: BodyPartConfig) -> None:
        self.config = config
        self.model = PersonHeightModel(config.height_memory,
                                       min_samples=config.min_height_samples)

    def add(self, reported_boxes) -> None:
        boxes = np.asarray(reported_boxes, dtype=np.float64).reshape(-1, 4)
        for i in range(len(boxes)):
            if height_sample(i, boxes, self.config.person_aspect):
                self.model.add(boxes[i, 1] + boxes[i, 3], boxes[i, 3])

    def height_at(self, y_bottom: float) -> float | None:
        return self.model.height_at(y_bottom)


def is_other_part(detection_box, track_boxes, config: BodyPartConfig,
                  height_at: HeightAt | None = None) -> bool:
    """Whether ``detection_box`` is the other part of the person of any of ``track_boxes``
    (``(N, 4)``), a half (:func:`stacked_part`) or, given ``height_at``, a short part
    (:func:`short_stacked_part`); False when ``enabled`` is off."""
    if not config.enabled:
        return False
    boxes = np.asarray(track_boxes, dtype=np.float64).reshape(-1, 4)
    if any(stacked_part(t, detection_box, config) for t in boxes):
        return True
    return height_at is not None and any(
        short_stacked_part(t, detection_box, height_at, config) for t in boxes)
