"""Shadow and highlight test of foreground pixels against the background image, by the
brightness and chromaticity distortions of Horprasert, Harwood & Davis (1999).

A pixel ``I`` over the background colour ``B`` (both colour vectors) has

* brightness distortion ``a = (I . B) / (B . B)``: the scale of ``B`` closest to ``I``
  (``a < 1`` darker, ``a > 1`` brighter), and
* chromaticity distortion ``c = |I - a B| / (a |B|)``: how far ``I`` is from the line of
  ``B``'s colour, relative to its brightness (the tangent of the angle between the two).

A cast shadow darkens the surface without changing its colour much: ``a`` in
``[min_ratio, max_ratio]`` and ``c <= max_chroma``.  A highlight (a lamp, sun from a cloud
gap) brightens it the same way: ``a`` in ``(1, highlight_ratio]``.  On a grey image
``c`` is 0, so the test is on brightness alone.

OpenCV's MOG2 has its own shadow test (``detectShadows``, ``shadowThreshold``): ``a`` in
``[threshold, 1]`` with the colour distance measured in the model's variance.  The
background detector takes either (``background.shadow_method``);
docs/benchmark_background_detector.md compares them.
"""

from __future__ import annotations

import numpy as np

__all__ = ["shadow_or_highlight"]


def shadow_or_highlight(image: np.ndarray, background: np.ndarray, foreground: np.ndarray,
                        min_ratio: float, max_ratio: float, highlight_ratio: float,
                        max_chroma: float) -> np.ndarray:
    """Boolean mask (image shape, without channels) of the ``foreground`` pixels of
    ``image`` that are a shadow or a highlight on ``background`` (same shape, uint8)."""
    out = np.zeros(foreground.shape, dtype=bool)
    rows, cols = np.nonzero(foreground)
    if rows.size == 0:
        return out
    pix = image[rows, cols].astype(np.float32).reshape(rows.size, -1)
    bg = background[rows, cols].astype(np.float32).reshape(rows.size, -1)
    bb = np.einsum("ij,ij->i", bg, bg)
    ratio = np.einsum("ij,ij->i", pix, bg) / np.maximum(bb, 1.0)
    residual = pix - ratio[:, None] * bg
    chroma = np.sqrt(np.einsum("ij,ij->i", residual, residual)) / np.maximum(
        ratio * np.sqrt(bb), 1.0)
    same_colour = (chroma <= max_chroma) & (bb >= 1.0)     # a black background has no colour
    shadow = (ratio >= min_ratio) & (ratio <= max_ratio)
    highlight = (ratio > 1.0) & (ratio <= highlight_ratio)
    out[rows, cols] = same_colour & (shadow | highlight)
    return out
