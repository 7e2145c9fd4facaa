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

Pure functions on ``(x, y, w, h)`` boxes; the tracker calls :func:`is_other_part` for each
detection that would start a track.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mk_tracker.parameters import parameter

__all__ = ["BodyPartConfig", "stacked_part", "is_other_part"]


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


def is_other_part(detection_box, track_boxes, config: BodyPartConfig) -> bool:
    """Whether ``detection_box`` is the other part of the person of any of ``track_boxes``
    (``(N, 4)``); False when ``enabled`` is off."""
    if not config.enabled:
        return False
    return any(stacked_part(t, detection_box, config)
               for t in np.asarray(track_boxes, dtype=np.float64).reshape(-1, 4))
