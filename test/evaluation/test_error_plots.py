"""mk_tracker.evaluation.error_plots: the two per-frame error plots are written as PNGs of their size."""

import cv2
import numpy as np
import pytest

from mk_tracker.evaluation.error_plots import (ErrorPlotError, MotFrameErrors, plot_mot_errors,
                                    plot_single_target_errors)


def test_single_target_plot_is_a_png_and_bad_input_is_our_error(tmp_path):
    out = plot_single_target_errors([1.0, float("inf"), 30.0], [0.9, 0.0, 0.4],
                                    tmp_path / "single.png", title="walk")
    image = cv2.imread(str(out))
    assert out == tmp_path / "single.png"
    assert image is not None and image.shape[:2] == (450, 810)       # 9 x 5 in at 90 dpi
    with pytest.raises(ErrorPlotError, match="equally long"):
        plot_single_target_errors([1.0, 2.0], [0.5], tmp_path / "bad.png")
    assert not (tmp_path / "bad.png").exists()


def test_mot_plot_is_a_png(tmp_path):
    errors = MotFrameErrors(frames=np.array([1, 2, 3]), objects=np.array([2, 2, 2]),
                            matches=np.array([2, 1, 2]), misses=np.array([0, 1, 0]),
                            false_positives=np.array([0, 0, 1]), switches=np.array([0, 0, 1]),
                            mean_iou=np.array([0.8, np.nan, 0.7]))
    out = plot_mot_errors(errors, tmp_path / "mot.png")
    image = cv2.imread(str(out))
    assert image is not None and image.shape[:2] == (630, 810)        # 9 x 7 in at 90 dpi
