"""Shadow/highlight ratio test (Horprasert et al. 1999) on hand-computed pixels."""

from __future__ import annotations

import numpy as np

from mk_tracker.detection.shadows import shadow_or_highlight


def test_ratio_and_chroma_decide_on_hand_computed_pixels():
    background = np.array([[[100, 100, 100], [100, 50, 20], [100, 100, 100],
                            [100, 100, 100], [100, 100, 100], [0, 0, 0]]], np.uint8)
    image = np.array([[[70, 70, 70],       # 0.7 x grey: a shadow
                       [70, 35, 14],       # 0.7 x the colour: a shadow
                       [30, 30, 30],       # 0.3: darker than any shadow, a person
                       [120, 120, 120],    # 1.2: a highlight when allowed
                       [100, 40, 100],     # another colour at about the same brightness
                       [10, 10, 10]]],     # on a black background: no colour, kept
                     np.uint8)
    everything = np.ones((1, 6), np.uint8)
    got = shadow_or_highlight(image, background, everything, min_ratio=0.5, max_ratio=0.95,
                              highlight_ratio=1.0, max_chroma=0.1)
    assert got.tolist() == [[True, True, False, False, False, False]]
    got = shadow_or_highlight(image, background, everything, min_ratio=0.5, max_ratio=0.95,
                              highlight_ratio=1.3, max_chroma=0.1)
    assert got.tolist() == [[True, True, False, True, False, False]]
    # pixel 4: a = (100*100 + 40*100 + 100*100) / 30000 = 0.8, residual (20, -40, 20),
    # |residual| / (a |B|) = 48.99 / 138.6 = 0.354: a shadow only with max_chroma >= 0.354
    loose = shadow_or_highlight(image, background, everything, min_ratio=0.5, max_ratio=0.95,
                                highlight_ratio=1.0, max_chroma=0.36)
    tight = shadow_or_highlight(image, background, everything, min_ratio=0.5, max_ratio=0.95,
                                highlight_ratio=1.0, max_chroma=0.35)
    assert loose[0, 4] and not tight[0, 4]


def test_only_foreground_pixels_are_tested_and_grey_images_work():
    background = np.full((2, 3), 100, np.uint8)
    image = np.full((2, 3), 70, np.uint8)                   # a shadow everywhere
    foreground = np.array([[1, 0, 1], [0, 0, 0]], np.uint8)
    got = shadow_or_highlight(image, background, foreground, 0.5, 0.95, 1.0, 0.1)
    assert got.tolist() == [[True, False, True], [False, False, False]]
    empty = shadow_or_highlight(image, background, np.zeros((2, 3), np.uint8), 0.5, 0.95,
                                1.0, 0.1)
    assert not empty.any()
