"""mk_tracker.evaluation.error_plots: per-frame counts by hand, and what each plot draws.

The PNGs are checked for their size; what is drawn is checked on the matplotlib figure
itself (its lines' data, labels, limits and title), caught just before it is saved.
"""

import cv2
import numpy as np
import pytest

from mk_tracker.evaluation import error_plots
from mk_tracker.evaluation.error_plots import (ErrorPlotError, MotFrameErrors, mot_frame_errors,
                                               plot_mot_errors, plot_single_target_errors)


@pytest.fixture
def drawn(monkeypatch):
    """Records every figure handed to ``_save``: per axis, ``{label: (x, y)}`` of its lines,
    the y limits and labels, and the figure title."""
    figures = []
    save = error_plots._save

    def spy(fig, overlap_axis, ylabel, xlabel, title, path):
        out = save(fig, overlap_axis, ylabel, xlabel, title, path)
        axes = []
        for ax in fig.axes:
            lines = {}
            for k, line in enumerate(ax.get_lines()):
                label = line.get_label()
                key = label if not label.startswith("_") else f"line{k}"
                lines[key] = (np.asarray(line.get_xdata(), float),
                              np.asarray(line.get_ydata(), float))
            axes.append(dict(lines=lines, ylim=ax.get_ylim(), ylabel=ax.get_ylabel(),
                             xlabel=ax.get_xlabel()))
        figures.append(dict(axes=axes, title=fig._suptitle.get_text()))
        return out

    monkeypatch.setattr(error_plots, "_save", spy)
    return figures


def _equal(actual, expected):
    np.testing.assert_allclose(actual, expected, atol=1e-12)


def test_single_target_plot_draws_errors_misses_and_overlaps(tmp_path, drawn):
    out = plot_single_target_errors([1.0, float("inf"), 30.0], [0.9, 0.0, 0.4],
                                    tmp_path / "single.png", title="walk")
    image = cv2.imread(str(out))
    assert out == tmp_path / "single.png"
    assert image is not None and image.shape[:2] == (450, 810)       # 9 x 5 in at 90 dpi
    (fig,) = drawn
    assert fig["title"] == "walk"
    top, bottom = fig["axes"]
    # centre error at the frames with a box (1 and 3); frame 2 (no box) is a cross drawn
    # at 1.1 x the largest finite error (30 > the 20 px threshold): 33
    _equal(top["lines"]["centre error"][0], [1, 3])
    _equal(top["lines"]["centre error"][1], [1.0, 30.0])
    _equal(top["lines"]["no box"][0], [2])
    _equal(top["lines"]["no box"][1], [33.0])
    _equal(top["lines"]["20 px"][1], [20.0, 20.0])
    assert top["ylabel"] == "centre error (px)"
    # IoU of every frame, on [0, 1], with the 0.5 success line
    _equal(bottom["lines"]["line0"][0], [1, 2, 3])
    _equal(bottom["lines"]["line0"][1], [0.9, 0.0, 0.4])
    _equal(bottom["lines"]["line1"][1], [0.5, 0.5])
    assert bottom["ylim"] == (0.0, 1.0)
    assert (bottom["ylabel"], bottom["xlabel"]) == ("IoU", "frame (with ground truth)")


def test_single_target_plot_without_any_box_puts_the_crosses_above_the_threshold(
        tmp_path, drawn):
    # no finite error: the crosses sit at 1.1 x the threshold (15 px) = 16.5
    plot_single_target_errors([float("inf")] * 2, [0.0, 0.0], tmp_path / "none.png",
                              threshold=15.0)
    (fig,) = drawn
    top = fig["axes"][0]
    assert len(top["lines"]["centre error"][0]) == 0
    _equal(top["lines"]["no box"][1], [16.5, 16.5])
    assert "15 px" in top["lines"]
    assert fig["title"] == "single-target errors per frame"


def test_single_target_plot_refuses_bad_input(tmp_path):
    with pytest.raises(ErrorPlotError, match="equally long"):
        plot_single_target_errors([1.0, 2.0], [0.5], tmp_path / "bad.png")
    with pytest.raises(ErrorPlotError):
        plot_single_target_errors([], [], tmp_path / "empty.png")
    assert not (tmp_path / "bad.png").exists() and not (tmp_path / "empty.png").exists()


def test_mot_plot_draws_counts_errors_and_overlap(tmp_path, drawn):
    errors = MotFrameErrors(frames=np.array([1, 2, 3]), objects=np.array([2, 2, 2]),
                            matches=np.array([2, 1, 2]), misses=np.array([0, 1, 0]),
                            false_positives=np.array([0, 0, 1]), switches=np.array([0, 0, 1]),
                            mean_iou=np.array([0.8, np.nan, 0.7]))
    out = plot_mot_errors(errors, tmp_path / "mot.png")
    image = cv2.imread(str(out))
    assert image is not None and image.shape[:2] == (630, 810)        # 9 x 7 in at 90 dpi
    (fig,) = drawn
    assert fig["title"] == "per-frame tracking errors"
    counts, errs, overlap = fig["axes"]
    _equal(counts["lines"]["ground-truth objects"][1], [2, 2, 2])
    _equal(counts["lines"]["matched"][1], [2, 1, 2])
    _equal(errs["lines"]["misses"][1], [0, 1, 0])
    _equal(errs["lines"]["false positives"][1], [0, 0, 1])
    # an identity switch is a cross at the frames that have one (frame 3) only
    _equal(errs["lines"]["ID switches"][0], [3])
    _equal(errs["lines"]["ID switches"][1], [1])
    _equal(overlap["lines"]["line0"][0], [1, 2, 3])
    _equal(overlap["lines"]["line0"][1], [0.8, np.nan, 0.7])
    assert overlap["ylim"] == (0.0, 1.0)
    assert overlap["ylabel"] == "mean IoU of matches"


def test_mot_frame_errors_by_hand():
    import motmetrics as mm
    nan = np.nan
    acc = mm.MOTAccumulator(auto_id=False)
    # frame 1: both objects matched, distances 0.2 and 0.4 -> IoUs 0.8, 0.6, mean 0.7
    acc.update([1, 2], [10, 20], [[0.2, nan], [nan, 0.4]], frameid=1)
    # frame 2: object 1 matched (IoU 0.9), object 2 missed
    acc.update([1, 2], [10], [[0.1], [nan]], frameid=2)
    # frame 3: object 1 now on hypothesis 20 (a switch, still a match: IoU 0.7),
    # object 2 missed, hypothesis 30 a false positive
    acc.update([1, 2], [20, 30], [[0.3, nan], [nan, nan]], frameid=3)
    # frame 4: object 1 missed, nothing matched: no mean IoU (NaN)
    acc.update([1], [], np.zeros((1, 0)), frameid=4)
    e = mot_frame_errors(acc)
    _equal(e.frames, [1, 2, 3, 4])
    _equal(e.objects, [2, 2, 2, 1])
    _equal(e.matches, [2, 1, 1, 0])
    _equal(e.misses, [0, 1, 1, 1])
    _equal(e.false_positives, [0, 0, 1, 0])
    _equal(e.switches, [0, 0, 1, 0])
    _equal(e.mean_iou, [0.7, 0.9, 0.7, nan])


def test_mot_frame_errors_of_an_empty_accumulator_is_our_error():
    import motmetrics as mm
    with pytest.raises(ErrorPlotError):
        mot_frame_errors(mm.MOTAccumulator(auto_id=False))
