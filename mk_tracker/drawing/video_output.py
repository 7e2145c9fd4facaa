"""Annotated MP4 video output (OpenCV ``VideoWriter``, ``mp4v`` codec).

:class:`VideoOutput` checks that the writer really opened (OpenCV returns a closed writer
instead of raising when a codec or path is unusable), writes BGR uint8 frames of one size
(other sizes are resized to the first frame's, so one odd frame does not end the video) and
counts the frames written.  :func:`count_video_frames` reads a video back frame by frame.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np


class VideoOutputError(ValueError):
    """The video cannot be opened or a frame cannot be written."""


class VideoOutput:
    """An MP4 file being written; use as a context manager.  Opens on the first frame."""

    def __init__(self, path: str | Path, fps: float, fourcc: str = "mp4v") -> None:
        if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
            raise VideoOutputError(f"video frame rate must be a positive number, got {fps!r}")
        if len(fourcc) != 4:
            raise VideoOutputError(f"fourcc must be 4 characters, got {fourcc!r}")
        self.path = Path(path)
        if not self.path.parent.is_dir():
            raise VideoOutputError(f"{self.path.parent} is not a directory")
        self.fps = float(fps)
        self.fourcc = fourcc
        self.size: tuple[int, int] | None = None
        self.frames = 0
        self.resized = 0
        self._writer: cv2.VideoWriter | None = None

    def write(self, frame: np.ndarray) -> None:
        """Append one BGR uint8 frame (gray frames are converted)."""
        if not isinstance(frame, np.ndarray) or frame.dtype != np.uint8 or frame.ndim not in (2, 3):
            raise VideoOutputError("a video frame must be a uint8 (h, w) or (h, w, 3) array")
        if frame.ndim == 2:
            frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        if frame.shape[2] != 3 or frame.shape[0] < 2 or frame.shape[1] < 2:
            raise VideoOutputError(f"cannot write a frame of shape {frame.shape}")
        if self._writer is None:
            self.size = (int(frame.shape[1]), int(frame.shape[0]))
            self._writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*self.fourcc),
                                           self.fps, self.size)
            if not self._writer.isOpened():
                self._writer = None
                raise VideoOutputError(f"OpenCV cannot open {self.path} for writing with codec "
                                       f"{self.fourcc!r}")
        if (frame.shape[1], frame.shape[0]) != self.size:
            frame = cv2.resize(frame, self.size, interpolation=cv2.INTER_AREA)
            self.resized += 1
        self._writer.write(np.ascontiguousarray(frame))
        self.frames += 1

    def close(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None

    def __enter__(self) -> "VideoOutput":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def count_video_frames(path: str | Path) -> int:
    """Number of frames OpenCV decodes from the video at ``path`` (read one by one)."""
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise VideoOutputError(f"OpenCV cannot open {path} for reading")
    n = 0
    try:
        while True:
            ok, _ = cap.read()
            if not ok:
                break
            n += 1
    finally:
        cap.release()
    return n
