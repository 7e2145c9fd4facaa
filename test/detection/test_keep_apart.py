"""Objects followed apart are kept apart at a full-frame pass (``detector.keep_apart``,
issue #15): two people who were two Kalman-filtered objects before they came close are
not joined into one object by the link rule when a full pass falls on their closest
approach."""

import numpy as np
import pytest

from mk_tracker.detection.keep_apart import KeepApartConfig, seeds_inside
from mk_tracker.detection.person_cover import PersonCoverConfig
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig
from mk_tracker.parameters import ParameterError

W, H = 120, 70
#: the frame with a full-frame pass (reconfigure_period 25 after the start-up at frame 5)
#: while the two people touch: their columns overlap from frame 46 to 54
CONTACT_PASS = 55


def _passing(n: int = 80) -> list[np.ndarray]:
    """Two warm people walking towards each other at 1 px a frame and passing: A (10x30 px,
    level 200, rows 4-33) walking right, B (10x34 px, level 170, rows 32-65, in front, so it
    hides A's two lowest rows while they pass) walking left, on a background of 40."""
    out = []
    for k in range(n):
        f = np.full((H, W), 40, np.uint8)
        xa, xb = 5 + k, 105 - k
        f[4:34, xa:xa + 10] = 200
        f[32:66, xb:xb + 10] = 170
        out.append(f)
    return out


def _truth(k: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """Centroids of A's visible pixels and of B in frame ``k``."""
    xa, xb = 5 + k, 105 - k
    a_rows = 28 if xb < xa + 10 and xa < xb + 10 else 30
    return (xa + 5.0, 4 + a_rows / 2.0), (xb + 5.0, 32 + 17.0)


def _run(enabled: bool, **kw) -> tuple[ThermalDetector, list]:
    # the person cover (on by default) would split the joined pair into person boxes after
    # the pass; these tests are about the objects of the pass itself
    # (stamps at 10 Hz; the passes are counted in frames: counts_fps 0)
    det = ThermalDetector(ThermalDetectorConfig(
        keep_apart=KeepApartConfig(enabled=enabled, **kw),
        person_cover=PersonCoverConfig(enabled=False), counts_fps=0.0))
    out = []
    for k, f in enumerate(_passing()):
        found = det.process(f, k / 10.0)
        out.append((det.last_mode, found))
    return det, out


def test_the_scene_puts_a_full_pass_on_the_closest_approach():
    _, out = _run(False)
    assert out[CONTACT_PASS][0] == "reconfiguration"
    a, b = _truth(CONTACT_PASS)
    assert abs(a[0] - b[0]) <= 10          # columns overlap: they touch


def test_without_the_rule_the_pair_is_one_object_at_the_full_pass():
    _, out = _run(False)
    assert len(out[CONTACT_PASS][1]) == 1


def test_with_the_rule_they_stay_two_objects_with_their_ids_through_the_pass():
    _, out = _run(True)
    ids_before = None
    for k in range(CONTACT_PASS - 10, len(out)):
        mode, found = out[k]
        assert len(found) == 2, (k, mode, found)
        a, b = _truth(k)
        by_id = sorted(found, key=lambda d: d.object_id)
        # the older object is A, the other B, in every frame (no swap, no new id)
        assert np.hypot(by_id[0].centroid[0] - a[0], by_id[0].centroid[1] - a[1]) < 4.0, k
        assert np.hypot(by_id[1].centroid[0] - b[0], by_id[1].centroid[1] - b[1]) < 4.0, k
        ids = [d.object_id for d in by_id]
        assert ids_before is None or ids == ids_before
        ids_before = ids


def test_a_seed_must_have_been_found_alone_at_enough_full_passes():
    # at the contact pass each object has been found alone at 2 passes (start-up, frame
    # 30): asking for 3 leaves them without seeds, and the pair is one object as without
    # the rule
    _, out = _run(True, min_full_passes=3)
    assert len(out[CONTACT_PASS][1]) == 1
    _, out = _run(True, min_full_passes=2)
    assert len(out[CONTACT_PASS][1]) == 2


def test_one_person_alone_is_never_split():
    det = ThermalDetector(ThermalDetectorConfig(keep_apart=KeepApartConfig(enabled=True)))
    for k in range(80):
        f = np.full((H, W), 40, np.uint8)
        f[10:50, 5 + k:15 + k] = 200
        found = det.process(f, k / 10.0)
        if det.last_mode != "warming_up":
            assert len(found) == 1, (k, det.last_mode)


def test_seeds_inside_a_box():
    pts = np.array([[1.0, 1.0], [5.0, 5.0], [11.0, 5.0], [10.0, 10.0]])
    assert seeds_inside((0.0, 0.0, 10.0, 10.0), pts).tolist() == [0, 1, 3]
    assert seeds_inside((0.0, 0.0, 10.0, 10.0), np.zeros((0, 2))).size == 0


@pytest.mark.parametrize("value", [0, 1001])
def test_out_of_range_settings_are_refused(value):
    with pytest.raises(ParameterError):
        ThermalDetector(ThermalDetectorConfig(
            keep_apart=KeepApartConfig(enabled=True, min_full_passes=value)))


def _pair_footprint():
    """A 20x40 px footprint of two touching 10 px wide people at columns 20-29 and 30-39,
    rows 10-49, in an 80x60 frame; its candidate box holds both people's centres."""
    frame = np.full((60, 80), 40.0, np.float32)
    frame[10:50, 20:40] = 200.0
    mask = np.zeros((60, 80), bool)
    mask[10:50, 20:40] = True
    support = np.zeros((60, 80), bool)
    support[10:50, 20:22] = True
    from types import SimpleNamespace
    from mk_tracker.detection.footprint_split import _Candidate
    cand = _Candidate((30.0, 30.0), (20.0, 10.0, 20.0, 40.0), 1.0, 800)
    return frame, SimpleNamespace(support=support), ((0, 0), mask), cand


def test_the_footprint_goes_to_the_nearest_seed():
    det = ThermalDetector(ThermalDetectorConfig(keep_apart=KeepApartConfig(enabled=True)))
    frame, result, fp, cand = _pair_footprint()
    seeds = np.array([[24.0, 30.0], [36.0, 30.0], [70.0, 30.0]])   # the third is outside
    parts = det._apart_parts(frame, result, np.zeros(0, int), np.zeros(0, int),
                             (0, 60, 0, 80), cand, fp, seeds)
    assert parts is not None and len(parts) == 2
    boxes = sorted(p.box for p in parts)
    assert boxes == [(20.0, 10.0, 10.0, 40.0), (30.0, 10.0, 10.0, 40.0)]
    assert sum(p.pixel_count for p in parts) == 800


def test_one_seed_or_seeds_in_one_place_leave_the_object_whole():
    det = ThermalDetector(ThermalDetectorConfig(keep_apart=KeepApartConfig(enabled=True)))
    frame, result, fp, cand = _pair_footprint()
    args = (frame, result, np.zeros(0, int), np.zeros(0, int), (0, 60, 0, 80), cand, fp)
    assert det._apart_parts(*args, np.array([[24.0, 30.0]])) is None
    assert det._apart_parts(*args, np.zeros((0, 2))) is None
    # two filters predicted at one point (K-means leaves the second cluster empty)
    assert det._apart_parts(*args, np.array([[30.0, 30.0], [30.0, 30.0]])) is None
