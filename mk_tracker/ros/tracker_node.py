"""``tracker_node``: multiple-kernel tracking of people in RGB video, as a ROS 2 node.

A thin adapter around :class:`mk_tracker.tracking.multi_object_tracker.MultiObjectTracker` with the
projected-gradient multiple-kernel refiner (:mod:`mk_tracker.tracking.multi_kernel`, Chu et al.
2013) and Kalman filtering; every decision (association, staleness of detections, time
going backwards, lifecycle) is the library's, the per-frame glue is
:mod:`mk_tracker.frame_processing` (shared with the offline pipeline).

Topics (relative names, resolved in the node's namespace; change them by remapping, e.g.
``--ros-args -r image_raw:=/camera/image_raw``):

* subscribes ``image_raw`` (sensor_msgs/Image: rgb8, bgr8, rgba8, bgra8, mono8, yuv422,
  yuv422_yuy2, 8-bit Bayer; or, with ``image_transport: compressed``, sensor_msgs/
  CompressedImage JPEG/PNG on ``image_raw/compressed``), sensor-data QoS, depth 1; only
  the newest frame is processed, overwritten frames are counted and
  reported (:class:`mk_tracker.ros.latest_frame.LatestFrameWorker`);
* subscribes ``thermal/detections`` (vision_msgs/Detection2DArray from any publisher);
  the last ``detection_buffer`` messages are kept, and each frame gets those stamped at or
  before it, with their own stamps (later ones wait for a later frame); with
  ``detection_wait`` > 0 a frame first waits (at most that long) for the detections of its
  own stamp, so the pairing does not depend on arrival order
  (:class:`mk_tracker.frame_processing.DetectionBuffer`, the offline pipeline's rule too).  A message whose ``header.frame_id`` equals the image's frame is
  in the RGB plane; one equal to ``thermal_frame_id`` is mapped with ``tracker.homography``;
  any other frame is logged and skipped;
* subscribes ``~/start_track`` (vision_msgs/Detection2D): starts a track on its box by hand
  (box in the RGB plane, or in the thermal plane when its frame is ``thermal_frame_id``);
* serves ``~/start_track`` (mk_tracker_msgs/StartTrack, the same request as a service: the
  track is started on the next processed image and the answer carries its id) and
  ``~/stop_track`` (mk_tracker_msgs/StopTrack: deletes a track by id at once; an unknown id
  answers ``success`` false with the reason).  A topic and a service of the same name do not
  collide (DDS names them ``rt/...`` and ``rq/...Request``);
* publishes ``tracks`` (vision_msgs/Detection2DArray, header of the RGB image, ``id`` = the
  track id, score = similarity; confirmed tracks and briefly occluded ones), and
  ``~/tracks_detailed`` (mk_tracker_msgs/TrackedObjectArray, same header: every live track
  -- tentative, confirmed, occluded, lost -- with state, velocity and its covariance, age,
  time since detected; :mod:`mk_tracker.messages.track_messages`) on every processed
  image, and, when ``publish_debug_image`` is true,
  ``~/debug_image`` (bgr8) with boxes, ids, states and the kernels as ellipses, and the
  same as JPEG on ``~/debug_image/compressed``, each only while it has a subscriber;
* publishes ``/diagnostics`` (diagnostic_msgs/DiagnosticArray) every ``diagnostics.period``
  s: input and processed rate, dropped frames, latency (:mod:`mk_tracker.ros.node_diagnostics`).

Parameters: ``tracker.*`` (MultiObjectTrackerConfig, e.g. ``tracker.kalman.sigma_u``,
``tracker.homography``, ``tracker.multi_kernel.num_kernels``) and the node's own
(:class:`TrackerNodeConfig`); see :mod:`mk_tracker.ros.parameter_bridge` for the scheme.
"""

from __future__ import annotations

import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import Image

from mk_tracker.boxes import InvalidBoxError, as_box, center_to_xywh, transform_box
from mk_tracker.messages.detection_messages import (DetectionMessageError,
                                           make_detection_array, read_detection,
                                           read_detection_array)
from mk_tracker.frame_processing import (DetectionBatch, DetectionBuffer, detection_plane,
                                         kernel_drawings, tracker_config_for_encoding,
                                         tracker_debug_image, tracker_input,
                                         tracker_inputs, tracks_to_detections,
                                         step_detections)
