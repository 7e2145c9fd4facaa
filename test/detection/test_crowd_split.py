"""Grouping K-means clusters into people in full-frame passes (``split_clusters``, issue
#15): :mod:`mk_tracker.detection.crowd_split`."""

from dataclasses import replace

import numpy as np
import pytest

from mk_tracker.detection.crowd_split import (is_sliver, join_pieces, leading_clusters,
                                              union_box)
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig

PERSON = (10.0, 60.0)        # expected width, height


def _known(_row):
    return PERSON


def test_union_box():
    assert union_box((0, 5, 4, 9), (2, 1, 10, 6)) == (0, 1, 10, 9)


def test_trailing_bands_are_not_people():
    # fractions of each cluster's support inside its own newest-frame footprint
    assert leading_clusters([0.9, 0.1, 0.5, 0.49], 0.5) == [0, 2]
    # a blob of trailing bands only stays one object: every cluster
    assert leading_clusters([0.1, 0.2], 0.5) == [0, 1]


def test_pieces_of_one_band_are_one_person():
    # three pieces of one leading band, stacked: union 5 x 60 px, within 1.6 x 10 by
    # 1.2 x 60
    boxes = [(10, 0, 14, 20), (10, 20, 14, 40), (11, 40, 15, 60)]
    assert join_pieces(boxes, _known, 1.6, 1.2) == [[0, 1, 2]]


def test_two_people_side_by_side_stay_two():
    # A at x 0..10, B at x 12..22, each cut in two pieces (top, bottom): a top of A with
    # a top of B is 22 px wide, above 1.6 x 10 = 16
    boxes = [(0, 0, 10, 30), (12, 0, 22, 30), (0, 30, 10, 60), (12, 30, 22, 60)]
    assert join_pieces(boxes, _known, 1.6, 1.2) == [[0, 2], [1, 3]]


def test_one_person_behind_another_stays_two():
    # same columns, rows 0..60 and 50..110: the union is 110 px tall, above 1.2 x 60 = 72
    boxes = [(0, 0, 10, 60), (0, 50, 10, 110)]
    assert join_pieces(boxes, _known, 1.6, 1.2) == [[0], [1]]


def test_closest_pieces_are_joined_first():
    # 0 and 1 touch (gap 0), 1 and 2 are 4 px apart; each pair fits one person, all three
    # do not (26 px wide): 0 + 1 first, then 2 cannot join them
    boxes = [(0, 0, 8, 60), (8, 0, 16, 60), (20, 0, 26, 60)]
    assert join_pieces(boxes, _known, 1.6, 1.2) == [[0, 1], [2]]


def test_without_a_learnt_size_the_blob_is_one_object():
    boxes = [(0, 0, 10, 30), (40, 0, 50, 30), (0, 80, 10, 110)]
    assert join_pieces(boxes, lambda _row: None, 1.6, 1.2) == [[0, 1, 2]]


def test_known_objects_are_kept_apart():
    # two stacked pieces that would fit one person, but each holds another known object
    boxes = [(10, 0, 14, 30), (10, 30, 14, 60)]
    assert join_pieces(boxes, _known, 1.6, 1.2, apart=lambda i, j: True) == [[0], [1]]
    assert join_pieces(boxes, _known, 1.6, 1.2, apart=lambda i, j: False) == [[0, 1]]


def test_slivers():
    # 0.5 of 10 x 60 is 5 x 30
    assert is_sliver(4.9, 60, 10, 60, 0.5)
    assert is_sliver(10, 29.9, 10, 60, 0.5)
    assert not is_sliver(5, 30, 10, 60, 0.5)


def test_apart_needs_a_prediction_each():
    det = ThermalDetector(ThermalDetectorConfig(window_margin=2))
    preds = np.array([[5.0, 5.0], [30.0, 5.0]])
    boxes = [(0, 0, 10, 10), (20, 0, 27, 10), (12, 0, 40, 10)]
    apart = det._apart(boxes, preds)
    # box 0 holds prediction 0; box 1 grown by 2 px (18..29) holds none; box 2 holds 1
    assert apart(0, 2) and apart(2, 0)
    assert not apart(0, 1) and not apart(1, 2)
    # with fewer than two objects there is nothing to keep apart
    assert det._apart(boxes, preds[:1]) is None


def _two_people_frames(n_frames=6, gap=0):
    """mono8 frames: background 40, two warm (200) people 10 x 40 px side by side,
    ``gap`` px apart, walking right at 2 px per frame from x = 20 (left person)."""
    frames = []
    for t in range(n_frames):
        f = np.full((80, 120), 40, dtype=np.uint8)
        x = 20 + 2 * t
        f[20:60, x:x + 10] = 200
        f[20:60, x + 10 + gap:x + 20 + gap] = 200
        frames.append(f)
    return frames


def _startup(config, frames, heights=None):
    det = ThermalDetector(replace(config, counts_fps=0.0))   # stamps at 10 Hz, frames counted
    if heights:
        for y_bottom, h in heights:
            det.heights.add(y_bottom, h)
    out = []
    for t, f in enumerate(frames):
        out = det.process(f, 0.1 * t, "mono8")
    assert det.last_mode == "startup"
    return out


