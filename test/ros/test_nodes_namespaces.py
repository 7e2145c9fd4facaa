"""Two camera pairs side by side on one ROS domain, each in its own namespace (issue #14).

Both pairs (detector_node + tracker_node under ``/cam1`` and under ``/cam2``) load the
shipped config/*.yaml, whose sections are keyed ``/**/<node>``, plus a parameters file with
whole numbers where doubles are declared (``tracker.kalman.sigma_u: 25``, an integer
homography ``[2, 0, 0, 0, 2, 0, 0, 0, 1]``, the detector's ``report_period: 7``; and
``-p detection_wait:=1`` on /cam2's tracker's command line): before
issue #14 such a file stopped the node ("... of type 'INTEGER', expecting type 'DOUBLE'").

Checked:

* every node resolves its relative topics inside its namespace (its ready line names them)
  and reads back the whole numbers as doubles over the parameter services; an integer set
  at run time is accepted and stored as a double;
* each detector answers only its own camera's thermal frames (header frame ids differ);
* each tracker follows the person of its own camera: detections sent in the thermal plane
  of /cam1 (box at 20, 20) and /cam2 (box at 100, 50) come back as tracks on /cam1/tracks
  and /cam2/tracks at twice those coordinates (the integer homography was applied), with
  the frame id of that camera's images, and never the other camera's.

Timing (issue #12): the frames are sent in lock-step, each once the answer to the previous
one came, after every connection matched; the timeouts only bound waits for answers that
must come (30 s for one answer, observed: a few ms).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from rcl_interfaces.srv import GetParameters, SetParameters  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.messages.detection_messages import (Detection,  # noqa: E402
                                                    make_detection_array, read_detection_array)
from mk_tracker.messages.image_conversion import numpy_to_image  # noqa: E402
from mk_tracker.messages.message_types import ros_message_types  # noqa: E402
from mk_tracker.ros.launcher import READY_LINES  # noqa: E402

from nodes_harness import (REPO, call_service, domain, make_stamp, node_group,  # noqa: E402,F401
                           peer, reliable_qos)

TYPES = ros_message_types()
RELIABLE = reliable_qos()
ANSWER_TIMEOUT_S = 30.0
FRAMES = 12
WHOLE_NUMBERS = """\
/**/tracker_node:
  ros__parameters:
    image_qos:
      reliability: reliable
      depth: 10
    detections_qos:
      reliability: reliable
      depth: 10
    detection_wait: 2
    tracker:
      kalman:
        sigma_u: 25
      homography: [2, 0, 0, 0, 2, 0, 0, 0, 1]
/**/detector_node:
  ros__parameters:
    image_qos:
      reliability: reliable
      depth: 10
    report_period: 7
