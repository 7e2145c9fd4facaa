"""Adapters running ByteTrack and OC-SORT of the ``trackers`` package (2.6.1) and ``motpy``
(0.0.10) on the same box detections as every other peer.

* ByteTrack (Zhang et al., ECCV 2022) and OC-SORT (Cao et al., CVPR 2023) run at their
  library defaults with ``frame_rate`` = the sequence's frame rate; detections are
  ``supervision.Detections`` (x0, y0, x1, y1) with their scores.  They report the boxes of the
  detections they matched to a confirmed track (tracker id >= 0).
* motpy runs with ``dt`` = 1 / frame rate and its default model (constant-velocity
  position, constant size) and reports its active tracks.

Install (benchmarks only; ``trackers`` and ``trackeval`` declare ``opencv-python``, which would
put a second cv2 beside the project's ``opencv-python-headless``, so they go in without
their dependencies, followed by the pure-Python ones that are missing)::

    .venv/bin/pip install --no-deps -r benchmarks/requirements-peers.txt
"""

from __future__ import annotations

import uuid

import numpy as np


def _xyxy(detections):
    boxes = np.array([[x, y, x + w, y + h] for x, y, w, h, _ in detections],
                     dtype=np.float64).reshape(-1, 4)
    scores = np.array([s for *_, s in detections], dtype=np.float64)
    return boxes, scores


class TrackersPeer:
    """ByteTrack or OC-SORT of ``trackers`` 2.6.1 behind ``update(stamp, detections)``."""

    def __init__(self, kind: str, frame_rate: float) -> None:
        import supervision as sv
        import trackers
        self._sv = sv
        cls = {"bytetrack": trackers.ByteTrackTracker, "ocsort": trackers.OCSORTTracker}[kind]
        self.tracker = cls(frame_rate=float(frame_rate))

    def update(self, stamp, detections):
        boxes, scores = _xyxy(detections)
        dets = self._sv.Detections(xyxy=boxes, confidence=scores,
                                   class_id=np.zeros(len(boxes), dtype=int))
        out = self.tracker.update(dets)
        result = []
        if out.tracker_id is None:
            return result
        for (x0, y0, x1, y1), tid in zip(out.xyxy, out.tracker_id):
            if tid is not None and int(tid) >= 0 and x1 > x0 and y1 > y0:
                result.append((int(tid), (float(x0), float(y0), float(x1 - x0),
                                          float(y1 - y0))))
        return result


class MotpyPeer:
    """motpy 0.0.10 at its defaults (dt = 1 / frame rate)."""

    def __init__(self, frame_rate: float) -> None:
        from motpy import Detection, MultiObjectTracker
        self._detection = Detection
        self.tracker = MultiObjectTracker(dt=1.0 / float(frame_rate))
        self._ids: dict[str, int] = {}

    def update(self, stamp, detections):
        boxes, scores = _xyxy(detections)
        self.tracker.step(detections=[self._detection(box=b, score=float(s))
                                      for b, s in zip(boxes, scores)])
        out = []
        for t in self.tracker.active_tracks():
            key = str(t.id) if not isinstance(t.id, uuid.UUID) else t.id.hex
            tid = self._ids.setdefault(key, len(self._ids) + 1)
            x0, y0, x1, y1 = (float(v) for v in t.box)
            if x1 > x0 and y1 > y0:
                out.append((tid, (x0, y0, x1 - x0, y1 - y0)))
        return out
