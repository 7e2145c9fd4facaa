"""Frames of a video file or of a plain image folder: the one reader behind ``mk_tracker
import`` for recordings without annotations (RGB or thermal, issues #13 and #19).

* A **video file** (``.mp4``, ``.avi``, ``.mkv``, ``.mov``, ...) is decoded by OpenCV's
  ``VideoCapture`` (a maintained decoder: FFmpeg where OpenCV has it); its frame rate is
  the container's ``CAP_PROP_FPS``.  A frame the decoder cannot read ends the video early,
  and :attr:`FrameSource.unreadable` tells how many frames the container declared but did
  not give.
* An **image folder** holds one image per frame (``.png``, ``.tif``/``.tiff``, ``.jpg``,
  ``.bmp``, ``.pgm``), in natural name order (``frame_2`` before ``frame_10``).  Images are
  read unchanged, so 16-bit PNG/TIFF thermal frames keep their 16 bits.  An unreadable
  file is skipped and counted (:attr:`FrameSource.unreadable`); every frame must have the
  first frame's size and channel count, or :class:`FrameSourceError` says which does not.
  A folder has no frame rate: the caller gives one.

Frames come out as numpy arrays: ``HxW`` (grey, uint8 or uint16) or ``HxWx3`` BGR uint8.
No rclpy in here.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm", ".mpg", ".mpeg", ".wmv")
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg", ".bmp", ".pgm", ".ppm")


class FrameSourceError(ValueError):
    """A video or image folder that cannot be read as a sequence of frames."""


def _natural_key(path: Path) -> list:
    return [int(part) if part.isdigit() else part.lower()
            for part in re.split(r"(\d+)", path.name)]


def is_video_file(path: str | Path) -> bool:
    """Whether ``path`` is a file with a video suffix."""
    p = Path(path)
    return p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES


def image_files(folder: str | Path) -> list[Path]:
    """The image files directly in ``folder``, in natural name order."""
    root = Path(folder)
    return sorted((p for p in root.iterdir()
                   if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES), key=_natural_key)


def _normalised(frame: np.ndarray) -> np.ndarray:
    """Grey images as ``HxW``; 3- and 4-channel images as BGR ``HxWx3``."""
    if frame.ndim == 3 and frame.shape[2] == 1:
        return frame[:, :, 0]
    if frame.ndim == 3 and frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    return frame


@dataclass
class FrameSource:
    """A sequence of frames with a frame rate (``None`` for a folder until the caller sets
    one).  ``declared`` is the number of frames the container or folder announces;
    :meth:`frames` may give fewer (``unreadable`` counts them once iterated)."""

    path: Path
    kind: str                                 # "video" | "folder"
    fps: float | None
    declared: int
    unreadable: int = 0
    _files: list[Path] = field(default_factory=list, repr=False)

    def frames(self) -> Iterator[np.ndarray]:
        """Every readable frame, in order (see the module docstring for what is skipped)."""
        self.unreadable = 0
        if self.kind == "video":
            yield from self._video_frames()
        else:
            yield from self._folder_frames()

    def _video_frames(self) -> Iterator[np.ndarray]:
        capture = cv2.VideoCapture(str(self.path))
        if not capture.isOpened():
            raise FrameSourceError(f"{self.path}: OpenCV cannot open this video")
        given = 0
        try:
            while True:
                ok, frame = capture.read()
                if not ok or frame is None:
                    break
                given += 1
                yield _normalised(frame)
        finally:
            capture.release()
        self.unreadable = max(0, self.declared - given)

    def _folder_frames(self) -> Iterator[np.ndarray]:
        shape = dtype = None
        for path in self._files:
            frame = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            if frame is None:
                self.unreadable += 1
                continue
            frame = _normalised(frame)
            if frame.dtype not in (np.uint8, np.uint16):
                raise FrameSourceError(f"{path}: {frame.dtype} pixels; 8- or 16-bit images "
                                       "are supported")
            if shape is None:
                shape, dtype = frame.shape, frame.dtype
            elif frame.shape != shape or frame.dtype != dtype:
                raise FrameSourceError(
                    f"{path}: {frame.shape} {frame.dtype} differs from the first frame's "
                    f"{shape} {dtype}; every frame of a folder must have the same size")
            yield frame


def open_frames(path: str | Path, fps: float | None = None) -> FrameSource:
    """A :class:`FrameSource` for a video file or an image folder.

    ``fps`` overrides the container's frame rate (a folder has none: it stays ``None`` when
    not given).  Raises :class:`FrameSourceError` for a missing path, an unknown suffix, an
    empty folder, a video OpenCV cannot open, or a bad ``fps``.
    """
    p = Path(path)
    if fps is not None and not (math.isfinite(float(fps)) and float(fps) > 0):
        raise FrameSourceError(f"the frame rate must be a positive number, got {fps}")
    if not p.exists():
        raise FrameSourceError(f"{p}: no such file or folder")
    if p.is_dir():
        files = image_files(p)
        if not files:
            raise FrameSourceError(f"{p}: no image files ({', '.join(IMAGE_SUFFIXES)})")
        return FrameSource(p, "folder", None if fps is None else float(fps), len(files),
                           _files=files)
    if p.suffix.lower() not in VIDEO_SUFFIXES:
        raise FrameSourceError(f"{p}: not a video file ({', '.join(VIDEO_SUFFIXES)}) and not "
                               "a folder")
    capture = cv2.VideoCapture(str(p))
    try:
        if not capture.isOpened():
            raise FrameSourceError(f"{p}: OpenCV cannot open this video")
        container_fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0)
        declared = int(capture.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    finally:
        capture.release()
    if fps is None:
        fps = container_fps if math.isfinite(container_fps) and container_fps > 0 else None
    return FrameSource(p, "video", None if fps is None else float(fps), max(declared, 0))


def to_thermal(frame: np.ndarray) -> tuple[np.ndarray, str]:
    """A frame as a thermal image and its ROS encoding: grey 8-bit -> ``mono8``, grey
    16-bit -> ``mono16``, BGR (a thermal video stored with 3 channels) -> its grey
    (``mono8``)."""
    if frame.ndim == 2:
        return frame, ("mono16" if frame.dtype == np.uint16 else "mono8")
    return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), "mono8"


def to_colour(frame: np.ndarray) -> np.ndarray:
    """A frame as ``bgr8``: grey is replicated (16-bit scaled to the frame's own 0.5-99.5 %
    range: a 16-bit frame has no fixed 8-bit meaning)."""
    if frame.ndim == 3:
        return frame
    if frame.dtype == np.uint16:
        lo, hi = np.percentile(frame, (0.5, 99.5))
        scale = 255.0 / max(float(hi - lo), 1.0)
        frame = np.clip((frame.astype(np.float32) - lo) * scale, 0, 255).astype(np.uint8)
    return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