from mk_tracker.messages.compressed_image import as_image
from mk_tracker.messages.image_transport import (image_transport_parameter,
                                                 no_image_warning_parameter)
from mk_tracker.ros.image_subscription import ImageSubscription
from mk_tracker.messages.image_conversion import ImageConversionError
from mk_tracker.messages.message_types import ros_message_types, stamp_to_seconds
from mk_tracker.messages.track_messages import (make_tracked_object_array,
                                                ros_track_message_types, tracked_objects)
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                             MultiObjectTrackerConfig, TrackerInputError)
from mk_tracker.parameters import ParameterError, parameter
from mk_tracker.node_health import DiagnosticsConfig
from mk_tracker.ros.debug_image_publisher import DebugImagePublisher, jpeg_quality_parameter
from mk_tracker.ros.latest_frame import LatestFrameWorker
from mk_tracker.ros.node_diagnostics import NodeDiagnostics
from mk_tracker.ros.node_runner import ReportTimer, log_shutdown, logged_warm_up, run_node
from mk_tracker.ros.parameter_bridge import ParameterBridge
from mk_tracker.ros.throttled_log import throttled_ros_log
from mk_tracker.ros.qos import SubscriptionQosConfig, publisher_qos, subscription_qos
from mk_tracker.ros.subscription_events import log_matches
from mk_tracker.warm_up import warm_up_tracker

NO_BOX = (0.0, 0.0, 0.0, 0.0)
#: Longest time (s) a ~/start_track service call waits for the image its track starts on.
START_TRACK_TIMEOUT = 10.0
#: Start requests (topic and service) waiting for the next processed image.
MAX_PENDING_STARTS = 10


@dataclass(eq=False)
class _StartRequest:
    """A start request waiting for the next image; ``reply(track_id, reason)`` answers a
    service call (``None`` for the topic): the id on success, ``None`` and why otherwise.

    Whoever :meth:`claim` s the request first decides it: the frame worker (which then
    starts the track) or the service's timeout (after which the request is dropped)."""

    frame_id: str
    box: tuple[float, float, float, float]
    source: str = "~/start_track"
    reply: Callable[[int | None, str], None] | None = None
    _claimed: bool = False
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def claim(self) -> bool:
        with self._lock:
            if self._claimed:
                return False
            self._claimed = True
            return True

    def answer(self, track_id: int | None, reason: str) -> None:
        if self.reply is not None:
            self.reply(track_id, reason)


#: Input and output topics (remap them; they are not parameters).
IMAGE_TOPIC = "image_raw"
DETECTIONS_TOPIC = "thermal/detections"
TRACKS_TOPIC = "tracks"


@dataclass(frozen=True)
class TrackerNodeConfig:
    """The node's own parameters (flat names; QoS grouped as ``image_qos.*`` ...)."""

    image_transport: str = image_transport_parameter()
    no_image_warning: float = no_image_warning_parameter()
    image_qos: SubscriptionQosConfig = parameter(SubscriptionQosConfig(),
                                                 "QoS of the image subscription")
    detections_qos: SubscriptionQosConfig = parameter(
        SubscriptionQosConfig(depth=10), "QoS of the detections subscription")
    publish_debug_image: bool = parameter(
        False, "Publish ~/debug_image (bgr8) and ~/debug_image/compressed (JPEG), each while "
        "it has a subscriber")
    debug_image_jpeg_quality: int = jpeg_quality_parameter()
    thermal_frame_id: str = parameter(
        "thermal_camera", "Detections with this header.frame_id are in the thermal plane and "
        "are mapped with tracker.homography")
    detection_buffer: int = parameter(
        5, "Detection messages kept between two processed frames (oldest dropped first)",
        minimum=1, maximum=1000, read_only=True)
    detection_wait: float = parameter(
        0.0, "Longest time (s) a frame waits for the detection message of its own stamp "
        "while detections are arriving; 0 = use what has arrived (lowest latency, but which "
        "frame a late detection lands on then depends on arrival order)",
        minimum=0.0, maximum=2.0)
    initial_box: tuple = parameter(
        NO_BOX, "[x, y, w, h] (top-left, px) of a track started on the first frame; "
        "w = h = 0 disables", minimum=0.0, read_only=True)
    class_id: str = parameter("person", "class_id written into the tracks' results")
    report_period: float = parameter(
        5.0, "Seconds between the logs of dropped frames and skipped input", minimum=0.1,
        maximum=3600.0)
    warm_up: bool = parameter(
        True, "Compile (first run) or load the multiple-kernel tracker's numba kernels before "
        "subscribing, so the first tracked frames are not stalled", read_only=True)
    diagnostics: DiagnosticsConfig = parameter(
        DiagnosticsConfig(), "/diagnostics: input rate, processed rate, dropped frames, latency")


