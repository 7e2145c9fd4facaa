"""Kernel layouts (Chu 2013 Fig. 4, Fig. 14) generated from a box."""

import numpy as np
import pytest

from mk_tracker.boxes import InvalidBoxError
from mk_tracker.tracking.kernel_layouts import (SUPPORTED_KERNEL_COUNTS, kernel_layout,
                                       kernels_bounding_box, layout_fractions,
                                       max_pairwise_overlap)

BOX = (100.0, 50.0, 40.0, 120.0)


@pytest.mark.parametrize("n", SUPPORTED_KERNEL_COUNTS)
def test_layout_has_n_kernels_inside_the_box_and_spans_it(n):
    centres, axes = kernel_layout(BOX, n)
    assert centres.shape == (n, 2) and axes.shape == (n, 2)
    assert np.all(axes > 0)
    x, y, w, h = BOX
    assert np.all(centres[:, 0] - axes[:, 0] >= x - 1e-9)
    assert np.all(centres[:, 0] + axes[:, 0] <= x + w + 1e-9)
    assert np.all(centres[:, 1] - axes[:, 1] >= y - 1e-9)
    assert np.all(centres[:, 1] + axes[:, 1] <= y + h + 1e-9)
    # eq. (14): the kernels' extremes give back the box
    assert np.allclose(kernels_bounding_box(centres, axes), BOX)


@pytest.mark.parametrize("n", [2, 4, 5, 6])
def test_pairwise_overlap_is_limited(n):
    assert 0.0 < max_pairwise_overlap(n) <= 0.2


def test_two_kernels_are_upper_and_lower_55_percent():
    centres, axes = kernel_layout((0, 0, 10, 100), 2)
    assert np.allclose(centres[0] - axes[0], [0, 0])
    assert np.allclose(centres[0] + axes[0], [10, 55])
    assert np.allclose(centres[1] - axes[1], [0, 45])
    assert np.allclose(centres[1] + axes[1], [10, 100])


def test_four_kernels_form_a_two_by_two_grid():
    frac = layout_fractions(4)
    assert len({tuple(f[[0, 2]]) for f in frac}) == 2   # two columns
    assert len({tuple(f[[1, 3]]) for f in frac}) == 2   # two rows


def test_five_kernel_layout_has_one_full_width_top_kernel():
    frac = layout_fractions(5)
    assert np.allclose(frac[0], [0, 0, 1, 0.38])
    assert np.all(frac[1:, 1] > 0.3)


@pytest.mark.parametrize("n", [0, 3, 7])
def test_unsupported_counts_are_rejected(n):
    with pytest.raises(ValueError, match="num_kernels"):
        kernel_layout(BOX, n)


@pytest.mark.parametrize("box", [(0, 0, 0, 10), (0, 0, 10, -1), (np.nan, 0, 1, 1), (1, 2, 3)])
def test_bad_boxes_are_rejected(box):
    with pytest.raises(InvalidBoxError):
        kernel_layout(box, 2)
