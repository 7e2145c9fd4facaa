"""Property tests of Detection2DArray parsing (mk_tracker.messages.detection_messages) on hostile input.

Arbitrary centres, sizes (NaN, inf, huge, subnormal, negative), scores, ids, class ids and
result lists, in both message worlds (rclpy and rosbags) and after a CDR round trip.  Each
detection is either read as exactly the box/score/class/id an independent reading of the
vision_msgs convention gives, or rejected with :class:`DetectionMessageError` (skip mode
drops and counts exactly the rejected ones) -- never another exception, never a wrong box.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st

import property_profile  # noqa: F401  (registers and loads the derandomized profile)
from mk_tracker.bags.bag_typestore import make_typestore
from mk_tracker.messages.detection_messages import (Detection, DetectionMessageError,
                                           make_detection_array, read_detection_array)
from mk_tracker.messages.message_types import bag_message_types, make_header, ros_message_types

STORE = make_typestore()
WORLDS = {"bag": bag_message_types(STORE)}
try:
    import vision_msgs.msg  # noqa: F401
    WORLDS["ros"] = ros_message_types()
except ImportError:   # pragma: no cover - vision_msgs is built into the venv
    pass

TYPE = "vision_msgs/msg/Detection2DArray"
floats = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                   st.floats(-2000.0, 2000.0),
                   st.sampled_from([0.0, -0.0, 5e-324, 1e308, -1e308, 1.7e308]))
sizes = st.one_of(floats, st.floats(0.5, 500.0))
names = st.text(alphabet=st.characters(blacklist_categories=("Cs",),
                                       blacklist_characters="\x00"), max_size=6)
scores = st.one_of(floats, st.floats(-10.0, 10.0),
                   st.sampled_from([math.nan, math.inf, -math.inf]))
result = st.tuples(names, scores)
detection = st.fixed_dictionaries({
    "cx": floats, "cy": floats, "w": sizes, "h": sizes, "id": names,
    "results": st.lists(result, max_size=3)})


def expected(d: dict) -> tuple | None:
    """(box, score, class_id, id) by the module's documented convention, or None if the
    detection must be rejected.  Written independently of the module."""
    values = (d["cx"], d["cy"], d["w"], d["h"])
    if not all(math.isfinite(v) for v in values) or d["w"] <= 0 or d["h"] <= 0:
        return None
    x, y = d["cx"] - d["w"] / 2.0, d["cy"] - d["h"] / 2.0
    if not (math.isfinite(x) and math.isfinite(y)):
        return None
    scores = [s for _, s in d["results"]]
    if not all(math.isfinite(s) for s in scores):
        return None           # a corrupt hypothesis makes the detection unusable
    if scores:
        best = max(range(len(scores)), key=lambda i: (scores[i], -i))  # first of the highest
        class_id, score = d["results"][best]
    else:
        class_id, score = "", 0.0
    return (x, y, d["w"], d["h"]), score, class_id, d["id"]


def build(items: list[dict], types) -> object:
    header = make_header(types, "thermal_camera", 7)
    template = make_detection_array([Detection((0, 0, 1, 1), 0.5)] * len(items), header, types)
    pose = None
    for msg_det, d in zip(template.detections, items):
        pose = msg_det.results[0].pose
        msg_det.bbox.center.position.x = d["cx"]
        msg_det.bbox.center.position.y = d["cy"]
        msg_det.bbox.size_x, msg_det.bbox.size_y = d["w"], d["h"]
        msg_det.id = d["id"]
        msg_det.results = [types.ObjectHypothesisWithPose(
            hypothesis=types.ObjectHypothesis(class_id=c, score=s), pose=pose)
            for c, s in d["results"]]
    return template


def check(found: Detection, want: tuple) -> None:
    box, score, class_id, track_id = want
    for got, ref in zip(found.box, box):
        assert math.isfinite(got)
        assert got == pytest.approx(ref, rel=1e-12, abs=1e-300)
    assert found.score == score and found.class_id == class_id and found.id == track_id


@settings(max_examples=300)
@given(items=st.lists(detection, max_size=5), world=st.sampled_from(sorted(WORLDS)),
       through_cdr=st.booleans())
@example(items=[{"cx": 5.0, "cy": 5.0, "w": 2.0, "h": 2.0, "id": "",
                 "results": [("a", 0.5), ("b", math.nan)]}], world="bag", through_cdr=False)
def test_arbitrary_detection_arrays_parse_correctly_or_raise_our_error(items, world,
                                                                      through_cdr):
    types = WORLDS[world]
    msg = build(items, types)
    if through_cdr and world == "bag":
        msg = STORE.deserialize_cdr(STORE.serialize_cdr(msg, TYPE), TYPE)
    wants = [expected(d) for d in items]
    event(f"{sum(w is None for w in wants)} of {len(wants)} rejected")
    good, skipped = read_detection_array(msg, on_error="skip")
    assert skipped == sum(w is None for w in wants)
    kept = [w for w in wants if w is not None]
    assert len(good) == len(kept)
    for found, want in zip(good, kept):
        check(found, want)
    if skipped:
        first_bad = wants.index(None)
        with pytest.raises(DetectionMessageError, match=f"#{first_bad}\\b"):
            read_detection_array(msg)
    else:
        assert len(read_detection_array(msg)) == len(items)


@settings(max_examples=200)
@given(x=st.floats(-5000, 5000), y=st.floats(-5000, 5000), w=st.floats(1e-3, 5000),
       h=st.floats(1e-3, 5000), score=st.floats(-1e6, 1e6), track_id=names,
       world=st.sampled_from(sorted(WORLDS)))
def test_valid_detections_round_trip(x, y, w, h, score, track_id, world):
    types = WORLDS[world]
    det = Detection((x, y, w, h), score, "person", track_id)
    msg = make_detection_array([det], make_header(types, "camera", 1), types)
    raw = STORE.serialize_cdr(msg, TYPE) if world == "bag" else None
    if raw is not None:
        msg = STORE.deserialize_cdr(raw, TYPE)
    (back,) = read_detection_array(msg)
    assert back.score == score and back.id == track_id and back.class_id == "person"
    # centre/size and back: exact up to one rounding of the centre
    for got, ref in zip(back.box, (x, y, w, h)):
        assert got == pytest.approx(ref, rel=1e-12, abs=1e-9)


@settings(max_examples=50)
@given(junk=st.one_of(st.none(), st.integers(), st.text(max_size=5),
                      st.lists(st.integers(), max_size=3)))
def test_objects_that_are_not_detection_arrays_raise_our_error(junk):
    class Fake:
        detections = [junk]

    with pytest.raises(DetectionMessageError):
        read_detection_array(Fake())
    good, skipped = read_detection_array(Fake(), on_error="skip")
    assert good == [] and skipped == 1
