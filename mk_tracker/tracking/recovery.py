"""Observation-centric recovery of drifted active tracks (issue #19).

OC-SORT (Cao, Pang, Weng, Khirodkar & Kitani, CVPR 2023, Sec. 4.3, "OCR") adds a second
association round after the first one: the tracks left unmatched are associated with the
detections left unmatched using each track's *last observation* instead of its estimate,
because an estimate that ran on without observations has drifted.

Here the estimate drifts for a second reason besides the constant-velocity prediction
(4.2) of Schizas et al. 2018: an undetected track is moved each frame by its
multiple-kernel refinement (Chu et al. 2013, Sec. IV-D), and on a grey thermal image the
kernels slide off their person (BU-TIV-lab: 0.2-0.7 box heights in 0.1-0.7 s,
docs/benchmark_real_thermal.md).  The refined estimate is confident, so the person's
returning detection falls outside the Kalman gate of step 4b and starts a new track next
to the old one.  The recovery round (step 4b' of
:meth:`~mk_tracker.tracking.multi_object_tracker.MultiObjectTracker.step`) gives it back:

* candidates are the confirmed or occluded tracks, not started by hand, that step 4b left
  without a detection (members of a group measurement are not in step 4b), and the
  detections that step 4b gave to no track or to a still-tentative one (a duplicate born
  next to the drifted track a frame or two ago);
* the distance of a detection centre ``z`` from a track's last detected centre ``c`` is
  the one of the lost-track gate (:func:`~mk_tracker.tracking.reacquisition.
  last_detection_distance2`): ``d2 = |z - c|^2 / (h^2 (s0^2 + (v dt)^2))`` with ``h`` the
  last detected height, ``dt`` the time since that detection (``Track.detected_stamp``),
  ``s0`` the floor and ``v`` a walking speed in box heights per second
  (``recovery.floor``, ``recovery.speed``); it replaces OC-SORT's IoU with the last
  observation by a radius that grows with the time the track went undetected;
* for a track slower than ``lifecycle.still_speed`` (a person standing still, whom the
  kernel covariance detector no longer sees) that time is capped at
  ``recovery.still_max_age``: the person has not walked away, and with the full time the
  radius reached passers-by (after 3 s: 3.3 box heights), whose grey thermal appearance
  passes the check, and the still person's track restarted on them
  (benchmarks/bench_still_people.py, docs/benchmark_real_thermal.md);
  ``recovery.skip_still`` leaves such tracks out altogether (off: BU-TIV-lab 13 ids);
* a pair is possible when ``d2 <= recovery.gate``, the heights differ by at most
  ``recovery.max_size_ratio``, and the track's frozen reference models match the
  detection's box with at least ``recovery.min_similarity``
  (:func:`~mk_tracker.tracking.reacquisition.reference_similarity`, as for re-acquiring a
  lost track).  Without that appearance check, on TUD-Campus the round gave a walking
  person's neighbour to it (one pair cost 0.07 MOTA); OC-SORT has no appearance term;
* the assignment is one-to-one, minimising ``d2``;
* a recovered track restarts its filter at the detection (:func:`restart_filter`,
  ``recovery.restart``): by default ``still``, a new filter at the detection's centre with
  velocity 0 and the initial variances, as a track is born, keeping its id; the drifted
  estimate and the velocity of the kernels' slide are discarded, not averaged with the
  detection by a covariance that the confident refinements kept small.  ``observations``
  takes the velocity from the last two detections (in the spirit of OC-SORT's
  observation-centric momentum, Sec. 4.2); ``correct`` is the ordinary Kalman correction.
  A tentative track that held the detection is deleted.

The multiple-kernel method (Chu et al.) and the detector (Schizas et al.) have no such
round: this is not in either paper.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from mk_tracker.kalman import ConstantVelocityKalman, KalmanConfig
from mk_tracker.parameters import parameter
from mk_tracker.tracking.association import assign
from mk_tracker.tracking.reacquisition import last_detection_distance2
from mk_tracker.tracking.track import TrackState

__all__ = ["RecoveryConfig", "recover_into", "recovery_cost", "recovery_round",
           "restart_filter"]


@dataclass(frozen=True)
class RecoveryConfig:
    """Observation-centric recovery of drifted active tracks (``recovery.*``)."""

    enabled: bool = parameter(
        True, "Second association round (OC-SORT's observation-centric recovery, Cao et "
        "al. 2023): a confirmed or occluded track left without a detection takes a "
        "remaining detection near its last detected box that its appearance matches "
        "(mk_tracker/tracking/recovery.py)")
    floor: float = parameter(
        0.05, "Std (box heights) of the last detected centre right after that detection",
        minimum=0.0, maximum=100.0)
    speed: float = parameter(
        0.3, "Growth of that std in box heights per second since the last detection",
        minimum=0.0, maximum=100.0)
    gate: float = parameter(
        13.8, "Chi-square gate (2 dof) on the squared normalised distance from the last "
        "detected centre (13.8 = 99.9 %: 3.7 std)", minimum=0.1, maximum=1e4)
    max_size_ratio: float = parameter(
        1.6, "Largest height ratio between the last detected box and the detection",
        minimum=1.0, maximum=100.0)
    min_similarity: float = parameter(
        0.7, "Appearance similarity (the best of the track's frozen reference models) the "
        "detection's box needs; 0 = no appearance check (TUD-Campus MOTA 0.593 -> 0.351: "
        "neighbours' detections are taken); 0.8 gives BU-TIV-lab 13 ids instead of 8",
        minimum=0.0, maximum=1.0)
    restart: str = parameter(
        "still", "How a recovered track takes the detection: still (a new filter at the "
        "detection, velocity 0 with the initial variances), observations (a new filter "
        "with the velocity of its last two detections), correct (the ordinary Kalman "
        "correction of the drifted estimate)",
        choices=("still", "observations", "correct"))
    skip_still: bool = parameter(
        False, "Leave tracks slower than lifecycle.still_speed out of the round: a person "
        "standing still has not drifted, and the radius that grows with the time since the "
        "last detection would otherwise reach a passer-by's detection, which the thermal "
        "appearance (people look alike in grey) lets through")
    still_max_age: float = parameter(
        0.5, "For tracks slower than lifecycle.still_speed, the time since the last "
        "detection that sets the radius is capped at this many seconds (a person standing "
        "still has not walked away from the last detection, so a passer-by's detection "
        "two box heights away is not theirs); 0 = no cap (chosen on the still-person "
        "scenes of benchmarks/bench_still_people.py, seeds 101-103: 0.5 and 1.0 tried)",
        minimum=0.0, maximum=1e5)


def recovery_cost(detected_boxes: np.ndarray, elapsed: Sequence[float],
                  detection_boxes: np.ndarray, config: RecoveryConfig) -> np.ndarray:
    """``(T, D)`` squared normalised distances (module docstring) of the detections'
    centres from each track's last detected box, ``inf`` outside the gate or beyond the
    height ratio.

    ``detected_boxes (T, 4)`` the tracks' last detected boxes ``(x, y, w, h)``,
    ``elapsed (T,)`` seconds since those detections, ``detection_boxes (D, 4)``.
    """
    tracks = np.asarray(detected_boxes, dtype=np.float64).reshape(-1, 4)
    dets = np.asarray(detection_boxes, dtype=np.float64).reshape(-1, 4)
    ages = np.asarray(elapsed, dtype=np.float64).reshape(-1)
    if ages.shape[0] != tracks.shape[0]:
        raise ValueError(f"{tracks.shape[0]} tracks but {ages.shape[0]} elapsed times")
    cost = np.full((tracks.shape[0], dets.shape[0]), np.inf)
    centres = dets[:, :2] + dets[:, 2:] / 2.0
    for i, b in enumerate(tracks):
        d2 = last_detection_distance2(centres, b[:2] + b[2:] / 2.0, float(b[3]),
                                      float(ages[i]), config.floor, config.speed)
        ratio = dets[:, 3] / max(float(b[3]), 1e-9)
        ok = (d2 <= config.gate) & (ratio >= 1.0 / config.max_size_ratio) & \
            (ratio <= config.max_size_ratio)
        cost[i, ok] = d2[ok]
    return cost


def recovery_round(tracks: Sequence[Any], detection_boxes: Sequence[np.ndarray],
                   holders: Sequence[Any | None], stamp: float, config: RecoveryConfig,
                   similarity: Callable[[Any, np.ndarray], float] | None = None
                   ) -> list[tuple[Any, int, Any | None]]:
    """The recovery round on the tracks of step 4b (module docstring).

    ``tracks``: the tracks step 4b saw; ``detection_boxes``: its detections;
    ``holders[j]``: the track step 4b gave detection ``j`` to, or None;
    ``similarity(track, box)``: the appearance similarity of a pair inside the gate
    (required by ``min_similarity`` > 0; None = no appearance check).  Returns ``(track,
    detection index, previous holder or None)`` per recovered pair, none when
    ``config.enabled`` is false; the caller gives the detection to the track and deletes
    the previous (tentative) holder."""
    if not config.enabled:
        return []
    held = {id(h) for h in holders if h is not None}
    cands = [t for t in tracks if id(t) not in held and not getattr(t, "manual", False)
             and t.state in (TrackState.CONFIRMED, TrackState.OCCLUDED)
             and not (config.skip_still and t.is_still())]
    cols = [j for j, h in enumerate(holders) if h is None or h.state is TrackState.TENTATIVE]
    if not cands or not cols:
        return []
    ages = [float(stamp) - t.detected_stamp for t in cands]
    if config.still_max_age > 0.0:
        ages = [min(a, config.still_max_age) if t.is_still() else a
                for a, t in zip(ages, cands)]
    cost = recovery_cost(np.array([t.detected_box for t in cands]), ages,
                         np.array([detection_boxes[j] for j in cols]), config)
    if config.min_similarity > 0.0 and similarity is not None:
        for r, c in zip(*np.nonzero(np.isfinite(cost))):
            sim = similarity(cands[r], np.asarray(detection_boxes[cols[c]]))
            if not sim >= config.min_similarity:          # NaN: refused
                cost[r, c] = np.inf
    pairs = assign(cost, np.inf).matches
    return [(cands[r], cols[c], holders[cols[c]]) for r, c in pairs]


def recover_into(tracks: Sequence[Any], single: Sequence[int], boxes: Sequence[np.ndarray],
                 matched: dict[int, int], stamp: float, config: RecoveryConfig,
                 events: list[str], similarity: Callable[[Any, np.ndarray], float] | None
                 ) -> set[int]:
    """Step 4b' of the tracker: :func:`recovery_round` on the tracks of step 4b
    (``tracks``, with ``.id``), its detections (indices ``single`` into ``boxes``) and its
    assignment ``matched`` (detection index -> track id), which is updated; a tentative
    track that held a recovered detection is deleted (state DELETED) and an event says
    so.  Returns the recovered track ids."""
    by_id = {t.id: t for t in tracks}
    holders = [by_id.get(matched.get(k)) for k in single]
    pairs = recovery_round(tracks, [boxes[k] for k in single], holders, stamp, config,
                           similarity)
    for t, j, previous in pairs:
        if previous is not None:
            previous.state = TrackState.DELETED
            events.append(f"tentative track {previous.id} is track {t.id} recovered")
        matched[single[j]] = t.id
    return {t.id for t, _, _ in pairs}


def restart_filter(track: Any, box: np.ndarray, stamp: float, kalman: KalmanConfig,
                   observed_velocity: bool = False) -> None:
    """Give a recovered ``track`` a new filter at the centre of ``box`` ``(x, y, w, h)``
    with ``kalman``'s initial variances and the size of ``box``; its velocity is 0, or
    with ``observed_velocity`` the one from its last detected box (``track.detected_box``
    at ``track.detected_stamp``) to ``box`` at ``stamp`` (0 when no time passed)."""
    x, y, w, h = (float(v) for v in box)
    centre = np.array([x + w / 2.0, y + h / 2.0])
    last = np.asarray(track.detected_box, dtype=np.float64)
    dt = float(stamp) - float(track.detected_stamp)
    velocity = (centre - (last[:2] + last[2:] / 2.0)) / dt \
        if dt > 0 and observed_velocity else np.zeros(2)
    track.kf = ConstantVelocityKalman.from_config(centre, kalman, initial_velocity=velocity)
    track.size = np.array([w, h])