def default_configs() -> dict[str, Any]:
    """Every config the node declares, by parameter prefix (for config/tracker.yaml)."""
    return {"": TrackerNodeConfig(), "tracker": MultiObjectTrackerConfig()}


def check_node_config(config: TrackerNodeConfig) -> None:
    """Constraints a range cannot express: an initial box is 4 numbers, both sides > 0."""
    box = config.initial_box
    if len(box) != 4:
        raise ParameterError(f"initial_box: needs 4 values [x, y, w, h], got {len(box)}")
    if tuple(float(v) for v in box) != NO_BOX and not (box[2] > 0 and box[3] > 0):
        raise ParameterError(f"initial_box: width and height must be > 0 (or all zero to "
                             f"disable), got {list(box)}")


def check_tracker_config(config: MultiObjectTrackerConfig) -> None:
    """The library's own check of a config (singular homography ...), as a ParameterError."""
    try:
        MultiObjectTracker(config)
    except TrackerInputError as exc:
        raise ParameterError(f"homography/config rejected by the tracker: {exc}") from exc


@dataclass
class _Counters:
    frames: int = 0
    bad_images: int = 0
    bad_detection_messages: int = 0
    bad_detections: int = 0
    unknown_frame: int = 0
    overflowed_detection_messages: int = 0
    detection_waits_timed_out: int = 0
    report_timer: ReportTimer = field(default_factory=ReportTimer)
    reported_drops: int = 0


