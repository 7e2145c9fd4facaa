"""The person cover (issue #15): a detection that holds several people becomes one
whole-person box per person, sized by the learnt person height of its row."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.boxes import iou
from mk_tracker.detection.person_cover import PersonCoverConfig, cover_people, warm_mask
from mk_tracker.detection.thermal_detector import ThermalDetector
from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig
from mk_tracker.parameters import updated
from mk_tracker.synthetic.scene_bag import build_preset


def _height(y_bottom: float) -> float:
    return 20.0 + 0.25 * y_bottom           # a ground plane: farther people are shorter


ASPECT = 0.36


def _person(y_bottom: int, x_centre: int) -> tuple[int, int, int, int]:
    h = _height(y_bottom)
    w = ASPECT * h
    return (int(round(x_centre - w / 2)), int(round(y_bottom - h)), int(round(w)),
            int(round(h)))


def _warm(*people: tuple[int, int, int, int], shape=(300, 400)) -> np.ndarray:
    mask = np.zeros(shape, dtype=bool)
    for x, y, w, h in people:
        mask[y:y + h, x:x + w] = True
    return mask


def _union(*boxes):
    x0 = min(b[0] for b in boxes)
    y0 = min(b[1] for b in boxes)
    x1 = max(b[0] + b[2] for b in boxes)
    y1 = max(b[1] + b[3] for b in boxes)
    return (x0, y0, x1 - x0, y1 - y0)


def _matched(found, people, level=0.7) -> bool:
    return len(found) == len(people) and all(
        max(iou(f, p) for f in found) >= level for p in people)


def test_two_people_side_by_side_in_one_box_become_two_person_boxes():
    a, b = _person(240, 150), _person(244, 180)          # touching, one box around both
    found = cover_people(_warm(a, b), _union(a, b), _height, ASPECT, PersonCoverConfig())
    assert _matched(found, [a, b]), found


def test_a_person_partly_behind_another_is_found_from_what_shows():
    front = _person(250, 200)
    back = _person(200, 185)              # farther (shorter, higher), left half hidden
    found = cover_people(_warm(back, front), _union(back, front), _height, ASPECT,
                         PersonCoverConfig())
    assert _matched(found, [front, back], level=0.6), found


def test_one_person_in_a_loose_box_gets_one_tight_box():
    p = _person(220, 120)
    loose = (p[0] - 20, p[1] - 5, p[2] + 40, p[3] + 10)
    found = cover_people(_warm(p), loose, _height, ASPECT, PersonCoverConfig())
    assert _matched(found, [p], level=0.8), found


def test_nothing_to_cover_gives_no_boxes():
    p = _person(220, 120)
    assert cover_people(_warm(), p, _height, ASPECT, PersonCoverConfig()) == []
    assert cover_people(_warm(p), p, lambda y: None, ASPECT, PersonCoverConfig()) == []
    # a box off the image
    assert cover_people(_warm(p), (500.0, 10.0, 30.0, 60.0), _height, ASPECT,
                        PersonCoverConfig()) == []


def test_min_gain_stops_at_the_people_and_max_people_bounds_the_count():
    people = [_person(240, x) for x in (60, 90, 120, 150)]
    box = _union(*people)
    assert len(cover_people(_warm(*people), box, _height, ASPECT, PersonCoverConfig(), 2)) == 4
    assert len(cover_people(_warm(*people), box, _height, ASPECT,
                            PersonCoverConfig(max_people=2), 2)) == 2


def test_warm_mask_is_relative_to_the_background_level():
    frame = np.full((40, 40), 100.0, dtype=np.float32)
    frame[10:20, 10:14] = 130.0
    frame[30:32, 30:32] = 104.0                     # within the radius: background
    mask = warm_mask(frame, 10.0)
    assert mask.sum() == 40 and mask[10:20, 10:14].all()


def _iou_recall(cover: bool) -> float:
    config = updated(ThermalDetectorConfig(), {"person_cover.enabled": cover})
    scene = build_preset("crowd", seed=101, people=8, frames=150, width=320, height=240)
    detector = ThermalDetector(config)
    found = total = 0
    for i in range(len(scene)):
        frame = scene.frame(i)
        dets = detector.process(frame.thermal, frame.stamp)
        if detector.last_mode == "warming_up":
            continue
        for o in frame.objects:
            if o.in_frame and o.visible_fraction >= 0.5:
                total += 1
                found += any(iou(d.box, o.box_thermal) >= 0.5 for d in dets)
    return found / total


def test_the_detector_finds_more_people_of_a_crowd_with_the_cover():
    without, with_cover = _iou_recall(False), _iou_recall(True)
    assert with_cover > without + 0.1, (without, with_cover)


class _Detection:
    def __init__(self, box):
        self.box = box


def _detector_with_heights(samples, people: int = 5) -> ThermalDetector:
    """A detector that has learnt ``samples`` ``(feet row, height)`` from ``people`` of its
    objects."""
    detector = ThermalDetector(updated(ThermalDetectorConfig(),
                                       {"person_cover.enabled": True}))
    for k, (y_bottom, height) in enumerate(samples):
        detector.heights.add(y_bottom, height)
        detector._add_aspect(ASPECT * height, height)
        detector._note_size_object(1 + k % people)
    return detector


def test_the_cover_acts_only_where_person_heights_follow_the_row():
    """A group box is covered when the learnt heights follow the image row (a ground
    plane) in samples of several people; where they do not (a near view: R^2 about 0), or
    the samples are of one person, it is left as it is."""
    a, b = _person(240, 150), _person(244, 180)
    group = _Detection(_union(a, b))
    frame = np.where(_warm(a, b), 200.0, 40.0).astype(np.float32)
    rows = [150 + (7 * k) % 140 for k in range(60)]            # 60 samples
    ground = _detector_with_heights([(y, _height(y)) for y in rows])
    # a near view: half- and whole-body boxes end on any row, heights scatter by a quarter
    # of their mean (BU-TIV-lab: 0.26-0.37), so the level form of the gate stays shut too
    near = _detector_with_heights([(y, 60.0 + 5 * ((13 * y) % 17)) for y in rows])
    one = _detector_with_heights([(y, _height(y)) for y in rows], people=1)
    assert ground.heights.explained() > 0.9 and near.heights.explained() < 0.3
    assert near.heights.relative_residual() > 0.2
    for detector in (ground, near, one):
        detector._newest = lambda: frame
        detector._raw_radius = lambda: 20.0
    pieces = ground._covered([group], lambda d, box: _Detection(box))
    assert _matched([p.box for p in pieces], [a, b]), [p.box for p in pieces]
    assert near._covered([group], lambda d, box: _Detection(box)) == [group]
    # sixty samples on a line, but all of one person (min_people): one person walking
    # towards the camera is such a line in any scene
    assert one.heights.explained() > 0.9
    assert one._covered([group], lambda d, box: _Detection(box)) == [group]


def test_the_detector_counts_the_objects_its_size_samples_come_from():
    """Size samples are counted per detector object: a person followed over many frames is
    one, whatever the number of samples."""
    scene = build_preset("crowd", seed=101, people=3, frames=60, width=320, height=240)
    detector = ThermalDetector(updated(ThermalDetectorConfig(),
                                       {"person_cover.enabled": True}))
    for i in range(len(scene)):
        frame = scene.frame(i)
        detector.process(frame.thermal, frame.stamp)
    people = detector.sampled_objects()
    assert 1 <= people <= 6, detector.size_objects
    assert detector.heights.samples > 3 * people
    assert max(detector.size_objects) < detector._next_id      # ids the detector gave
    detector.reset()
    assert detector.sampled_objects() == 0


def test_people_the_size_model_has_forgotten_no_longer_count():
    """After a whole ``size_memory`` of samples from one person, the people sampled before
    no longer count: the fit is that one person's again, and the cover waits."""
    config = updated(ThermalDetectorConfig(), {"person_cover.enabled": True,
                                               "size_memory": 20.0})
    detector = ThermalDetector(config)
    for k in range(30):
        detector._note_size_object(1 + k % 3)
    assert detector.sampled_objects() == 3
    for _ in range(17):
        detector._note_size_object(7)
    assert detector.sampled_objects() == 4          # 1-3's last samples 17-19 ago, and 7
    detector._note_size_object(7)
    assert detector.sampled_objects() == 3          # object 1's last sample, 20 ago, is out
    detector._note_size_object(7)
    detector._note_size_object(7)
    assert detector.sampled_objects() == 1          # only the one person left
    for oid in range(100, 400):                     # a long run of passers-by: the
        detector._note_size_object(oid)             # forgotten ids are dropped too
    assert detector.sampled_objects() == 20
    assert len(detector.size_objects) <= 21


