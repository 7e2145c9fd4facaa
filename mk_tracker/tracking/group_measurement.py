"""Group measurements: one detection box that covers several tracked people (issue #15).

A detector that cannot separate people who walk close together reports one box around
them.  Assigned to one of their tracks, that box would become that track's measurement: the
track grows to the group's size and the others, without a detection, coast and are lost.
The box is instead a *group measurement*:

* a detection is a group when at least two confirmed (or occluded) tracks lie mostly inside
  it (:func:`coverage_matrix` ``>= member_coverage``) and it is clearly larger than each of
  them (``min_area_ratio``: a box about one person's size around two tracks is one person
  with a duplicate track, not a group), and its members do not overlap one another by more
  than ``member_max_iou`` (two tracks on one person are not two people);
* the group's detection is not assigned to any track; each member is placed by its own
  multiple-kernel refinement from its Kalman prediction (Chu et al. 2013, Sec. IV-D: the
  kernels are built for people who occlude one another), and the group box only
  *constrains* that position (:func:`constrain_inside`): the member's box is moved the
  least distance that puts it inside the group box;
* the member counts as detected (the detector does see it, inside the group), at a lower
  measurement quality (``quality_factor``), and its appearance model is not refreshed from a
  view shared with its neighbours;
* a detection whose area is mostly covered by live tracks (:func:`explained_fraction`
  ``>= explained_coverage``) never starts a new track: it is already explained.

Pure functions on ``(x, y, w, h)`` boxes; the tracker
(:class:`mk_tracker.tracking.multi_object_tracker.MultiObjectTracker`) calls them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mk_tracker.boxes import iou_matrix
from mk_tracker.parameters import parameter

__all__ = ["GroupConfig", "coverage_matrix", "find_groups", "constrain_inside",
           "explained_fraction"]


@dataclass(frozen=True)
class GroupConfig:
    """When a detection is a group measurement, and how much it counts (``group.*``)."""

    enabled: bool = parameter(True, "Treat a detection box around two or more confirmed "
                              "tracks as a group measurement (each member placed by its own "
                              "multiple-kernel refinement inside the box) instead of "
                              "assigning it to one of them")
    member_coverage: float = parameter(
        0.6, "A track is inside a detection when at least this fraction of its predicted "
        "box lies in the detection box", minimum=0.05, maximum=1.0)
    min_area_ratio: float = parameter(
        1.4, "A group box is at least this many times the area of each member's box",
        minimum=1.0, maximum=100.0)
    member_max_iou: float = parameter(
        0.5, "Tracks that overlap one another by more than this IoU are not a group of "
        "people (two tracks on one person): the detection is associated as usual",
        minimum=0.0, maximum=1.0)
    member_min_height: float = parameter(
        0.0, "A member's box is at least this fraction of the group box's height (people "
        "side by side at one distance are about equally tall in the image; a much shorter "
        "track inside the box follows a part of a person, e.g. torso or legs); 0 = off",
        minimum=0.0, maximum=1.0)
    quality_factor: float = parameter(
        0.5, "Factor on the detection's quality for a member's constrained position "
        "(lower: the member follows its own prediction and refinement more)",
        minimum=0.0, maximum=1.0)
    explained_coverage: float = parameter(
        0.6, "An unassigned detection whose area is covered by live tracks' boxes by at "
        "least this fraction starts no new track (1 = only the IoU rule new_track_max_iou)",
        minimum=0.0, maximum=1.0)


def _as_boxes(boxes) -> np.ndarray:
    return np.asarray(boxes, dtype=np.float64).reshape(-1, 4)


def coverage_matrix(inner, outer) -> np.ndarray:
    """``(I, O)`` fraction of each inner box's area that lies inside each outer box."""
    a, b = _as_boxes(inner), _as_boxes(outer)
    x0 = np.maximum(a[:, None, 0], b[None, :, 0])
    y0 = np.maximum(a[:, None, 1], b[None, :, 1])
    x1 = np.minimum(a[:, None, 0] + a[:, None, 2], b[None, :, 0] + b[None, :, 2])
    y1 = np.minimum(a[:, None, 1] + a[:, None, 3], b[None, :, 1] + b[None, :, 3])
    inter = np.clip(x1 - x0, 0.0, None) * np.clip(y1 - y0, 0.0, None)
    area = np.maximum(a[:, 2] * a[:, 3], 1e-12)
    return inter / area[:, None]


def find_groups(track_boxes, det_boxes, config: GroupConfig) -> dict[int, list[int]]:
    """Group detections and their members: ``{detection index: [track indices]}``.

    Each track belongs to at most one group, the detection that covers most of it; a
    detection is a group when two or more tracks belong to it and its area is at least
    ``min_area_ratio`` times each member's.
    """
    tracks, dets = _as_boxes(track_boxes), _as_boxes(det_boxes)
    if not config.enabled or len(tracks) < 2 or len(dets) == 0:
        return {}
    cover = coverage_matrix(tracks, dets)                      # (T, D)
    best = np.argmax(cover, axis=1)
    inside = cover[np.arange(len(tracks)), best] >= config.member_coverage
    det_area = dets[:, 2] * dets[:, 3]
    track_area = tracks[:, 2] * tracks[:, 3]
    groups: dict[int, list[int]] = {}
    for i in np.flatnonzero(inside):
        k = int(best[i])
        if det_area[k] >= config.min_area_ratio * track_area[i] and \
                tracks[i, 3] >= config.member_min_height * dets[k, 3]:
            groups.setdefault(k, []).append(int(i))
    out = {}
    for k, members in groups.items():
        if len(members) < 2:
            continue
        pair = iou_matrix(tracks[members], tracks[members])
        np.fill_diagonal(pair, 0.0)
        if pair.max() <= config.member_max_iou:
            out[k] = members
    return out


def constrain_inside(box, outer) -> np.ndarray:
    """``box`` moved the least distance that puts it inside ``outer`` (centred on the
    outer box along an axis where it is larger); its size is kept."""
    x, y, w, h = (float(v) for v in box)
    ox, oy, ow, oh = (float(v) for v in outer)

    def axis(pos: float, size: float, lo: float, span: float) -> float:
        if size >= span:
            return lo + (span - size) / 2.0
        return min(max(pos, lo), lo + span - size)

    return np.array([axis(x, w, ox, ow), axis(y, h, oy, oh), w, h])


def explained_fraction(box, track_boxes, samples: int = 12) -> float:
    """Fraction of ``box``'s area covered by the union of ``track_boxes``, measured on a
    ``samples x samples`` grid of points at the centres of equal cells."""
    tracks = _as_boxes(track_boxes)
    if len(tracks) == 0:
        return 0.0
    x, y, w, h = (float(v) for v in box)
    t = (np.arange(samples) + 0.5) / samples
    px, py = np.meshgrid(x + t * w, y + t * h)
    px, py = px.ravel()[:, None], py.ravel()[:, None]
    inside = ((px >= tracks[None, :, 0]) & (px < tracks[None, :, 0] + tracks[None, :, 2])
              & (py >= tracks[None, :, 1]) & (py < tracks[None, :, 1] + tracks[None, :, 3]))
    return float(inside.any(axis=1).mean())