def test_two_close_walkers_are_two_detections_with_split_clusters():
    # 3 px apart (within link_gap 4); touching people of one temperature would be one
    # wider person to any detector: only the outer edges of the pair change
    frames = _two_people_frames(gap=3)
    # the newest frame: people at x 30..40 and 43..53, rows 20..60
    learnt = [(60.0, 40.0)] * 5           # isolated people seen before: 40 px tall at row 60
    config = ThermalDetectorConfig(split_clusters=True, person_aspect=0.25)
    dets = _startup(config, frames, learnt)
    centres = sorted(d.centroid[0] for d in dets)
    assert len(dets) == 2
    assert 30.0 <= centres[0] <= 40.0 and 43.0 <= centres[1] <= 53.0
    # the defaults (link rule + footprint merge) report the pair as one object
    assert len(_startup(ThermalDetectorConfig(), frames)) == 1
    # without a learnt size, split_clusters keeps today's one object
    assert len(_startup(config, frames)) == 1


def test_split_clusters_turns_itself_off_while_the_size_fit_is_refused():
    # the pair of the test above.  Samples of one row, half and whole bodies (h 20 and 60,
    # mean 40 as above): relative residual spread 20 / 40 = 0.5, so with size_max_residual
    # 0.3 the learnt size is refused and the detector does as the defaults (one object)
    frames = _two_people_frames(gap=3)
    mixed = [(60.0, 20.0), (60.0, 60.0)] * 3
    strict = ThermalDetectorConfig(split_clusters=True, person_aspect=0.25,
                                   size_max_residual=0.3, size_min_samples=2.5)
    assert len(_startup(strict, frames, mixed)) == 1
    # the same samples under a lenient threshold: the mean height 40 is used, two people
    lenient = ThermalDetectorConfig(split_clusters=True, person_aspect=0.25,
                                    size_max_residual=0.6, size_min_samples=2.5)
    assert len(_startup(lenient, frames, mixed)) == 2
    # consistent samples but fewer than size_min_samples: refused too
    few = ThermalDetectorConfig(split_clusters=True, person_aspect=0.25,
                                size_max_residual=0.3, size_min_samples=8.0)
    assert len(_startup(few, frames, [(60.0, 40.0)] * 5)) == 1
    assert len(_startup(few, frames, [(60.0, 40.0)] * 9)) == 2


def test_one_walker_is_one_detection_with_split_clusters():
    # one 20 x 40 person (as wide as the pair above): its leading and trailing bands are
    # 20 px apart and the person is the expected size, so it stays one
    frames = []
    for t in range(6):
        f = np.full((80, 120), 40, dtype=np.uint8)
        f[20:60, 20 + 2 * t:40 + 2 * t] = 200
        frames.append(f)
    config = ThermalDetectorConfig(split_clusters=True, person_aspect=0.5)
    dets = _startup(config, frames, [(60.0, 40.0)] * 5)
    assert len(dets) == 1
    assert dets[0].box == pytest.approx((30.0, 20.0, 20.0, 40.0))


def _cand(box, n=100, centroid=None):
    from mk_tracker.detection.footprint_split import _Candidate
    x, y, w, h = box
    c = centroid if centroid is not None else (x + w / 2, y + h / 2)
    return _Candidate(c, box, 0.5, n, 1.0, 0.0)


def _sized_detector(**overrides):
    det = ThermalDetector(ThermalDetectorConfig(split_clusters=True, person_aspect=0.25,
                                                **overrides))
    for _ in range(5):
        det.heights.add(100.0, 40.0)      # every row: 40 px tall, so 10 px wide
    return det


def test_a_head_and_a_body_strip_are_one_person():
    det = _sized_detector()
    # a head 8 x 9 above a body strip 7 x 30: with 0.5 of 10 x 40 = 5 x 20, the head is a
    # sliver (9 < 20), the strip is not (7 >= 5, 30 >= 20)
    head = _cand((12.0, 60.0, 8.0, 9.0), n=50, centroid=(16.0, 64.0))
    body = _cand((10.0, 69.0, 7.0, 30.0), n=150, centroid=(13.0, 84.0))
    out = det._without_slivers([head, body])
    assert len(out) == 1
    # union 10..20 x 60..99: 10 x 39 fits 1.6 x 10 by 1.2 x 40; centroid pixel-weighted
    assert out[0].box == (10.0, 60.0, 10.0, 39.0)
    assert out[0].centroid == pytest.approx(((16 * 50 + 13 * 150) / 200,
                                             (64 * 50 + 84 * 150) / 200))
    assert out[0].pixel_count == 200


def test_two_people_side_by_side_are_not_slivers_of_each_other():
    det = _sized_detector()
    a = _cand((0.0, 60.0, 10.0, 40.0))
    b = _cand((11.0, 60.0, 10.0, 40.0))
    assert det._without_slivers([a, b]) == [a, b]


