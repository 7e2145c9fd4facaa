"""``detector_node``: people detection in thermal video, as a ROS 2 node.

A thin adapter around :class:`mk_tracker.detection.thermal_detector.ThermalDetector` (sparse kernel
covariance factorization, Schizas, Maroulas & Ren 2018) and the threshold baseline
:mod:`mk_tracker.detection.threshold_detector`; the ``method`` parameter selects one.

Topics (relative names, resolved in the node's namespace; change them by remapping, e.g.
``--ros-args -r thermal/image_raw:=/flir/image_raw``):

* subscribes ``thermal/image_raw`` (sensor_msgs/Image: mono8, mono16, 16UC1, 32FC1, yuv422
  luma; or, with ``image_transport: compressed``, sensor_msgs/CompressedImage PNG/JPEG on
  ``thermal/image_raw/compressed``), sensor-data QoS, depth 1; only the newest frame is processed, overwritten frames are
  counted and reported (:class:`mk_tracker.ros.latest_frame.LatestFrameWorker`);
* publishes ``thermal/detections`` (vision_msgs/Detection2DArray): header copied from the
  image, ``id`` empty, one result with ``class_id`` and the detector's score
  (conventions of :mod:`mk_tracker.messages.detection_messages`);
* publishes ``~/debug_image`` (bgr8, colour-mapped thermal with the boxes) and
  ``~/debug_image/compressed`` (JPEG, ``debug_image_jpeg_quality``) when
  ``publish_debug_image`` is true, each only while it has a subscriber
  (:mod:`mk_tracker.ros.debug_image_publisher`);
* publishes ``/diagnostics`` (diagnostic_msgs/DiagnosticArray) every ``diagnostics.period``
  s: input and processed rate, dropped frames, latency (:mod:`mk_tracker.ros.node_diagnostics`).

Parameters: ``detector.*`` (ThermalDetectorConfig), ``threshold.*`` (the baseline's
config) and the node's own (:class:`DetectorNodeConfig`); see
:mod:`mk_tracker.ros.parameter_bridge` for the scheme.  Bad frames (unsupported encoding,
short data, empty or all-NaN images) are logged (throttled) and skipped.
"""

from __future__ import annotations

import sys
import threading
from dataclasses import dataclass, field
from typing import Any

from rclpy.node import Node
from sensor_msgs.msg import Image

from mk_tracker.messages.detection_messages import make_detection_array
from mk_tracker.detection.ignore_regions import parse_regions
from mk_tracker.frame_processing import (METHODS, build_detector, detector_debug_image,
                                         detector_event, detector_outputs, skipped_reason,
                                         detector_input)
from mk_tracker.messages.compressed_image import as_image
from mk_tracker.messages.image_transport import (image_transport_parameter,
                                                 no_image_warning_parameter)
from mk_tracker.ros.image_subscription import ImageSubscription
from mk_tracker.messages.image_conversion import ImageConversionError
from mk_tracker.messages.message_types import ros_message_types, stamp_to_seconds
from mk_tracker.parameters import ParameterError, parameter
from mk_tracker.node_health import DiagnosticsConfig
from mk_tracker.ros.debug_image_publisher import DebugImagePublisher, jpeg_quality_parameter
from mk_tracker.ros.latest_frame import LatestFrameWorker
from mk_tracker.ros.node_diagnostics import NodeDiagnostics
from mk_tracker.ros.node_runner import ReportTimer, log_shutdown, logged_warm_up, run_node
from mk_tracker.ros.parameter_bridge import ParameterBridge
from mk_tracker.ros.throttled_log import throttled_ros_log
from mk_tracker.ros.qos import SubscriptionQosConfig, publisher_qos, subscription_qos
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig
from mk_tracker.detection.threshold_detector import ThresholdDetector, ThresholdDetectorConfig
from mk_tracker.detection.background_detector import BackgroundDetector, BackgroundDetectorConfig
from mk_tracker.warm_up import warm_up_detector

#: Input and output topics (remap them; they are not parameters).
IMAGE_TOPIC = "thermal/image_raw"
DETECTIONS_TOPIC = "thermal/detections"


