"""A panning camera over a rendered scene: a moving crop window with exactly known motion.

A scene (:mod:`mk_tracker.synthetic.scene`) is rendered larger than the camera's view and
each frame is cropped at an offset that moves with the camera; the crop of frame ``i`` at
offset ``o_i`` shows world pixel ``p`` at ``p - o_i``, so the image motion from frame
``i - 1`` to ``i`` is the pure translation ``-(o_i - o_{i-1})`` and every truth box moves by
``-o_i``.  Sub-pixel offsets are resampled bilinearly (``cv2.warpAffine``).

:func:`robot_pan_offsets` is the offset path of a robot that turns in bursts: still, a fast
pan, still, a pan back (the case a constant-velocity model in image pixels cannot follow:
the image velocity jumps at every start and stop).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator, Sequence

import cv2
import numpy as np

from mk_tracker.synthetic.scene import SyntheticScene

__all__ = ["PanFrame", "panned_frames", "robot_pan_offsets"]


@dataclass(frozen=True)
class PanFrame:
    """One cropped frame: the image, its stamp, the crop offset and the shifted truth boxes
    (``boxes[id] = (x, y, w, h)`` in the crop's pixels; people outside the scene's frame or
    hidden entirely are left out)."""

    index: int
    stamp: float
    rgb: np.ndarray
    offset: tuple[float, float]
    boxes: dict[int, tuple[float, float, float, float]]


def robot_pan_offsets(frames: int, speed: float = 20.0, still: int = 8, moving: int = 10,
                      start: tuple[float, float] = (0.0, 0.0)) -> list[tuple[float, float]]:
    """Crop offsets of a camera that pans in bursts: ``still`` frames at rest, ``moving``
    frames at ``speed`` px/frame to the right, at rest again, then back to the left, and so
    on (the view moves right, so the image content moves left)."""
    if frames < 1 or still < 0 or moving < 1:
        raise ValueError("frames and moving must be >= 1 and still >= 0")
    offsets, x = [], float(start[0])
    period = 2 * (still + moving)
    for i in range(frames):
        phase = i % period
        if still <= phase < still + moving:
            x += speed
        elif phase >= 2 * still + moving:
            x -= speed
        offsets.append((x, float(start[1])))
    return offsets


def panned_frames(scene: SyntheticScene, offsets: Sequence[tuple[float, float]],
                  width: int, height: int) -> Iterator[PanFrame]:
    """Frames ``0 .. len(offsets) - 1`` of ``scene`` cropped to ``width x height`` at the
    given offsets (the crop must stay inside the rendered frame)."""
    cfg = scene.config
    for i, (ox, oy) in enumerate(offsets):
        if ox < 0 or oy < 0 or ox + width > cfg.width or oy + height > cfg.height:
            raise ValueError(f"crop at ({ox}, {oy}) of {width}x{height} leaves the "
                             f"{cfg.width}x{cfg.height} scene")
        frame = scene.frame(i)
        if float(ox).is_integer() and float(oy).is_integer():
            x0, y0 = int(ox), int(oy)
            rgb = np.ascontiguousarray(frame.rgb[y0:y0 + height, x0:x0 + width])
        else:
            m = np.array([[1.0, 0.0, -ox], [0.0, 1.0, -oy]])
            rgb = cv2.warpAffine(frame.rgb, m, (width, height), flags=cv2.INTER_LINEAR)
        boxes = {o.id: (o.box_rgb[0] - ox, o.box_rgb[1] - oy, o.box_rgb[2], o.box_rgb[3])
                 for o in frame.objects if o.in_frame_rgb and o.visible_fraction > 0}
        yield PanFrame(index=i, stamp=frame.stamp, rgb=rgb, offset=(float(ox), float(oy)),
                       boxes=boxes)