class TrackerNode(Node):
    """The tracker node; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("tracker_node", **kwargs)
        self._types = ros_message_types()
        self._buffer_lock = threading.Lock()   # detection buffer and start requests
        self._detections_arrived = threading.Condition(self._buffer_lock)
        self._tracker_lock = threading.Lock()  # the tracker (worker thread vs parameters)
        self._warn = throttled_ros_log(self.get_logger(), "warning", period=1.0)
        self._error = throttled_ros_log(self.get_logger(), "error", period=1.0)
        self._event = throttled_ros_log(self.get_logger(), "info", period=1.0)
        self._bridge = ParameterBridge(self)
        self.node_config: TrackerNodeConfig = self._bridge.add_config(
            "", TrackerNodeConfig(), extra_check=check_node_config,
            on_change=self._on_node_config)
        tracker_cfg = self._bridge.add_config("tracker", MultiObjectTrackerConfig(),
                                              extra_check=check_tracker_config,
                                              on_change=self._on_tracker_config)
        self._tracker_config = tracker_cfg     # as set; the tracker's may differ by encoding
        self.tracker = MultiObjectTracker(tracker_cfg)
        self._bridge.activate()

        cfg = self.node_config
        self._detections = DetectionBuffer(cfg.detection_buffer, cfg.detection_wait)
        self._start_requests: deque[_StartRequest] = deque()
        self._initial_box_pending = tuple(float(v) for v in cfg.initial_box) != NO_BOX
        self._counters = _Counters()
        self._last_stamp: float | None = None

        from vision_msgs.msg import Detection2D, Detection2DArray
        from mk_tracker_msgs.msg import TrackedObjectArray
        from mk_tracker_msgs.srv import StartTrack, StopTrack
        self._track_types = ros_track_message_types()
        self._tracks_pub = self.create_publisher(Detection2DArray, TRACKS_TOPIC,
                                                 publisher_qos(10))
        self._detailed_pub = self.create_publisher(TrackedObjectArray, "~/tracks_detailed",
                                                   publisher_qos(10))
        self._debug = DebugImagePublisher(self, self._types)
        if cfg.warm_up and tracker_cfg.use_multi_kernel:
            logged_warm_up(self, "multiple-kernel tracker",
                           lambda: warm_up_tracker(tracker_cfg.multi_kernel))
        self._worker = LatestFrameWorker(self._process_image, self._on_worker_error,
                                         name="tracker_node-frames").start()
        self._diagnostics = NodeDiagnostics(
            self, lambda: self.node_config.diagnostics, self._worker,
            lambda: self._counters.bad_images, self.statistics)
        log = self.get_logger().info
        self._images = ImageSubscription(self, IMAGE_TOPIC, cfg.image_transport,
                                         self._worker.submit, subscription_qos(cfg.image_qos),
                                         cfg.no_image_warning)
        self.create_subscription(
            Detection2DArray, DETECTIONS_TOPIC, self._on_detections,
            subscription_qos(cfg.detections_qos),
            event_callbacks=log_matches(log, self.resolve_topic_name(DETECTIONS_TOPIC)))
        # reliable, like ``ros2 topic pub``: a hand-made command should not be lost
        self.create_subscription(Detection2D, "~/start_track", self._on_start_track,
                                 subscription_qos(SubscriptionQosConfig("reliable", 10)))
        # The start service awaits the next image: its coroutine and its timeout timer must
        # not sit in the node's default (mutually exclusive) callback group, which would keep
        # the image subscription from running until the call ends.
        self._start_group = ReentrantCallbackGroup()
        self.create_service(StartTrack, "~/start_track", self._on_start_track_service,
                            callback_group=self._start_group)
        self.create_service(StopTrack, "~/stop_track", self._on_stop_track_service)
        self.get_logger().info(
            f"tracking {self._images.topic} with detections from "
            f"{self.resolve_topic_name(DETECTIONS_TOPIC)} -> "
            f"{self.resolve_topic_name(TRACKS_TOPIC)}; "
            f"{tracker_cfg.multi_kernel.num_kernels} kernels per target")

    # -- parameters ----------------------------------------------------------------------
    def _on_node_config(self, config: TrackerNodeConfig) -> None:
        self.node_config = config
        with self._buffer_lock:
            self._detections.wait = config.detection_wait

    def _on_tracker_config(self, config: MultiObjectTrackerConfig) -> None:
        # MultiObjectTracker has no way to change its config in place (tracks keep the
        # Kalman/lifecycle constants they were created with).  A new tracker applies the
        # change everywhere, at the price of restarting the tracks.
        with self._tracker_lock:
            self._tracker_config = config
            self.tracker = MultiObjectTracker(config)
        self.get_logger().warning("tracker restarted with the new parameters (tracks reset)")

    # -- subscriptions (executor thread: store and return) -------------------------------
    def _on_detections(self, msg: Any) -> None:
        try:
            detections, skipped = read_detection_array(msg, on_error="skip")
            stamp = stamp_to_seconds(msg.header.stamp)
        except (DetectionMessageError, ValueError, AttributeError) as exc:
            self._counters.bad_detection_messages += 1
            self._warn(f"skipping a detections message: {exc}")
            return
        if skipped:
            self._counters.bad_detections += skipped
            self._warn(
                f"skipped {skipped} bad detection(s) (NaN or non-positive size, bad score) in "
                f"a message from frame {msg.header.frame_id!r}")
        with self._buffer_lock:
            if self._detections.add(DetectionBatch(stamp, msg.header.frame_id, detections),
                                    time.monotonic()):
                self._counters.overflowed_detection_messages += 1
            self._detections_arrived.notify_all()

    def _on_start_track(self, msg: Any) -> None:
        try:
            detection = read_detection(msg)
        except DetectionMessageError as exc:
            self.get_logger().warning(f"ignoring ~/start_track: {exc}")
            return
        if not self._queue_start(_StartRequest(msg.header.frame_id, detection.box)):
            self.get_logger().warning(
                f"ignoring ~/start_track: {MAX_PENDING_STARTS} requests already wait for the "
                "next image")

    def _queue_start(self, request: _StartRequest) -> bool:
        with self._buffer_lock:
            if len(self._start_requests) >= MAX_PENDING_STARTS:
                return False
            self._start_requests.append(request)
            return True

    async def _on_start_track_service(self, request: Any, response: Any) -> Any:
        """``~/start_track`` service: queue the box for the frame worker and wait (without
        blocking the executor: this is a coroutine awaiting an rclpy Future) for the id the
        next processed image gives it, at most :data:`START_TRACK_TIMEOUT` seconds."""
        try:
            b = request.box
            box = tuple(float(v) for v in as_box(center_to_xywh(
                float(b.center.position.x), float(b.center.position.y),
                float(b.size_x), float(b.size_y))))
        except (InvalidBoxError, AttributeError, TypeError, ValueError) as exc:
            response.success, response.message = False, f"bad box: {exc}"
            return response
        future = Future(executor=self.executor)
        # a done callback is scheduled on the executor, which wakes it up to resume us
        future.add_done_callback(lambda _future: None)
        pending = _StartRequest(request.frame_id, box,
                                reply=lambda track_id, reason: future.set_result(
                                    (track_id, reason)))
        if not self._queue_start(pending):
            response.success = False
            response.message = (f"{MAX_PENDING_STARTS} start requests already wait for the "
                                "next image; try again")
            return response

        def time_out() -> None:
            if pending.claim():
                pending.answer(None, f"no image was processed within {START_TRACK_TIMEOUT:g} "
                               "s; request withdrawn")

        timer = self.create_timer(START_TRACK_TIMEOUT, time_out,
                                  callback_group=self._start_group)
        try:
            track_id, reason = await future
        finally:
            timer.cancel()
            self.destroy_timer(timer)
        response.success = track_id is not None
        response.track_id = "" if track_id is None else str(track_id)
        response.message = reason
        return response

    def _on_stop_track_service(self, request: Any, response: Any) -> Any:
        """``~/stop_track`` service: delete the track at once (waits for a frame in
        progress, whose output may still hold it)."""
        text = str(request.track_id).strip()
        try:
            track_id = int(text)
        except ValueError:
            response.success = False
            response.message = f"track_id {request.track_id!r} is not a track id (an integer)"
            return response
        with self._tracker_lock:
            removed = self.tracker.stop_track(track_id)
        response.success = removed
        response.message = "" if removed else f"no live track has id {track_id}"
        if removed:
            self.get_logger().info(f"stopped track {track_id} (~/stop_track)")
        return response

    # -- frame processing (worker thread) ------------------------------------------------
    def _on_worker_error(self, exc: BaseException) -> None:
        self._error(f"frame processing failed ({type(exc).__name__}: {exc}); frame skipped")

    def _plane(self, frame_id: str, image_frame: str) -> str | None:
        return detection_plane(frame_id, image_frame, self.node_config.thermal_frame_id)

    def _process_image(self, msg: Image) -> None:
        counters = self._counters
        try:
            msg = as_image(msg)             # a CompressedImage is decoded here
            bgr = tracker_input(msg)
        except ImageConversionError as exc:
            counters.bad_images += 1
            self._warn(f"skipping an image: {exc}")
            return
        stamp = stamp_to_seconds(msg.header.stamp)
        frame = msg.header.frame_id
        with self._buffer_lock:
            deadline = time.monotonic() + self._detections.wait
            while self._detections.waiting(stamp, time.monotonic()):
                left = deadline - time.monotonic()
                if left <= 0.0:
                    counters.detection_waits_timed_out += 1
                    break
                self._detections_arrived.wait(left)
            discarded = self._detections.discarded
            batches = self._detections.take(stamp)
            discarded = self._detections.discarded - discarded
            starts = list(self._start_requests)
            self._start_requests.clear()
        with self._tracker_lock:
            wanted = tracker_config_for_encoding(self._tracker_config, msg.encoding)
            if wanted != self.tracker.config:   # the shared rule of thermal-only tracking
                self.tracker = MultiObjectTracker(wanted)
                self._event(f"{msg.encoding} images: the tracker uses "
                            f"{wanted.multi_kernel.colour_space} histograms (tracks reset)")
            tracker = self.tracker
            dets, unknown = tracker_inputs(batches, frame, self.node_config.thermal_frame_id)
            for frame_id in unknown:
                counters.unknown_frame += 1
                self._warn(
                    f"skipping detections in unknown frame {frame_id!r} (image frame "
                    f"{frame!r}, thermal_frame_id {self.node_config.thermal_frame_id!r})")
            if self._last_stamp is not None and stamp < self._last_stamp:
                self._warn(
                    f"image time went backwards by {self._last_stamp - stamp:.3f} s "
                    "(bag restarted?); the tracker decides what to do")
            if discarded:
                self._warn(f"dropped {discarded} detection message(s) stamped after this "
                           f"frame: time went backwards, they belong to the old time line")
            self._last_stamp = stamp
            try:
                self._start_tracks(tracker, bgr, stamp, frame, starts)
                result = tracker.step(bgr, stamp, step_detections(dets, batches))
            except (TrackerInputError, ValueError) as exc:
                counters.bad_images += 1
                self._warn(f"tracker rejected a frame: {exc}")
                return
        counters.frames += 1
        for event in result.events:
            self._event(event)
        reported = result.reported()
        class_id = self.node_config.class_id
        out = tracks_to_detections(reported, class_id)
        tracks_msg = make_detection_array(out, msg.header, self._types)
        # latency is read before the publish: a subscriber never sees an answer earlier
        self._diagnostics.published(msg.header)
        self._tracks_pub.publish(tracks_msg)
        if self._detailed_pub.get_subscription_count():   # built only for a reader
            self._detailed_pub.publish(make_tracked_object_array(
                tracked_objects(result.tracks, class_id, (t.id for t in reported)),
                msg.header, self._types,
                self._track_types))
        if self.node_config.publish_debug_image and self._debug.wanted():
            self._publish_debug(bgr, msg.header, reported, kernel_drawings(result), dets,
                                tracker)
        self._report()

    def _start_tracks(self, tracker: MultiObjectTracker, bgr: np.ndarray, stamp: float,
                      frame: str, starts: list[_StartRequest]) -> None:
        requests: list[_StartRequest] = []
        if self._initial_box_pending:
            self._initial_box_pending = False
            requests.append(_StartRequest("", tuple(self.node_config.initial_box),
                                          source="initial_box"))
        for request in starts:
            if not request.claim():
                continue                    # its service call timed out: withdrawn
            frame_id = request.frame_id
            plane = self._plane(frame_id, frame) if frame_id else "rgb"
            if plane is None:
                self._refuse(request, f"~/start_track in unknown frame {frame_id!r} ignored")
                continue
            if plane == "thermal":
                try:
                    request.box = tuple(transform_box(request.box, tracker.homography))
                except InvalidBoxError as exc:
                    self._refuse(request, f"~/start_track box cannot be mapped: {exc}")
                    continue
            requests.append(request)
        for request in requests:
            box = request.box
            try:
                track_id = tracker.start_track(bgr, stamp, box)
            except ValueError as exc:
                self._refuse(request, f"cannot start a track from {request.source} {box}: "
                             f"{exc}")
                continue
            self.get_logger().info(f"started track {track_id} from {request.source} at {box}")
            request.answer(track_id, "")

    def _refuse(self, request: _StartRequest, reason: str) -> None:
        self.get_logger().warning(reason)
        request.answer(None, reason)

    def _publish_debug(self, bgr: np.ndarray, header: Any, reported: list, kernels: dict,
                       dets: list[FrameDetection], tracker: MultiObjectTracker) -> None:
        w = self._worker
        canvas = tracker_debug_image(bgr, reported, kernels, dets, tracker.homography,
                                     [f"tracks {len(reported)}  frames {w.processed + 1}"
                                      f"  dropped {w.dropped}"])
        self._debug.publish(canvas, header, self.node_config.debug_image_jpeg_quality)

    def _report(self) -> None:
        c = self._counters
        if not c.report_timer.due(self.node_config.report_period):
            return
        received, _, dropped = self._worker.counts()
        totals = self.tracker.totals
        if dropped > c.reported_drops or c.bad_images or c.unknown_frame:
            self.get_logger().info(
                f"{c.frames} frames tracked, {dropped} dropped (newer frame arrived first), "
                f"{received} received, "
                f"{c.bad_images} bad images, {c.bad_detection_messages} bad detection "
                f"messages, {c.bad_detections} bad detections, {c.unknown_frame} detection "
                f"messages in unknown frames, {c.overflowed_detection_messages} overflowed, "
                f"{c.detection_waits_timed_out} frames stopped waiting for detections; "
                f"tracker: {totals}")
        c.reported_drops = dropped

    # -- shutdown ------------------------------------------------------------------------
    def statistics(self) -> dict[str, int]:
        c = self._counters
        received, _, dropped = self._worker.counts()
        return {"frames": c.frames, "received": received, "dropped": dropped,
                "bad_images": c.bad_images, "unknown_frame": c.unknown_frame,
                "bad_detection_messages": c.bad_detection_messages,
                "bad_detections": c.bad_detections,
                "detection_waits_timed_out": c.detection_waits_timed_out}

    def destroy_node(self) -> None:
        self._worker.stop()
        log_shutdown(self, self.statistics())
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of the ``tracker_node`` console script."""
    return run_node(TrackerNode, "tracker_node", args, end_process_after_interrupted_start=True)


if __name__ == "__main__":
    sys.exit(main())