def _level_group():
    """Two people of one height (90 px) touching along a diagonal, one box around both."""
    a = (150, 100, 32, 90)
    b = (176, 130, 32, 90)
    return a, b, _Detection(_union(a, b)), np.where(_warm(a, b), 200.0, 40.0).astype(
        np.float32)


@pytest.mark.parametrize("tolerance, span, scatter, change, covered", [
    (0.1, 200, 0.0, 0.0, True),      # one height over 200 rows (> 90 px): a queue on stairs
    (0.0, 200, 0.0, 0.0, False),     # the level form off: R^2 is 0, the gate stays shut
    (0.1, 60, 0.0, 0.0, False),      # feet over fewer rows than a person's height
    (0.1, 200, 0.2, 0.0, False),     # heights scattered by 20% (a near view, BU-TIV-lab)
    (0.1, 200, 0.0, 0.3, False),     # heights that grow by 30% over the rows: not level
])
def test_one_height_for_every_row_opens_the_cover_with_one_person(
        tolerance, span, scatter, change, covered):
    """R^2 is 0 when the heights do not vary with the row, yet the size is then known best:
    the level form of the gate covers the group from one person's samples, and only when
    their feet spread over a person's height of rows at one height."""
    a, b, group, frame = _level_group()
    rng = np.random.default_rng(3)
    rows = 150.0 + span * np.linspace(0.0, 1.0, 60)
    heights = 90.0 * (1.0 + change * (rows - rows[0]) / span
                      + scatter * rng.standard_normal(rows.size))
    detector = _detector_with_heights(list(zip(rows, heights)), people=1)
    detector.config = updated(detector.config, {"person_cover.level_tolerance": tolerance})
    detector._newest = lambda: frame
    detector._raw_radius = lambda: 20.0
    assert detector.heights.explained() < 0.3 or change > 0
    pieces = detector._covered([group], lambda d, box: _Detection(box))
    if covered:
        assert _matched([p.box for p in pieces], [a, b]), [p.box for p in pieces]
    else:
        assert pieces == [group]