"""
#: person box in each camera's thermal plane (x, y, w, h)
THERMAL_BOX = {"cam1": (20.0, 20.0, 15.0, 30.0), "cam2": (100.0, 50.0, 15.0, 30.0)}


def rgb_box(cam: str) -> tuple[float, ...]:
    x, y, w, h = THERMAL_BOX[cam]
    return (2 * x, 2 * y, 2 * w, 2 * h)       # the homography diag(2, 2, 1)


def rgb_frame(cam: str) -> np.ndarray:
    image = np.full((240, 320, 3), 90, np.uint8)
    x, y, w, h = (int(v) for v in rgb_box(cam))
    image[y:y + h, x:x + w] = (30, 40, 220)
    return image


def call(peer, client, request):
    # get / set parameters are idempotent: re-sent until answered (see call_service)
    return call_service(peer, client, request, ANSWER_TIMEOUT_S, resend_after=5.0)


def get_values(peer, node: str, names: list[str]):
    client = peer.node.create_client(GetParameters, f"{node}/get_parameters")
    return call(peer, client, GetParameters.Request(names=names)).values


@pytest.fixture
def pairs(node_group, tmp_path):
    params = tmp_path / "whole_numbers.yaml"
    params.write_text(WHOLE_NUMBERS)
    started = {}
    for cam in ("cam1", "cam2"):
        for module, shipped in (("detector_node", "detector.yaml"),
                                ("tracker_node", "tracker.yaml")):
            # a whole number on the command line too (/cam2's tracker)
            extra = (["-p", "detection_wait:=1"] if (cam, module) == ("cam2", "tracker_node")
                     else [])
            started[cam, module] = node_group.start(
                f"mk_tracker.ros.{module}", "--params-file", str(REPO / "config" / shipped),
                "--params-file", str(params), "-r", f"__ns:=/{cam}", *extra,
                ready=READY_LINES[module])
    return started


def test_two_namespaced_pairs_each_follow_their_own_camera(peer, pairs):
    for (cam, module), node in pairs.items():
        out = node.output()
        assert "Error" not in out and "expecting type" not in out, out
        if module == "detector_node":
            assert f"in /{cam}/thermal/image_raw -> /{cam}/thermal/detections" in out, out
        else:
            assert (f"tracking /{cam}/image_raw with detections from /{cam}/thermal/detections"
                    f" -> /{cam}/tracks") in out, out

    # whole numbers read back as doubles (namespaced parameter services)
    for cam in ("cam1", "cam2"):
        sigma, homography, wait = get_values(
            peer, f"/{cam}/tracker_node",
            ["tracker.kalman.sigma_u", "tracker.homography", "detection_wait"])
        assert sigma.type == Parameter.Type.DOUBLE.value and sigma.double_value == 25.0
        assert homography.type == Parameter.Type.DOUBLE_ARRAY.value
        assert list(homography.double_array_value) == [2.0, 0, 0, 0, 2.0, 0, 0, 0, 1.0]
        assert wait.type == Parameter.Type.DOUBLE.value
        assert wait.double_value == {"cam1": 2.0, "cam2": 1.0}[cam]
        (period,) = get_values(peer, f"/{cam}/detector_node", ["report_period"])
        assert period.type == Parameter.Type.DOUBLE.value and period.double_value == 7.0

    # each detector answers its own thermal frames only
    thermal_pubs, detections = {}, {}
    for cam in ("cam1", "cam2"):
        thermal_pubs[cam] = peer.publisher(Image, f"/{cam}/thermal/image_raw", RELIABLE)
        detections[cam] = peer.collect(Detection2DArray, f"/{cam}/thermal/detections", RELIABLE)
    assert peer.wait_matched(
        publishers=list(thermal_pubs.values()),
        subscriptions=[f"/{cam}/thermal/detections" for cam in ("cam1", "cam2")],
        node_inputs=[(pairs[cam, "detector_node"], f"/{cam}/thermal/image_raw")
                     for cam in ("cam1", "cam2")])
    thermal = np.zeros((120, 160), np.uint8)
    for i, cam in enumerate(("cam1", "cam2")):
        header = Header(stamp=make_stamp(1.0 + i), frame_id=f"{cam}_thermal_check")
        thermal_pubs[cam].publish(numpy_to_image(thermal, "mono8", header, types=TYPES))
        assert peer.spin_until(lambda: len(detections[cam]) >= 1, ANSWER_TIMEOUT_S), \
            pairs[cam, "detector_node"].output()
    for cam in ("cam1", "cam2"):
        assert [m.header.frame_id for m in detections[cam]] == [f"{cam}_thermal_check"]

    # each tracker follows the person of its own camera
    image_pubs, det_pubs, tracks = {}, {}, {}
    for cam in ("cam1", "cam2"):
        image_pubs[cam] = peer.publisher(Image, f"/{cam}/image_raw", RELIABLE)
        det_pubs[cam] = peer.publisher(Detection2DArray, f"/{cam}/thermal/detections",
                                       RELIABLE)
        tracks[cam] = peer.collect(Detection2DArray, f"/{cam}/tracks", RELIABLE)
    assert peer.wait_matched(
        publishers=list(image_pubs.values()) + list(det_pubs.values()),
        subscriptions=[f"/{cam}/tracks" for cam in ("cam1", "cam2")],
        node_inputs=[(pairs[cam, "tracker_node"], topic) for cam in ("cam1", "cam2")
                     for topic in (f"/{cam}/image_raw", f"/{cam}/thermal/detections")])
    for k in range(FRAMES):
        for cam in ("cam1", "cam2"):
            stamp = make_stamp(10.0 + 0.1 * k)
            det_header = Header(stamp=stamp, frame_id="thermal_camera")
            det_pubs[cam].publish(make_detection_array(
                [Detection(box=THERMAL_BOX[cam], score=0.9)], det_header, TYPES))
            image = numpy_to_image(rgb_frame(cam), "bgr8",
                                   Header(stamp=stamp, frame_id=f"{cam}_rgb"), types=TYPES)
            image_pubs[cam].publish(image)
            assert peer.spin_until(lambda: len(tracks[cam]) >= k + 1, ANSWER_TIMEOUT_S), \
                pairs[cam, "tracker_node"].output()
    for cam, other in (("cam1", "cam2"), ("cam2", "cam1")):
        assert len(tracks[cam]) == FRAMES
        assert {m.header.frame_id for m in tracks[cam]} == {f"{cam}_rgb"}
        boxes = [d.box for m in tracks[cam] for d in read_detection_array(m)]
        assert boxes, f"no track on /{cam}/tracks"
        x, y, w, h = rgb_box(cam)
        ox, oy = rgb_box(other)[:2]
        for bx, by, bw, bh in boxes:
            centre = np.array([bx + bw / 2, by + bh / 2])
            assert np.linalg.norm(centre - [x + w / 2, y + h / 2]) < 10.0, (cam, boxes)
            assert np.linalg.norm(centre - [ox + w / 2, oy + h / 2]) > 50.0

    # an integer set at run time is taken as a double
    client = peer.node.create_client(SetParameters, "/cam1/tracker_node/set_parameters")
    result = call(peer, client, SetParameters.Request(
        parameters=[Parameter("tracker.kalman.sigma_u", value=40).to_parameter_msg()]))
    assert result.results[0].successful, result.results[0].reason
    (sigma,) = get_values(peer, "/cam1/tracker_node", ["tracker.kalman.sigma_u"])
    assert sigma.type == Parameter.Type.DOUBLE.value and sigma.double_value == 40.0
    (other_sigma,) = get_values(peer, "/cam2/tracker_node", ["tracker.kalman.sigma_u"])
    assert other_sigma.double_value == 25.0
