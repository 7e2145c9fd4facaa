"""benchmarks/diagnose_coast_offset.py: the causes of an off-person coasting box."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import diagnose_coast_offset as diag  # noqa: E402
from mk_tracker.evaluation.metrics import MotRow  # noqa: E402

PERSON_1 = (100.0, 100.0, 40.0, 100.0)      # frame 1
PERSON_2 = (104.0, 100.0, 40.0, 100.0)      # frame 2: the person walked 4 px


def _case(snap_box, coast_box, pred_centre, refined):
    """Track 7 detected at ``snap_box`` in frame 1 and coasting at ``coast_box`` in frame
    2, where the pure prediction from frame 1 is ``pred_centre``."""
    frames = [(None, 0.0, [], [MotRow(1, 1, PERSON_1)]),
              (None, 0.04, [], [MotRow(2, 1, PERSON_2)])]
    hyp = [MotRow(1, 7, PERSON_1), MotRow(2, 7, coast_box)]
    snap = {"frame": 0, "stamp": 0.0, "box": np.array(snap_box), "group": False}
    coast = {(2, 7): {"box": np.array(coast_box), "pred": np.array(pred_centre),
                      "snap": snap, "refined": refined, "history": [],
                      "stamp": 0.04, "velocity": np.zeros(2)}}
    causes, _, _, lines = diag.diagnose(frames, hyp, coast)
    assert sum(causes.values()) == 1 and len(lines) == 1
    return next(iter(causes))


OFF = (128.0, 100.0, 40.0, 100.0)           # IoU 0.25 with PERSON_2


@pytest.mark.parametrize("snap_box, coast_box, pred, refined, cause", [
    (PERSON_1, OFF, (124.0, 150.0), 1, diag.PULLED),
    (PERSON_1, OFF, (124.0, 150.0), 0, diag.OTHER),
    (PERSON_1, OFF, (148.0, 150.0), 0, diag.DRIFT),
    ((125.0, 100.0, 40.0, 100.0), OFF, (148.0, 150.0), 0, diag.NOBODY),
    # right centre, more than twice the width: only the size is wrong
    (PERSON_1, (79.0, 100.0, 90.0, 100.0), (124.0, 150.0), 0, diag.SIZE),
])
def test_each_cause(snap_box, coast_box, pred, refined, cause):
    assert diag._iou1(coast_box, PERSON_2) < 0.5
    assert _case(snap_box, coast_box, pred, refined) == cause


def test_a_box_on_nobody_is_not_an_off_person_box():
    frames = [(None, 0.0, [], [MotRow(1, 1, PERSON_1)]),
              (None, 0.04, [], [MotRow(2, 1, PERSON_2)])]
    far = (400.0, 100.0, 40.0, 100.0)
    hyp = [MotRow(1, 7, PERSON_1), MotRow(2, 7, far)]
    coast = {(2, 7): {"box": np.array(far), "pred": np.array((420.0, 150.0)),
                      "snap": {"frame": 0, "stamp": 0.0, "box": np.array(PERSON_1),
                               "group": False},
                      "refined": 0, "history": [], "stamp": 0.04, "velocity": np.zeros(2)}}
    causes, _, _, _ = diag.diagnose(frames, hyp, coast)
    assert not causes