@dataclass(frozen=True)
class DetectorNodeConfig:
    """The node's own parameters (flat names; QoS grouped as ``image_qos.*``)."""

    image_qos: SubscriptionQosConfig = parameter(SubscriptionQosConfig(),
                                                 "QoS of the image subscription")
    image_transport: str = image_transport_parameter()
    no_image_warning: float = no_image_warning_parameter()
    method: str = parameter(
        "kernel_covariance", "Detection method: sparse kernel covariance factorization "
        "(Schizas et al. 2018) or the threshold baseline", choices=METHODS)
    ignore_regions: tuple = parameter(
        (0.0, 0.0, 0.0, 0.0), "Image boxes where nothing is detected (burned-in overlays, "
        "heaters, screens): flat [x, y, w, h, x, y, w, h, ...] in pixels, top-left corner; a "
        "box with w or h = 0 is a placeholder (the default: no region)", minimum=0.0)
    publish_debug_image: bool = parameter(
        False, "Publish ~/debug_image (bgr8) and ~/debug_image/compressed (JPEG), each while "
        "it has a subscriber")
    debug_image_jpeg_quality: int = jpeg_quality_parameter()
    class_id: str = parameter("person", "class_id written into every detection's result")
    report_period: float = parameter(
        5.0, "Seconds between the logs of dropped frames and skipped input", minimum=0.1,
        maximum=3600.0)
    warm_up: bool = parameter(
        True, "Compile (first run) or load the detector's numba kernels before subscribing, "
        "so the first frames are not stalled", read_only=True)
    diagnostics: DiagnosticsConfig = parameter(
        DiagnosticsConfig(), "/diagnostics: input rate, processed rate, dropped frames, latency")


def default_configs() -> dict[str, Any]:
    """Every config the node declares, by parameter prefix (for config/detector.yaml)."""
    return {"": DetectorNodeConfig(), "detector": ThermalDetectorConfig(),
            "threshold": ThresholdDetectorConfig(), "background": BackgroundDetectorConfig()}


def _check_with(factory: Any) -> Any:
    """An extra_check that builds the library object, turning its errors into ParameterError."""
    def check(config: Any) -> None:
        try:
            factory(config)
        except ParameterError:
            raise
        except ValueError as exc:
            raise ParameterError(str(exc)) from exc
    return check


def _check_regions(config: DetectorNodeConfig) -> None:
    try:
        parse_regions(config.ignore_regions)
    except ValueError as exc:
        raise ParameterError(str(exc)) from exc


@dataclass
class _Counters:
    frames: int = 0
    detections: int = 0
    bad_images: int = 0
    rejected_frames: int = 0
    report_timer: ReportTimer = field(default_factory=ReportTimer)
    reported_drops: int = 0


