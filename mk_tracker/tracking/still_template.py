"""Is a person who stopped still where they were last detected?  A grey template test.

A background-subtraction detector absorbs a person who stands still into its model within
seconds, and the kernel covariance detector (Schizas, Maroulas & Ren 2018) finds only what
moves: after the last detection a standing person's track lives on its multiple-kernel
appearance alone (Chu, Hwang, Pai & Lan, IEEE TMM 2013, Sec. IV-D: the kernel similarities
``rho_i = exp(-J_i)`` of (5)-(7) decide whether the target is visible).  On small people
(15-20 px wide) in a light that changes, those similarities hover around
``occlusion_similarity`` and one frame below it ends the track
(docs/benchmark_background_detector.md, "Issue #13's kind of sequence").

This test asks a narrower question than the colour model does: are the pixels where the
person was last detected the same pixels now?  The grey template of the detected box (its
central ``CENTRAL_WIDTH`` of the width, where the person is, over the full height) is kept
from the frame of the track's latest detection, and compared with the same place in the
current frame by the normalised cross-correlation coefficient (OpenCV's
``TM_CCOEFF_NORMED``: invariant to a gain and an offset of the intensities, so a fading
light does not change it).  A person who stays keeps it near 1; one who leaves uncovers
background, which does not correlate with a person; one who passes in front lowers it for
as long as they pass.  This is the stationarity test of static-object detection (a region
that differs from the background but not from its own recent past, Porikli, Ivanov & Haga,
EURASIP JASP 2008), asked of a track instead of a pixel.

Used by :class:`~mk_tracker.tracking.multi_object_tracker.MultiObjectTracker` for still
undetected tracks (``lifecycle.still_template``; 0 = off).  Pure functions.
"""

from __future__ import annotations

from typing import Sequence

import cv2
import numpy as np

#: Fraction of the box width (centred) that the template covers: a detection box of a
#: walking person holds background on both sides of the body.
CENTRAL_WIDTH = 0.6

#: Fewest pixels along each side of a template: below this, a correlation says nothing.
MIN_SIDE = 3


def template_window(box: Sequence[float], width: int, height: int
                    ) -> tuple[int, int, int, int] | None:
    """Integer ``(x0, y0, x1, y1)`` of the central ``CENTRAL_WIDTH`` of ``box`` (x, y, w, h),
    clipped to a ``width`` x ``height`` image; None when fewer than ``MIN_SIDE`` pixels
    remain along a side or the box is not finite."""
    x, y, w, h = (float(v) for v in box)
    if not all(np.isfinite([x, y, w, h])) or w <= 0 or h <= 0:
        return None
    margin = w * (1.0 - CENTRAL_WIDTH) / 2.0
    x0 = max(int(round(x + margin)), 0)
    x1 = min(int(round(x + w - margin)), width)
    y0 = max(int(round(y)), 0)
    y1 = min(int(round(y + h)), height)
    if x1 - x0 < MIN_SIDE or y1 - y0 < MIN_SIDE:
        return None
    return x0, y0, x1, y1


def grey_template(image: np.ndarray, box: Sequence[float]
                  ) -> tuple[tuple[int, int, int, int], np.ndarray] | None:
    """``(window, grey float32 pixels)`` of ``box`` in ``image`` (BGR or single channel), or
    None when the window is too small (:func:`template_window`)."""
    window = template_window(box, image.shape[1], image.shape[0])
    if window is None:
        return None
    x0, y0, x1, y1 = window
    crop = image[y0:y1, x0:x1]
    if crop.ndim == 3 and crop.shape[2] == 3:
        crop = cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY)
    elif crop.ndim == 3:
        crop = crop[..., 0]
    return window, np.ascontiguousarray(crop, dtype=np.float32)


def template_correlation(image: np.ndarray,
                         template: tuple[tuple[int, int, int, int], np.ndarray]) -> float:
    """Normalised cross-correlation coefficient in [-1, 1] between ``template`` (from
    :func:`grey_template`) and the same window of ``image``; 0 when either is uniform
    (nothing to correlate) or the window no longer fits the image."""
    (x0, y0, x1, y1), pixels = template
    if y1 > image.shape[0] or x1 > image.shape[1]:
        return 0.0
    crop = image[y0:y1, x0:x1]
    if crop.ndim == 3 and crop.shape[2] == 3:
        crop = cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY)
    elif crop.ndim == 3:
        crop = crop[..., 0]
    crop = np.ascontiguousarray(crop, dtype=np.float32)
    if float(crop.std()) < 1e-3 or float(pixels.std()) < 1e-3:
        return 0.0
    score = float(cv2.matchTemplate(crop, pixels, cv2.TM_CCOEFF_NORMED)[0, 0])
    return score if np.isfinite(score) else 0.0