def test_a_sliver_too_far_to_fit_one_person_stays():
    det = _sized_detector()
    person = _cand((0.0, 60.0, 10.0, 40.0))
    far = _cand((30.0, 60.0, 3.0, 40.0))      # union 33 px wide, above 1.6 x 10
    assert det._without_slivers([person, far]) == [person, far]


def test_a_box_mostly_inside_another_is_joined():
    det = _sized_detector(sliver_overlap=0.5)
    big = _cand((0.0, 60.0, 12.0, 40.0))
    # 8 x 24 with 6 x 24 inside the big box: 0.75 inside; not a sliver by size
    inner = _cand((6.0, 70.0, 8.0, 24.0))
    out = det._without_slivers([big, inner])
    assert [c.box for c in out] == [(0.0, 60.0, 14.0, 40.0)]
    # at 1 (never) they stay two
    det = _sized_detector(sliver_overlap=1.0)
    assert len(det._without_slivers([big, inner])) == 2


def test_join_pieces_slack_widens_both_limits():
    # 20 px wide: above 1.6 x 10 = 16, within 16 + 5
    boxes = [(0, 0, 10, 60), (10, 0, 20, 60)]
    assert join_pieces(boxes, _known, 1.6, 1.2) == [[0], [1]]
    assert join_pieces(boxes, _known, 1.6, 1.2, slack=5.0) == [[0, 1]]
    # 80 px tall: above 1.2 x 60 = 72, within 72 + 8
    tall = [(0, 0, 10, 40), (0, 40, 10, 80)]
    assert join_pieces(tall, _known, 1.6, 1.2) == [[0], [1]]
    assert join_pieces(tall, _known, 1.6, 1.2, slack=8.0) == [[0, 1]]


def test_motion_slack_is_the_fastest_inside_object_times_the_window():
    det = ThermalDetector(ThermalDetectorConfig(startup_frames=6))
    for t in range(6):                          # stamps 0.0 .. 0.5 s: span 0.5 s
        det._window.add(np.zeros((4, 4), np.float32), 0.1 * t)
    # (x, y, vx, vy): 50 px/s and 30 * sqrt(2) px/s inside, 200 px/s outside
    preds = np.array([[5.0, 5.0, 30.0, 40.0], [15.0, 5.0, 30.0, 30.0],
                      [100.0, 5.0, 200.0, 0.0]])
    boxes = [(0, 0, 10, 10), (10, 0, 20, 10)]
    assert det._motion_slack(boxes, preds) == pytest.approx(50.0 * 0.5)
    assert det._motion_slack(boxes, preds[2:]) == 0.0
    assert det._motion_slack(boxes, np.zeros((0, 4))) == 0.0


def test_known_objects_without_a_learnt_size_are_not_kept_apart():
    # two walkers found as two (size known), then the size forgotten: the next full pass
    # has two Kalman filters but no size, so the blob is one object (the rule without
    # split_clusters)
    from mk_tracker.detection.person_size import PersonHeightModel
    config = ThermalDetectorConfig(split_clusters=True, person_aspect=0.25,
                                   reconfigure_period=1, window_margin=0,
                                   counts_fps=0.0)      # stamps at 10 Hz, frames counted
    frames = _two_people_frames(n_frames=7, gap=3)
    det = ThermalDetector(config)
    for _ in range(5):
        det.heights.add(60.0, 40.0)
    for t, f in enumerate(frames[:6]):
        dets = det.process(f, 0.1 * t, "mono8")
    assert len(dets) == 2
    det.heights = PersonHeightModel(config.size_memory)
    dets = det.process(frames[6], 0.6, "mono8")
    assert det.last_mode == "reconfiguration"
    assert len(dets) == 1


def test_learnt_aspect_is_the_forgetting_mean_of_the_samples():
    det = ThermalDetector(ThermalDetectorConfig(split_clusters=True, learn_aspect=True,
                                                person_aspect=0.27, size_memory=2.0))
    # memory 2: each older sample's weight halves; fewer than 2.5 in weight: person_aspect
    det._add_aspect(10.0, 40.0)
    det._add_aspect(20.0, 40.0)
    assert det._aspect() == 0.27                      # weight 1.5
    det = ThermalDetector(ThermalDetectorConfig(split_clusters=True, learn_aspect=True,
                                                size_memory=1e6))
    for w in (10.0, 12.0, 14.0):
        det._add_aspect(w, 40.0)
    assert det._aspect() == pytest.approx(0.3, rel=1e-5)   # (0.25 + 0.3 + 0.35) / 3
    for _ in range(3):
        det.heights.add(100.0, 40.0)
    assert det._expected_size(100.0) == pytest.approx((12.0, 40.0), rel=1e-5)
    # off: person_aspect
    det = ThermalDetector(ThermalDetectorConfig(split_clusters=True, person_aspect=0.25))
    for w in (10.0, 12.0, 14.0):
        det._add_aspect(w, 40.0)
    assert det._aspect() == 0.25
