"""Figures of a multi-object run that need no ground truth (issue #19: real thermal video
without annotations): tracks and detections per frame, distinct track ids over the clip
(against the number of people seen), and pairs of tracks on top of one another (IoU > 0.5)
per frame, the duplicates an identity-keeping tracker should not make.
"""

from __future__ import annotations

from typing import Sequence

from mk_tracker.boxes import iou

__all__ = ["duplicate_pairs", "identity_figures"]


def duplicate_pairs(boxes: Sequence[Sequence[float]], threshold: float = 0.5) -> int:
    """Pairs of ``(x, y, w, h)`` boxes of one frame that overlap at IoU > ``threshold``."""
    return sum(1 for i in range(len(boxes)) for j in range(i + 1, len(boxes))
               if iou(boxes[i], boxes[j]) > threshold)


def identity_figures(tracks_by_frame: Sequence[Sequence[tuple[int, Sequence[float]]]],
                     detections_by_frame: Sequence[Sequence] = ()) -> dict[str, float]:
    """``detections`` and ``tracks`` per frame, distinct ``ids``, ``duplicates`` (pairs of
    tracks at IoU > 0.5) per frame, from ``[(track id, box), ...]`` per frame and the
    detections of the same frames (any sequence per frame)."""
    n = max(len(tracks_by_frame), 1)
    ids = {tid for frame in tracks_by_frame for tid, _ in frame}
    return {"detections": sum(map(len, detections_by_frame)) / n,
            "tracks": sum(map(len, tracks_by_frame)) / n,
            "ids": len(ids),
            "duplicates": sum(duplicate_pairs([b for _, b in f]) for f in tracks_by_frame) / n}
