"""tracker_node's ``~/tracks_detailed`` (mk_tracker_msgs/TrackedObjectArray) and its track
services ``~/start_track`` / ``~/stop_track`` (mk_tracker_msgs), over DDS.

The scene is made here: a two-coloured block (a "person", 40 x 100 px) moves to the right
at a known 60 px/s over a static textured background at 25 frames/s.  Detections of its
true box (in the image's frame, so no homography) are published for every frame except
during a gap of 6 frames (0.24 s), in which the block is not drawn either: hidden and
undetected, the track must coast (occluded) and come back (confirmed) when it is detected
again.  Lock-step: detections, then the image, then wait for the node's
``~/tracks_detailed`` of that stamp before the next frame, so nothing depends on the
machine's speed; every wait is for an event, bounded 10-100x above the observed time.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mk_tracker_msgs.msg", reason="mk_tracker_msgs is not built into this venv")

from mk_tracker_msgs.msg import TrackedObject, TrackedObjectArray  # noqa: E402
from mk_tracker_msgs.srv import StartTrack, StopTrack  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.messages.detection_messages import (Detection, make_detection_array,  # noqa: E402
                                                    read_detection_array)
from mk_tracker.messages.image_conversion import numpy_to_image  # noqa: E402
from mk_tracker.messages.message_types import ros_message_types  # noqa: E402

from nodes_harness import (domain, latest_at, make_stamp, node_group, peer,  # noqa: E402,F401
                           reliable_qos)

TYPES = ros_message_types()
RELIABLE = reliable_qos()
FPS = 25.0
SPEED = 60.0                       # px/s, to the right
SIZE = (40.0, 100.0)
START = (60.0, 150.0)              # top-left at t = 0
GAP = range(20, 26)                # frames without detection, block hidden
FRAMES = 46
DETAILED = "/tracker_node/tracks_detailed"
STATE_NAMES = {TrackedObject.TENTATIVE: "tentative", TrackedObject.CONFIRMED: "confirmed",
               TrackedObject.OCCLUDED: "occluded", TrackedObject.LOST: "lost"}


def _background() -> np.ndarray:
    rng = np.random.default_rng(11)
    coarse = rng.integers(60, 160, (24, 32, 3), dtype=np.uint8)
    return np.kron(coarse, np.ones((20, 20, 1), np.uint8))          # 480 x 640, blocks


def _box(i: int) -> tuple[float, float, float, float]:
    return (START[0] + SPEED * i / FPS, START[1], SIZE[0], SIZE[1])


def _frame(i: int, visible: bool = True) -> np.ndarray:
    image = _background().copy()
    if visible:
        x, y, w, h = (int(round(v)) for v in _box(i))
        image[y:y + h // 2, x:x + w] = (40, 40, 220)      # red shirt (bgr)
        image[y + h // 2:y + h, x:x + w] = (200, 60, 30)  # blue trousers
    return image


class Scene:
    """Publishes frames in lock-step and collects both track topics."""

    def __init__(self, peer, node) -> None:
        self.peer = peer
        self.node = node
        self.image_pub = peer.publisher(Image, "image_raw", RELIABLE)
        self.det_pub = peer.publisher(Detection2DArray, "thermal/detections", RELIABLE)
        self.detailed = peer.collect(TrackedObjectArray, DETAILED, RELIABLE)
        self.tracks = peer.collect(Detection2DArray, "tracks", RELIABLE)

    def connect(self) -> None:
        ok = self.peer.wait_matched(
            publishers=[self.image_pub, self.det_pub], subscriptions=[DETAILED, "tracks"],
            node_inputs=[(self.node, "/image_raw"), (self.node, "/thermal/detections")])
        assert ok, f"tracker_node did not connect:\n{self.node.output()}"

    def step(self, i: int, detected: bool = True, visible: bool = True):
        """Frame ``i``; returns its (tracks_detailed, tracks) messages."""
        stamp = i / FPS
        first, first_tracks = len(self.detailed), len(self.tracks)
        header = Header(stamp=make_stamp(stamp), frame_id="camera")
        boxes = [Detection(box=_box(i), score=0.9)] if detected else []
        self.det_pub.publish(make_detection_array(boxes, header, TYPES))
        self.peer.spin_for(0.01)
        self.image_pub.publish(numpy_to_image(_frame(i, visible), "bgr8", header, types=TYPES))
        assert self.peer.spin_until(
            lambda: latest_at(self.detailed, stamp, first) is not None
            and latest_at(self.tracks, stamp, first_tracks) is not None, 30.0), \
            f"no answer to frame {i}:\n{self.node.output()}"
        return latest_at(self.detailed, stamp, first), latest_at(self.tracks, stamp,
                                                                 first_tracks)


def _collapse(states: list[str]) -> list[str]:
    return [s for k, s in enumerate(states) if k == 0 or states[k - 1] != s]


def test_a_person_goes_tentative_confirmed_occluded_confirmed(peer, node_group):
    node = node_group.start("mk_tracker.ros.tracker_node", "-p",
                            "image_qos.reliability:=reliable")
    scene = Scene(peer, node)
    scene.connect()
    states, velocities = [], []
    for i in range(FRAMES):
        hidden = i in GAP
        detailed, tracks = scene.step(i, detected=not hidden, visible=not hidden)
        assert detailed.header.frame_id == "camera"
        assert len(detailed.tracks) == 1, (i, detailed.tracks)
        track = detailed.tracks[0]
        assert track.detection.id == "1" and not track.started_by_hand
        states.append(STATE_NAMES[track.state])
        # age and time since detected are image time
        age = track.age.sec + track.age.nanosec * 1e-9
        assert age == pytest.approx(i / FPS, abs=1e-6)
        since = track.time_since_detected.sec + track.time_since_detected.nanosec * 1e-9
        expected_since = (i - GAP.start + 1) / FPS if hidden else 0.0
        assert since == pytest.approx(expected_since, abs=1e-6), i
        # `tracks` (unchanged) carries no tentative track, and the same box for a reported one
        published = read_detection_array(tracks)
        # `published` says whether the track is on `tracks` this frame
        assert track.published == bool(published), (i, STATE_NAMES[track.state])
        if track.state == TrackedObject.TENTATIVE:
            assert published == []
        if published:
            [p] = published
            d = track.detection
            assert p.id == d.id and p.box == pytest.approx(
                (d.bbox.center.position.x - d.bbox.size_x / 2,
                 d.bbox.center.position.y - d.bbox.size_y / 2, d.bbox.size_x, d.bbox.size_y))
        velocities.append((track.velocity_x, track.velocity_y,
                           tuple(track.velocity_covariance)))
    assert _collapse(states) == ["tentative", "confirmed", "occluded", "confirmed"], states
    assert states[:2] == ["tentative", "tentative"]       # min_hits = 3
    assert all(s == "occluded" for s in states[GAP.start:GAP.stop])
    # a plausible velocity: the true 60 px/s within 15 px/s, once the filter has seen the
    # person for a while, before the gap and at the end
    for i in (GAP.start - 1, FRAMES - 1):
        vx, vy, cov = velocities[i]
        assert vx == pytest.approx(SPEED, abs=15.0), (i, vx)
        assert vy == pytest.approx(0.0, abs=15.0), (i, vy)
        # a covariance: positive variances, symmetric, and far below the initial 2500
        assert 0.0 < cov[0] < 2500.0 and 0.0 < cov[3] < 2500.0 and cov[1] == cov[2]
    # the uncertainty of the velocity grows while it coasts unseen
    assert velocities[GAP.stop - 1][2][0] > velocities[GAP.start - 1][2][0]


def _call(peer, client, request, timeout: float = 30.0):
    future = client.call_async(request)
    assert peer.spin_until(future.done, timeout), "no answer from the service"
    return future.result()


def test_start_track_service_answers_the_id_and_stop_track_removes_it(peer, node_group):
    node = node_group.start("mk_tracker.ros.tracker_node", "-p",
                            "image_qos.reliability:=reliable")
    scene = Scene(peer, node)
    start = peer.node.create_client(StartTrack, "/tracker_node/start_track")
    stop = peer.node.create_client(StopTrack, "/tracker_node/stop_track")
    scene.connect()
    assert start.wait_for_service(timeout_sec=30.0) and stop.wait_for_service(timeout_sec=30.0)

    # a bad box is refused at once, without waiting for an image
    bad = StartTrack.Request()
    bad.box.size_x, bad.box.size_y = 0.0, 50.0
    answer = _call(peer, start, bad)
    assert not answer.success and answer.track_id == "" and "bad box" in answer.message

    detailed, _ = scene.step(0, detected=False)
    assert list(detailed.tracks) == []
    request = StartTrack.Request()
    x, y, w, h = _box(1)
    request.box.center.position.x, request.box.center.position.y = x + w / 2, y + h / 2
    request.box.size_x, request.box.size_y = w, h
    request.frame_id = "camera"
    future = start.call_async(request)
    # the request is served by the next processed image (lock-step frames until answered)
    i = 1
    while not future.done():
        assert i < 10, f"~/start_track not answered after {i - 1} frames:\n{node.output()}"
        scene.step(i, detected=False)
        peer.spin_until(future.done, 1.0)
        i += 1
    answer = future.result()
    assert answer.success and answer.message == "", answer
    track_id = answer.track_id
    assert track_id.isdigit()
    detailed, tracks = scene.step(i, detected=False)
    [track] = detailed.tracks
    assert track.detection.id == track_id and track.started_by_hand
    assert track.state == TrackedObject.CONFIRMED
    assert [t.id for t in read_detection_array(tracks)] == [track_id]

    answer = _call(peer, stop, StopTrack.Request(track_id=track_id))
    assert answer.success and answer.message == ""
    detailed, tracks = scene.step(i + 1, detected=False)
    assert list(detailed.tracks) == [] and read_detection_array(tracks) == []

    for unknown in (track_id, "999", "abc"):
        answer = _call(peer, stop, StopTrack.Request(track_id=unknown))
        assert not answer.success and answer.message, unknown
    assert "no live track has id 999" in _call(peer, stop,
                                                 StopTrack.Request(track_id="999")).message

    # a box in a frame the node does not know is refused by the next image, with the reason
    request.frame_id = "nowhere"
    future = start.call_async(request)
    i += 2
    while not future.done():
        assert i < 20, f"~/start_track not answered:\n{node.output()}"
        detailed, _ = scene.step(i, detected=False)
        peer.spin_until(future.done, 1.0)
        i += 1
    answer = future.result()
    assert not answer.success and answer.track_id == ""
    assert "unknown frame 'nowhere'" in answer.message
    assert list(scene.step(i, detected=False)[0].tracks) == []
    assert node.alive()


def test_start_track_without_images_times_out_and_is_withdrawn(peer, node_group):
    """No image within START_TRACK_TIMEOUT (10 s): the call answers why, the executor was
    never blocked (the stop service answers meanwhile), and a later image starts nothing."""
    from mk_tracker.ros.tracker_node import START_TRACK_TIMEOUT

    node = node_group.start("mk_tracker.ros.tracker_node", "-p",
                            "image_qos.reliability:=reliable")
    scene = Scene(peer, node)
    start = peer.node.create_client(StartTrack, "/tracker_node/start_track")
    stop = peer.node.create_client(StopTrack, "/tracker_node/stop_track")
    scene.connect()
    assert start.wait_for_service(timeout_sec=30.0) and stop.wait_for_service(timeout_sec=30.0)
    request = StartTrack.Request()
    request.box.center.position.x, request.box.center.position.y = 100.0, 200.0
    request.box.size_x, request.box.size_y = 40.0, 100.0
    sent = time.monotonic()
    future = start.call_async(request)
    # while the start call waits, the node's executor still serves other requests
    answer = _call(peer, stop, StopTrack.Request(track_id="5"))
    assert not answer.success
    if time.monotonic() - sent < START_TRACK_TIMEOUT:   # (always, unless the host stalls)
        assert not future.done()
    assert peer.spin_until(future.done, 6 * START_TRACK_TIMEOUT), node.output()
    answer = future.result()
    assert not answer.success and answer.track_id == ""
    assert "no image was processed" in answer.message
    detailed, tracks = scene.step(0, detected=False)
    assert list(detailed.tracks) == [] and read_detection_array(tracks) == []
    assert node.alive()