def _queue_recall(level_tolerance: float) -> float:
    """Share of the fully visible people of a generated queue coming down stairs
    (benchmarks/bench_queue.py, 6 people, seed 1) that a detection matches at IoU >= 0.5,
    from frame 150 on (the first person has been seen alone by then)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from bench_queue import queue_scene

    scene = queue_scene(6, 1, 220, 30.0)
    detector = ThermalDetector(updated(ThermalDetectorConfig(),
                                       {"person_cover.level_tolerance": level_tolerance}))
    found = total = 0
    for i in range(len(scene)):
        frame = scene.frame(i)
        out = detector.process(frame.thermal, frame.stamp)
        if i < 150:
            continue
        for obj in frame.objects:
            if obj.visible_fraction > 0.9:
                total += 1
                found += any(iou(obj.box_thermal, d.box) >= 0.5 for d in out)
    assert total > 100
    return found / total


def test_a_queue_on_stairs_is_cut_into_people_by_the_level_form():
    """People of one height touching along a diagonal merge into one or two objects; the
    first of them, seen alone over many rows at one height, opens the cover's level form
    and the queue is cut into people (0.2 of them found without it, 0.86 with it)."""
    assert _queue_recall(0.1) > 0.7
    assert _queue_recall(0.0) < 0.35