class DetectorNode(Node):
    """The detector node; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("detector_node", **kwargs)
        self._types = ros_message_types()
        self._lock = threading.Lock()     # the detector (worker thread vs parameters)
        self._warn = throttled_ros_log(self.get_logger(), "warning", period=1.0)
        self._error = throttled_ros_log(self.get_logger(), "error", period=1.0)
        self._event = throttled_ros_log(self.get_logger(), "info", period=1.0)
        self._bridge = ParameterBridge(self)
        self.node_config: DetectorNodeConfig = self._bridge.add_config(
            "", DetectorNodeConfig(), on_change=self._on_node_config,
            extra_check=_check_regions)
        kernel_cfg = self._bridge.add_config(
            "detector", ThermalDetectorConfig(), extra_check=_check_with(ThermalDetector),
            on_change=lambda _cfg: self._rebuild_if_active("kernel_covariance"))
        threshold_cfg = self._bridge.add_config(
            "threshold", ThresholdDetectorConfig(), extra_check=_check_with(ThresholdDetector),
            on_change=lambda _cfg: self._rebuild_if_active("threshold"))
        self._bridge.add_config(
            "background", BackgroundDetectorConfig(),
            extra_check=_check_with(BackgroundDetector),
            on_change=lambda _cfg: self._rebuild_if_active("background"))
        self.detector = self._build()
        self._bridge.activate()
        self._counters = _Counters()
        self._last_stamp: float | None = None

        from vision_msgs.msg import Detection2DArray
        cfg = self.node_config
        self._detections_pub = self.create_publisher(Detection2DArray, DETECTIONS_TOPIC,
                                                     publisher_qos(10))
        self._debug = DebugImagePublisher(self, self._types)
        if cfg.warm_up and cfg.method == "kernel_covariance":
            logged_warm_up(self, "sparse kernel covariance detector",
                           lambda: warm_up_detector(kernel_cfg))
        self._worker = LatestFrameWorker(self._process_image, self._on_worker_error,
                                         name="detector_node-frames").start()
        self._diagnostics = NodeDiagnostics(
            self, lambda: self.node_config.diagnostics, self._worker,
            lambda: self._counters.bad_images + self._counters.rejected_frames,
            self.statistics)
        self._images = ImageSubscription(self, IMAGE_TOPIC, cfg.image_transport,
                                         self._worker.submit, subscription_qos(cfg.image_qos),
                                         cfg.no_image_warning)
        self.get_logger().info(
            f"detecting people ({cfg.method}) in {self._images.topic} -> "
            f"{self.resolve_topic_name(DETECTIONS_TOPIC)}")

    # -- parameters ----------------------------------------------------------------------
    def _on_node_config(self, config: DetectorNodeConfig) -> None:
        rebuild = (config.method != self.node_config.method
                   or tuple(config.ignore_regions) != tuple(self.node_config.ignore_regions))
        self.node_config = config
        if rebuild:
            self._rebuild_if_active(config.method)

    def _build(self) -> Any:
        return build_detector(self.node_config.method, self._bridge.config("detector"),
                              self._bridge.config("threshold"),
                              self.node_config.ignore_regions,
                              self._bridge.config("background"))

    def _rebuild_if_active(self, method: str) -> None:
        """Apply a changed config; the detector not in use is built when selected."""
        if method != self.node_config.method:
            return
        # a detector holds a sliding window of frames; a new config starts a new window
        with self._lock:
            self.detector = self._build()
        self.get_logger().info(f"detector rebuilt ({self.node_config.method}) with the new "
                               "parameters")

    # -- frame processing (worker thread) ------------------------------------------------
    def _on_worker_error(self, exc: BaseException) -> None:
        self._error(f"frame processing failed ({type(exc).__name__}: {exc}); frame skipped")

    def _process_image(self, msg: Image) -> None:
        counters = self._counters
        try:
            msg = as_image(msg)             # a CompressedImage is decoded here
            frame = detector_input(msg, self.node_config.method)
        except ImageConversionError as exc:
            counters.bad_images += 1
            self._warn(f"skipping a thermal image: {exc}")
            return
        stamp = stamp_to_seconds(msg.header.stamp)
        with self._lock:
            detector = self.detector
            if self._last_stamp is not None and stamp < self._last_stamp \
                    and not hasattr(detector, "time_resets"):
                # a detector that keeps no time (threshold): nothing to reset, only say so
                self._warn(f"thermal time went backwards by {self._last_stamp - stamp:.3f} s "
                           "(bag restarted?)")
            self._last_stamp = stamp
            try:
                found = detector.process(frame, stamp, encoding=msg.encoding)
            except ValueError as exc:   # the libraries' own input errors
                counters.rejected_frames += 1
                self._warn(f"detector skipped a frame: {exc}")
                return
            reason = skipped_reason(detector)
            if reason:
                counters.rejected_frames += 1
                self._warn(f"detector skipped the frame of stamp {stamp:.3f}: {reason}")
            event = detector_event(detector)
            if event:
                # the library resets itself (time went backwards: a looping bag; another
                # frame size or encoding) and says why
                self._warn(f"thermal detector: {event}")
        out, errors = detector_outputs(found, self.node_config.class_id)
        for error in errors:
            self._warn(error)
        counters.frames += 1
        counters.detections += len(out)
        detections_msg = make_detection_array(out, msg.header, self._types)
        # latency is read before the publish: a subscriber never sees an answer earlier
        self._diagnostics.published(msg.header)
        self._detections_pub.publish(detections_msg)
        if self.node_config.publish_debug_image and self._debug.wanted():
            canvas = detector_debug_image(frame, msg.encoding, out, self.node_config.method)
            self._debug.publish(canvas, msg.header, self.node_config.debug_image_jpeg_quality)
        self._report()

    def _report(self) -> None:
        c = self._counters
        if not c.report_timer.due(self.node_config.report_period):
            return
        received, _, dropped = self._worker.counts()
        if dropped > c.reported_drops or c.bad_images or c.rejected_frames:
            self.get_logger().info(
                f"{c.frames} frames, {c.detections} detections, {dropped} frames dropped "
                f"(newer frame arrived first), {received} frames received, "
                f"{c.bad_images} bad images, "
                f"{c.rejected_frames} frames rejected by the detector")
        c.reported_drops = dropped

    def statistics(self) -> dict[str, int]:
        c = self._counters
        received, _, dropped = self._worker.counts()
        return {"frames": c.frames, "detections": c.detections, "received": received,
                "dropped": dropped, "bad_images": c.bad_images,
                "rejected_frames": c.rejected_frames}

    def destroy_node(self) -> None:
        self._worker.stop()
        log_shutdown(self, self.statistics())
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of the ``detector_node`` console script."""
    return run_node(DetectorNode, "detector_node", args, end_process_after_interrupted_start=True)


if __name__ == "__main__":
    sys.exit(main())
