"""The extent bound of the thermal detector (``detector.extent``, issues #19 and #15): a
group of people made into one object wider than the bound is re-split by K-means in
full-frame passes and neither published nor carried in tracking passes."""

import numpy as np
import pytest

from mk_tracker.detection.object_extent import ObjectExtentConfig, oversized_width
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig
from mk_tracker.parameters import ParameterError

W, H = 80, 60
#: the bound of these scenes: 0.2 of an 80 px wide frame, 16 px; one person is 10 px wide,
#: two who touch make a 20 px wide footprint
FRACTION = 0.2
BOUND = FRACTION * W


def _frames(n: int = 40, join: int = 0, others: int = 1) -> list[np.ndarray]:
    """Warm upright people (10x40 px, levels 200, 180, 200, ... on 40) walking right at 1 px
    a frame side by side, touching: the first one, and ``others`` more from frame ``join``
    on."""
    out = []
    for k in range(n):
        f = np.full((H, W), 40, np.uint8)
        x = 6 + k
        f[10:50, x:x + 10] = 200
        if k >= join:
            for j in range(1, others + 1):
                f[10:50, x + 10 * j:x + 10 * (j + 1)] = 180 if j % 2 else 200
        out.append(f)
    return out


def _run(bound: bool, frames: list[np.ndarray], max_parts: int = 8, **kw
         ) -> tuple[ThermalDetector, list]:
    det = ThermalDetector(ThermalDetectorConfig(       # stamps at 10 Hz, frames counted
        extent=ObjectExtentConfig(bound=bound, max_width_fraction=FRACTION,
                                  max_parts=max_parts), counts_fps=0.0, **kw))
    out = []
    for k, f in enumerate(frames):
        found = det.process(f, k / 10.0)
        out.append((det.last_mode, found, list(det.tracks)))
    return det, out


def test_the_width_bound_by_the_frame_and_by_the_person_size():
    rule = ObjectExtentConfig(max_width_fraction=0.5, max_person_widths=3.0)
    assert not oversized_width(256.0, 512.0, rule)
    assert oversized_width(256.5, 512.0, rule)
    # a learnt person width of 30 px: 90 px is three people, 91 px more
    assert not oversized_width(90.0, 512.0, rule, person_width=30.0)
    assert oversized_width(91.0, 512.0, rule, person_width=30.0)
    # max_person_widths 0: no person test, only the frame's
    no_person = ObjectExtentConfig(max_width_fraction=0.5, max_person_widths=0.0)
    assert not oversized_width(200.0, 512.0, no_person, person_width=30.0)


@pytest.mark.parametrize("field, value", [("max_width_fraction", 0.0),
                                          ("max_width_fraction", 1.5),
                                          ("max_person_widths", -1.0),
                                          ("max_parts", 1)])
def test_out_of_range_settings_are_refused(field, value):
    with pytest.raises(ParameterError, match=field):
        ThermalDetector(ThermalDetectorConfig(extent=ObjectExtentConfig(**{field: value})))


def test_without_the_bound_two_touching_people_are_one_object_in_every_frame():
    # the defect: the link rule makes one 20 px wide object, carried by every tracking pass
    _, out = _run(False, _frames())
    widths = [[d.box[2] for d in found] for mode, found, _ in out if mode != "warming_up"]
    assert len(widths) == 35
    assert all(w == [20.0] for w in widths)


def test_with_the_bound_a_full_pass_splits_the_pair_into_two_people():
    _, out = _run(True, _frames())
    full = [found for mode, found, _ in out if mode in ("startup", "reconfiguration")]
    assert len(full) >= 3
    for found in full:
        boxes = sorted(d.box for d in found)
        assert len(boxes) == 2
        (xa, _, wa, ha), (xb, _, wb, hb) = boxes
        # two column ranges side by side, each about one person (10 px) wide and as tall
        assert xa + wa == xb
        assert 8.0 <= wa <= 12.0 and 8.0 <= wb <= 12.0
        assert ha == hb == 40.0
    # no published box is ever wider than the bound
    assert all(d.box[2] <= BOUND for _, found, _ in out for d in found)


def test_a_group_formed_in_a_tracking_pass_keeps_the_part_nearest_the_prediction():
    # one person alone until frame 10, then the second one touches it (on its right)
    frames = _frames(join=10)
    _, off = _run(False, frames)
    _, on = _run(True, frames)
    mode, found, _ = off[10]
    assert mode == "tracking" and [d.box[2] for d in found] == [20.0]
    assert off[11][0] == "tracking"          # next full pass only at reconfigure_period
    first_id = on[9][1][0].object_id
    mode, found, tracks = on[10]
    # the object keeps its own person: the left column part, its id, about 10 px wide
    assert mode == "tracking" and len(found) == 1 and len(tracks) == 1
    (d,) = found
    assert d.object_id == first_id
    assert d.box[0] == 16.0 and 8.0 <= d.box[2] <= 12.0
    # ... and the next full pass comes group_recheck_frames after the last one (frame 5)
    assert ThermalDetectorConfig().group_recheck_frames <= 6
    mode, found, _ = on[11]
    assert mode == "reconfiguration"
    assert len(found) == 2 and all(d.box[2] <= BOUND for d in found)
    assert first_id in {d.object_id for d in found}


def test_a_group_whose_nearest_part_is_still_too_wide_is_not_carried():
    # three more people join: a 40 px group; with at most 2 parts each is 20 px > 16 px
    # (a wide (5.2) window margin, so that the footprint holds the whole group)
    frames = _frames(join=10, others=3)
    _, on = _run(True, frames, max_parts=2, window_margin=40)
    assert len(on[9][1]) == 1
    mode, found, tracks = on[10]
    assert mode == "tracking" and found == [] and tracks == []
    assert on[11][0] == "reconfiguration"
    assert all(d.box[2] <= BOUND for _, found, _ in on for d in found)
