"""Annotated debug images: detections, tracks and their kernels drawn with OpenCV.

Pure functions over plain data (boxes in the project convention ``(x, y, w, h)``, see
:mod:`mk_tracker.boxes`): every function returns a new image and never modifies its input.
The ROS nodes publish these images on ``~/debug_image``; the offline pipeline writes them
into its video.

* :func:`thermal_to_display` turns a thermal frame (mono8/mono16/16UC1/32FC1) into a
  colour-mapped BGR image;
* :func:`draw_detections` draws detector boxes with scores;
* :func:`draw_tracks` draws tracked boxes with their id, state and score, and each track's
  kernels as ellipses (the multiple kernels of Chu et al. 2013, Sec. III);
* :func:`draw_text_lines` writes a status block in the top-left corner.

Non-finite or empty boxes and ellipses are skipped instead of raising: a debug image
should show what can be shown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import cv2
import numpy as np

from mk_tracker.messages.image_conversion import to_bgr

BGR = tuple[int, int, int]

DETECTION_COLOR: BGR = (0, 255, 255)     # yellow
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_COORD_LIMIT = 1e6   # OpenCV takes int coordinates; clamp far-away geometry


class DrawingError(ValueError):
    """The image to draw on is not an 8-bit BGR (or gray) image."""


@dataclass(frozen=True)
class KernelEllipse:
    """One kernel drawn as an ellipse: centre (px), semi-axes (px), angle (degrees)."""

    center: tuple[float, float]
    axes: tuple[float, float]
    angle_deg: float = 0.0


@dataclass(frozen=True)
class TrackDrawing:
    """What is drawn for one track."""

    box: tuple[float, float, float, float]
    track_id: int | str
    state: str = ""
    score: float | None = None
    kernels: Sequence[KernelEllipse] = field(default_factory=tuple)


def track_color(track_id: int | str) -> BGR:
    """A stable, saturated colour per track id (same id -> same colour in every frame)."""
    key = str(track_id)
    h = 0
    for ch in key:
        h = (h * 131 + ord(ch)) % 1_000_003
    hue = int((h * 47) % 180)           # OpenCV hue range is 0..179
    hsv = np.array([[[hue, 220, 255]]], dtype=np.uint8)
    b, g, r = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0]
    return int(b), int(g), int(r)


def as_canvas(image: np.ndarray) -> np.ndarray:
    """A writable BGR uint8 copy of ``image`` (gray ``(h, w)`` is converted to BGR)."""
    if not isinstance(image, np.ndarray):
        raise DrawingError(f"expected a numpy image, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise DrawingError(f"debug drawing needs a uint8 image, got {image.dtype}")
    if image.ndim == 2:
        canvas = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    elif image.ndim == 3 and image.shape[2] == 3:
        canvas = image.copy()
    else:
        raise DrawingError(f"debug drawing needs a (h, w) or (h, w, 3) image, got {image.shape}")
    if canvas.shape[0] == 0 or canvas.shape[1] == 0:
        raise DrawingError(f"cannot draw on an empty image of shape {image.shape}")
    return np.ascontiguousarray(canvas)


def thermal_to_display(frame: np.ndarray, encoding: str,
                       colormap: int | None = cv2.COLORMAP_INFERNO) -> np.ndarray:
    """A BGR display image of a thermal frame.

    Scaling to 0..255 (by the frame's own finite min..max for 16-bit and float frames; NaN
    pixels become 0) is :func:`mk_tracker.messages.image_conversion.to_bgr`; ``colormap`` (an OpenCV
    colormap id, or None for gray) is applied on top.
    """
    bgr = to_bgr(frame, encoding)
    if colormap is None:
        return np.ascontiguousarray(bgr).copy()
    gray = cv2.cvtColor(np.ascontiguousarray(bgr), cv2.COLOR_BGR2GRAY)
    return cv2.applyColorMap(gray, colormap)


def _finite_box(box: Sequence[float]) -> tuple[int, int, int, int] | None:
    try:
        x, y, w, h = (float(v) for v in box)
    except (TypeError, ValueError):
        return None
    if not all(math.isfinite(v) for v in (x, y, w, h)) or w <= 0 or h <= 0:
        return None
    x0 = int(round(max(-_COORD_LIMIT, min(_COORD_LIMIT, x))))
    y0 = int(round(max(-_COORD_LIMIT, min(_COORD_LIMIT, y))))
    x1 = int(round(max(-_COORD_LIMIT, min(_COORD_LIMIT, x + w))))
    y1 = int(round(max(-_COORD_LIMIT, min(_COORD_LIMIT, y + h))))
    return x0, y0, x1, y1


def _label(canvas: np.ndarray, text: str, x: int, y: int, color: BGR) -> None:
    """Filled label box above (x, y), kept inside the image."""
    scale, thickness = 0.45, 1
    (tw, th), baseline = cv2.getTextSize(text, _FONT, scale, thickness)
    height, width = canvas.shape[:2]
    x = min(max(x, 0), max(width - tw - 2, 0))
    top = y - th - baseline - 2
    if top < 0:
        top = min(max(y, 0), max(height - th - baseline - 2, 0))
    cv2.rectangle(canvas, (x, top), (x + tw + 2, top + th + baseline + 2), color, cv2.FILLED)
    luminance = 0.114 * color[0] + 0.587 * color[1] + 0.299 * color[2]
    ink = (0, 0, 0) if luminance > 128 else (255, 255, 255)
    cv2.putText(canvas, text, (x + 1, top + th + 1), _FONT, scale, ink, thickness, cv2.LINE_AA)


def draw_detections(image: np.ndarray, boxes: Iterable[Sequence[float]],
                    scores: Iterable[float] | None = None,
                    color: BGR = DETECTION_COLOR, thickness: int = 1) -> np.ndarray:
    """A copy of ``image`` with each detection box (and its score, if given) drawn."""
    canvas = as_canvas(image)
    box_list = list(boxes)
    score_list = list(scores) if scores is not None else [None] * len(box_list)
    if len(score_list) != len(box_list):
        raise DrawingError(f"{len(box_list)} boxes but {len(score_list)} scores")
    for box, score in zip(box_list, score_list):
        corners = _finite_box(box)
        if corners is None:
            continue
        x0, y0, x1, y1 = corners
        cv2.rectangle(canvas, (x0, y0), (x1, y1), color, thickness, cv2.LINE_8)
        if score is not None and math.isfinite(float(score)):
            _label(canvas, f"{float(score):.2f}", x0, y0, color)
    return canvas


def _draw_kernel(canvas: np.ndarray, kernel: KernelEllipse, color: BGR) -> None:
    try:
        cx, cy = (float(v) for v in kernel.center)
        ax, ay = (float(v) for v in kernel.axes)
        angle = float(kernel.angle_deg)
    except (TypeError, ValueError):
        return
    values = (cx, cy, ax, ay, angle)
    if not all(math.isfinite(v) for v in values) or ax <= 0 or ay <= 0:
        return
    if max(abs(cx), abs(cy), ax, ay) > _COORD_LIMIT:
        return
    cv2.ellipse(canvas, (int(round(cx)), int(round(cy))),
                (max(1, int(round(ax))), max(1, int(round(ay)))), angle, 0.0, 360.0, color, 1,
                cv2.LINE_8)
    cv2.circle(canvas, (int(round(cx)), int(round(cy))), 2, color, cv2.FILLED)


def draw_tracks(image: np.ndarray, tracks: Iterable[TrackDrawing],
                thickness: int = 2) -> np.ndarray:
    """A copy of ``image`` with each track's box, kernels and ``id state score`` label."""
    canvas = as_canvas(image)
    for track in tracks:
        color = track_color(track.track_id)
        for kernel in track.kernels:
            _draw_kernel(canvas, kernel, color)
        corners = _finite_box(track.box)
        if corners is None:
            continue
        x0, y0, x1, y1 = corners
        cv2.rectangle(canvas, (x0, y0), (x1, y1), color, thickness, cv2.LINE_8)
        text = f"#{track.track_id}"
        if track.state:
            text += f" {track.state}"
        if track.score is not None and math.isfinite(float(track.score)):
            text += f" {float(track.score):.2f}"
        _label(canvas, text, x0, y0, color)
    return canvas


def draw_text_lines(image: np.ndarray, lines: Iterable[str],
                    color: BGR = (255, 255, 255)) -> np.ndarray:
    """A copy of ``image`` with ``lines`` written top-left on a dark background."""
    canvas = as_canvas(image)
    y = 4
    for line in lines:
        (tw, th), baseline = cv2.getTextSize(line, _FONT, 0.45, 1)
        cv2.rectangle(canvas, (2, y), (6 + tw, y + th + baseline + 2), (0, 0, 0), cv2.FILLED)
        cv2.putText(canvas, line, (4, y + th + 1), _FONT, 0.45, color, 1, cv2.LINE_AA)
        y += th + baseline + 4
    return canvas
