"""Ghosts of the background model: foreground that does not move, found per pixel and put
back into the background at once (issue #13, real video with people in view from the
first frame).

A *ghost* (Cucchiara, Grana, Piccardi & Prati 2003, "Detecting moving objects, ghosts and
shadows in video streams", IEEE TPAMI 25(10)) is foreground where the model, not the
scene, is wrong: a person who stood in the start-up frames is in the background, and when
they walk away the ground they uncover differs from the model.  Cucchiara et al. tell a
ghost from a moving object by its lack of motion (the mean optical flow of the object) and
reset a ghost's pixels into the background at once, instead of waiting for the model's
slow update.  Here the motion is measured per pixel by differencing: a pixel whose value
has stayed within ``tolerance`` of its value at a start time is *still* since then
(:class:`StillPixels`), and a foreground region (8-connected) with at least ``ghost_share``
of its pixels still for ``ghost_time`` seconds is a ghost (:func:`ghost_blobs`; a test per
pixel absorbed the uniform inside of walkers' clothes and lost more).
A person who walks keeps changing the pixels at their edges and, at the detector's frame
rates, most of their inside (texture, limbs, shading); a person who stands still for
``ghost_time`` becomes background, which the detector's design already accepts (the
tracker coasts them), only sooner.

:func:`absorb` puts the ghost pixels into OpenCV's model.  MOG2 and KNN have no learning
rate per pixel, so the model is updated once more with a composite frame: the current frame
at the ghosts and at the pixels the model already calls background, and the model's own
background image at the other foreground pixels (people, shadows), at learning rate
``rate``.  A ghost pixel gets a new mode of weight ``rate``; with OpenCV's background ratio
0.9 a mode whose heavier modes weigh less than 0.9 is background, so ``rate`` above 0.1
makes the ghost background at once, while the old mode (now ``1 - rate``) stays background
too (the person learnt at start-up does not come back as a ghost when the ground returns).
Background pixels get one ordinary update; people are not learnt.  Or
(``ghost_reset: memory``) the model is left alone and :class:`GhostMemory` holds the ghost
values as background beside it.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

__all__ = ["GhostMemory", "StillPixels", "absorb", "ghost_blobs"]


class StillPixels:
    """Per pixel of a frame stream: the time since its value last moved more than
    ``tolerance`` grey levels (any channel) away from the value it had then."""

    def __init__(self, tolerance: float) -> None:
        self.tolerance = float(tolerance)
        self._reference: np.ndarray | None = None
        self._since: np.ndarray | None = None

    def update(self, frame: np.ndarray, t: float) -> np.ndarray:
        """Seconds each pixel of ``frame`` (uint8, grey or colour) has been still at time
        ``t`` (seconds, increasing); 0 for a pixel that changed now.  A frame of another
        shape starts again."""
        if self._reference is None or self._reference.shape != frame.shape:
            self._reference = frame.copy()
            self._since = np.full(frame.shape[:2], t, dtype=np.float64)
            return np.zeros(frame.shape[:2], dtype=np.float64)
        diff = cv2.absdiff(frame, self._reference)
        if diff.ndim == 3:
            diff = np.maximum(np.maximum(diff[:, :, 0], diff[:, :, 1]), diff[:, :, 2])
        moved = diff > self.tolerance
        np.copyto(self._reference, frame, where=moved[:, :, None] if frame.ndim == 3
                  else moved)
        np.copyto(self._since, t, where=moved)
        return t - self._since


def ghost_blobs(foreground: np.ndarray, still: np.ndarray, min_still: float,
                min_share: float, min_pixels: int) -> np.ndarray:
    """Bool mask of the connected ``foreground`` regions (8-connected) of at least
    ``min_pixels`` whose share of pixels still for ``min_still`` seconds or more is at
    least ``min_share``: Cucchiara et al.'s motion test of an object, with the share of
    still pixels for its mean optical flow.  A walking person's blob has moving edges and
    limbs; the ground uncovered where a learnt person stood does not move at all."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(foreground.astype(np.uint8),
                                                           connectivity=8)
    if n <= 1:
        return np.zeros(foreground.shape, dtype=bool)
    still_count = np.bincount(labels.ravel(), weights=(still >= min_still).ravel(),
                              minlength=n)
    area = stats[:, cv2.CC_STAT_AREA].astype(np.float64)
    is_ghost = (still_count >= min_share * area) & (area >= min_pixels)
    is_ghost[0] = False
    return is_ghost[labels]


def absorb(model: Any, frame: np.ndarray, raw: np.ndarray, ghost: np.ndarray,
           rate: float) -> None:
    """Learn the ``ghost`` pixels (bool, frame's height and width) of ``frame`` into the
    OpenCV background ``model`` at once, without learning the other foreground of ``raw``
    (the model's mask of this frame: 0 background, else foreground or shadow)."""
    keep = (raw != 0) & ~ghost
    composite = frame.copy()
    if keep.any():
        background = model.getBackgroundImage()
        composite[keep] = background[keep]
    model.apply(composite, learningRate=float(rate))


class GhostMemory:
    """Ghost pixels held as background beside the OpenCV model, without touching it: a
    ghost pixel's value is kept, and while the frame stays within ``tolerance`` of it the
    pixel is background; it is forgotten once the model itself calls it background (its
    own update has caught up) or the frame leaves the value (a person walks over it)."""

    def __init__(self, tolerance: float) -> None:
        self.tolerance = float(tolerance)
        self._value: np.ndarray | None = None
        self._held: np.ndarray | None = None

    def add(self, frame: np.ndarray, ghost: np.ndarray) -> None:
        if self._value is None or self._value.shape != frame.shape:
            self._value = frame.copy()
            self._held = np.zeros(frame.shape[:2], dtype=bool)
        np.copyto(self._value, frame, where=ghost[:, :, None] if frame.ndim == 3 else ghost)
        self._held |= ghost

    def background(self, frame: np.ndarray, foreground: np.ndarray) -> np.ndarray:
        """Bool mask of the ``foreground`` pixels held as ghosts and unchanged."""
        if self._held is None or self._value.shape != frame.shape:
            return np.zeros(foreground.shape, dtype=bool)
        self._held &= foreground
        diff = cv2.absdiff(frame, self._value)
        if diff.ndim == 3:
            diff = np.maximum(np.maximum(diff[:, :, 0], diff[:, :, 1]), diff[:, :, 2])
        self._held &= diff <= self.tolerance
        return self._held.copy()
