"""benchmarks/diagnose_still_man_passes.py's explanation of the region on a still person, on
hand-made masks whose answer is known."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from diagnose_still_man_passes import explain  # noqa: E402

from mk_tracker.detection.still_people import StillPeopleConfig  # noqa: E402

PERSON = (40.0, 15.0, 10.0, 30.0)


def _frame(neighbour: bool) -> np.ndarray:
    f = np.full((60, 100), 40.0)
    f[15:45, 40:50] = 150.0
    if neighbour:
        f[15:45, 50:60] = 150.0          # touching him on his right
    return f


def _explain(frame, boxes=(), tall=30.0, people=110.0):
    return explain(frame > 60.0, frame, 40.0, PERSON, list(boxes), people, tall,
                   StillPeopleConfig(), 0.4)


def test_a_person_alone_is_a_candidate():
    box, reasons = _explain(_frame(False))
    assert box == PERSON and reasons == []


def test_a_touching_neighbour_makes_one_region_that_is_not_person_shaped():
    box, reasons = _explain(_frame(True))
    assert box == (40.0, 15.0, 20.0, 30.0)
    assert len(reasons) == 1 and reasons[0].startswith("shape")


def test_overlap_height_and_warmth_are_named():
    _, reasons = _explain(_frame(False), boxes=[PERSON], tall=200.0, people=300.0)
    assert [r.split()[0] for r in reasons] == ["height", "overlap", "warmth"]


def test_no_warm_pixel_in_the_box():
    assert _explain(np.full((60, 100), 40.0)) == (None, ["no warm pixel"])
