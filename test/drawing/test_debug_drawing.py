"""Debug drawing: what is drawn lands where the box/ellipse says, inputs stay untouched."""

import numpy as np
import pytest

from mk_tracker.drawing.debug_image import (DrawingError, KernelEllipse, TrackDrawing, as_canvas,
                                      draw_detections, draw_text_lines, draw_tracks,
                                      thermal_to_display, track_color)


def _black(h=120, w=160):
    return np.zeros((h, w, 3), np.uint8)


def test_detection_box_edges_are_drawn_in_the_colour_and_input_is_untouched():
    image = _black()
    out = draw_detections(image, [(40, 30, 50, 60)], color=(0, 0, 255))
    assert not image.any()
    # left edge x=40, rows inside the box (below the label); right edge x=90
    assert tuple(out[60, 40]) == (0, 0, 255)
    assert tuple(out[60, 90]) == (0, 0, 255)
    assert tuple(out[90, 65]) == (0, 0, 255)     # bottom edge y=90
    assert not out[60, 65].any()                 # interior not filled
    assert not out[10, 150].any()                # far away untouched


def test_score_label_is_written_near_the_box():
    plain = draw_detections(_black(), [(40, 50, 50, 40)])
    scored = draw_detections(_black(), [(40, 50, 50, 40)], scores=[0.87])
    diff = np.any(plain != scored, axis=2)
    rows, cols = np.nonzero(diff)
    assert rows.size > 0
    assert rows.max() <= 52 and cols.min() >= 38     # the label sits above the top-left


def test_bad_boxes_are_skipped_not_raised():
    image = _black()
    out = draw_detections(image, [(np.nan, 0, 10, 10), (5, 5, -3, 4), (np.inf, 1, 2, 3),
                                  (1e30, 1e30, 5, 5)])
    assert not out.any()


def test_scores_must_match_boxes():
    with pytest.raises(DrawingError):
        draw_detections(_black(), [(0, 0, 5, 5)], scores=[0.1, 0.2])


def test_gray_input_becomes_bgr_and_wrong_dtype_is_rejected():
    gray = np.full((20, 30), 7, np.uint8)
    canvas = as_canvas(gray)
    assert canvas.shape == (20, 30, 3) and np.all(canvas == 7)
    with pytest.raises(DrawingError):
        as_canvas(np.zeros((20, 30, 3), np.float32))
    with pytest.raises(DrawingError):
        as_canvas(np.zeros((0, 30, 3), np.uint8))
    with pytest.raises(DrawingError):
        as_canvas(np.zeros((20, 30, 4), np.uint8))


def test_track_kernels_are_drawn_as_ellipses_with_the_track_colour():
    color = track_color(7)
    track = TrackDrawing(box=(20, 20, 100, 80), track_id=7, state="tracked", score=0.9,
                         kernels=[KernelEllipse(center=(70, 60), axes=(20, 10), angle_deg=0)])
    out = draw_tracks(_black(), [track])
    # ellipse extremes: (70 +- 20, 60) and (70, 60 +- 10)
    for (x, y) in [(90, 60), (50, 60), (70, 70), (70, 50)]:
        patch = out[y - 1:y + 2, x - 1:x + 2].reshape(-1, 3)
        assert any(tuple(int(v) for v in p) == color for p in patch), (x, y)
    assert tuple(out[70, 20]) == color              # left box edge
    # between the ellipse and the box edge nothing is drawn
    assert not out[60, 35].any()


def test_track_label_contains_state_so_label_width_grows_with_text():
    short = draw_tracks(_black(200, 300), [TrackDrawing((50, 100, 60, 60), 3)])
    long = draw_tracks(_black(200, 300),
                       [TrackDrawing((50, 100, 60, 60), 3, state="occluded", score=0.5)])
    assert np.count_nonzero(long[80:100].any(axis=2)) > np.count_nonzero(short[80:100].any(axis=2))


def test_track_colours_are_stable_and_differ_between_ids():
    assert track_color(3) == track_color(3) == track_color("3")
    colours = {track_color(i) for i in range(1, 11)}
    assert len(colours) >= 8


def test_bad_kernels_are_skipped():
    track = TrackDrawing(box=(np.nan, 0, 1, 1), track_id=1,
                         kernels=[KernelEllipse((np.nan, 3), (2, 2)),
                                  KernelEllipse((10, 10), (0, 5)),
                                  KernelEllipse((10, 10), (1e9, 5))])
    assert not draw_tracks(_black(), [track]).any()


def test_thermal_display_handles_nan_and_16_bit():
    frame = np.zeros((30, 40), np.float32)
    frame[10:20, 10:20] = 37.0
    frame[0, 0] = np.nan
    out = thermal_to_display(frame, "32FC1")
    assert out.shape == (30, 40, 3) and out.dtype == np.uint8
    hot, cold = out[15, 15].astype(int), out[25, 35].astype(int)
    assert hot.sum() > cold.sum() + 100
    all_nan = thermal_to_display(np.full((8, 8), np.nan, np.float32), "32FC1", colormap=None)
    assert not all_nan.any()
    counts = (np.arange(64, dtype=np.uint16).reshape(8, 8) * 1000)
    gray = thermal_to_display(counts, "mono16", colormap=None)
    assert gray[0, 0, 0] == 0 and gray[7, 7, 0] == 255


def _bands(mask_rows):
    """Runs of consecutive True values in a 1-D mask, as (first, last) index pairs."""
    bands, start = [], None
    for i, on in enumerate(mask_rows):
        if on and start is None:
            start = i
        if not on and start is not None:
            bands.append((start, i - 1))
            start = None
    if start is not None:
        bands.append((start, len(mask_rows) - 1))
    return bands


def test_text_lines_are_written_top_left_one_below_the_other_in_the_colour():
    image = _black()
    out = draw_text_lines(image, ["frames 10", "dropped 2"], color=(0, 255, 0))
    assert not image.any()                                  # the input is untouched
    ink = out.any(axis=2)
    rows, cols = np.nonzero(ink)
    assert rows.max() < 40 and cols.min() < 10              # top-left corner
    assert not ink[:, 100:].any() and not ink[60:].any()    # nothing elsewhere
    # two lines: two bands of text rows with blank rows between them, each band a
    # plausible text height (a few to ~20 px at this font scale)
    bands = _bands(ink.any(axis=1))
    assert len(bands) == 2, bands
    assert all(3 <= last - first + 1 <= 20 for first, last in bands), bands
    # green text on black (anti-aliased: shades of green only), (nearly) full green in the
    # strokes: OpenCV 5 reaches 255, OpenCV 4.6 (Ubuntu 24.04) 252 with its anti-aliasing
    assert not out[..., 0].any() and not out[..., 2].any()
    assert out[..., 1].max() >= 240


def test_text_lines_get_a_dark_background_as_wide_as_the_text():
    white = np.full((60, 200, 3), 255, np.uint8)
    short = draw_text_lines(white, ["ab"])
    long = draw_text_lines(white, ["ab ab ab ab ab"])
    # on a white image the background box shows as black pixels around the text
    short_dark = np.nonzero((short == 0).all(axis=2).any(axis=0))[0]
    long_dark = np.nonzero((long == 0).all(axis=2).any(axis=0))[0]
    assert short_dark.size > 0 and short_dark.min() < 10
    assert long_dark.max() > short_dark.max() + 20          # 12 more characters
    assert (short[50:, :] == 255).all() and (short[:, 150:] == 255).all()
