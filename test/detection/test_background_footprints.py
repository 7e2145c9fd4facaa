"""Full-frame passes drop footprints that are the scene's background
(``drop_background_footprints``, issue #15: one person at 640x480 reported twice)."""

import numpy as np
import pytest

from mk_tracker.detection.footprint_split import _Candidate, _footprint_levels
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig
from mk_tracker.synthetic.scene_bag import build_preset


def _candidate(level, local):
    return _Candidate((10.0, 10.0), (5.0, 5.0, 10.0, 10.0), 1.0, 100, level, local)


def _detector_and_frame():
    # mono8, sigma^2 = 0.01: the map is raw / 255, so the similarity radius of (3.6),
    # sigma sqrt(2 ln 2) = 0.11774 on the unit scale, is 0.11774 * 255 = 30.02 raw levels.
    det = ThermalDetector(ThermalDetectorConfig(sigma2=0.01))
    det._map = (0.0, 1.0 / 255.0)
    frame = np.full((20, 30), 40.0, dtype=np.float32)     # scene background: 40
    support = np.zeros(frame.shape, dtype=bool)
    frame[:, :10] = 200.0            # support pixels: not part of the scene background
    support[:, :10] = True
    return det, frame, support


def test_background_seen_against_a_warm_neighbour_is_dropped():
    det, frame, support = _detector_and_frame()
    # local background 115 (a near person): 75 from the scene's 40, more than 30.02
    levels = (40.0, 69.9, 10.1, 70.1, 9.9, 200.0)
    kept = det._without_background(frame, support, [_candidate(v, 115.0) for v in levels])
    # |level - 40| <= 30.02 is background; 70.1 and 9.9 are 30.1 away, 200 is a person
    assert [c.level for c in kept] == [70.1, 9.9, 200.0]


def test_a_faint_object_against_the_plain_background_is_kept():
    det, frame, support = _detector_and_frame()
    # footprints as close to the scene as above, but found against a local background
    # within 30.02 of the scene (69.9, 10.1: plain background): kept; 70.1 is not plain
    cands = [_candidate(60.0, local) for local in (69.9, 10.1, 40.0, 70.1)]
    kept = det._without_background(frame, support, cands)
    assert [c.local for c in kept] == [69.9, 10.1, 40.0]


def test_without_support_pixels_outside_every_object_nothing_is_dropped():
    det = ThermalDetector()
    det._map = (0.0, 1.0 / 255.0)
    frame = np.full((4, 4), 40.0, dtype=np.float32)
    support = np.ones(frame.shape, dtype=bool)
    cands = [_candidate(40.0, 115.0)]
    assert det._without_background(frame, support, cands) == cands


@pytest.fixture(scope="module")
def one_person_640():
    # the generator's scene where the band a near person swept became a second object
    # (frame 80, then half of the person in every tracking pass up to the end)
    return build_preset("crowd", seed=201, people=1, frames=150, width=640, height=480)


def _counts(scene, config):
    det = ThermalDetector(config)
    counts = []
    for i in range(len(scene)):
        fr = scene.frame(i)
        dets = det.process(fr.thermal, fr.stamp)
        if det.last_mode != "warming_up":
            counts.append(len(dets))
    return counts


def test_one_near_person_is_one_detection_in_every_frame(one_person_640):
    assert set(_counts(one_person_640, ThermalDetectorConfig())) == {1}


def test_without_the_rule_the_swept_band_becomes_a_second_object(one_person_640):
    # the same scene without the rule: the defect the rule removes is there
    counts = _counts(one_person_640, ThermalDetectorConfig(drop_background_footprints=False))
    assert max(counts) == 2 and counts.count(2) >= 10


def test_footprint_levels_are_the_mean_of_the_footprint_and_the_median_off_support():
    frame = np.array([[10, 20, 30, 40],
                      [50, 60, 70, 80],
                      [90, 100, 110, 120]], dtype=np.float32)
    support = np.zeros(frame.shape, dtype=bool)
    support[1, 1:3] = True                      # 60, 70
    mask = np.zeros((2, 3), dtype=bool)         # patch rows 1-2, columns 1-3
    mask[0, 0:2] = True                         # 60, 70
    mask[1, 2] = True                           # 120
    level, local = _footprint_levels(frame, support, ((1, 1), mask))
    # footprint mean (60 + 70 + 120) / 3; off-support patch pixels 80, 100, 110, 120
    assert level == pytest.approx(250.0 / 3.0)
    assert local == pytest.approx(105.0)


def test_overlapping_footprints_are_one_set_transitively():
    from mk_tracker.detection.footprint import overlapping_footprints

    def box(y0, x0, h, w):
        return (y0, x0), np.ones((h, w), bool)

    # 0 and 1 share rows 2-4 x columns 4-5; 1 and 3 share row 2 x columns 9-10 (so 0, 1
    # and 3 are one set through 1); 2 is apart; 4 has no footprint and stays alone
    fps = {0: box(0, 0, 5, 6), 1: box(2, 4, 3, 7), 2: box(10, 20, 4, 4), 3: box(0, 9, 3, 3),
           4: None}
    prints, sets = overlapping_footprints((20, 30), 5, fps.get)
    assert prints == [fps[k] for k in range(5)]
    assert sets == [[0, 1, 3], [2], [4]]
    # touching edges without a shared pixel are not an overlap
    _, sets = overlapping_footprints((20, 30), 2, {0: box(0, 0, 3, 3), 1: box(0, 3, 3, 3)}.get)
    assert sets == [[0], [1]]
