"""Per-frame orchestration shared by the ROS nodes and the offline pipeline.

"The offline pipeline and the nodes call the same code": everything the detector node and
the tracker node decide for one frame, beyond converting messages, lives here, and
:mod:`mk_tracker.tools.pipeline` (``mk_tracker process``) calls the same functions, so both make
identical decisions on the same input.

* Detector side: which detector a ``method`` means (:func:`build_detector`), which image
  encodings it takes (:func:`thermal_input`), the reason a detector skipped a frame
  (:data:`SKIPPED_MODES`) and the conversion of its output into
  :class:`~mk_tracker.messages.detection_messages.Detection` (:func:`detector_outputs`).
* Tracker side: which image plane a detection message is in, decided by its
  ``header.frame_id`` (:func:`detection_plane`: the RGB image's frame, or the thermal
  camera's frame whose boxes the tracker maps with its homography), which buffered
  detection messages belong to which frame (:class:`DetectionBuffer`), the tracker's input
  list built from them (:func:`tracker_inputs`), the tracker configuration for the image's
  encoding (:func:`tracker_config_for_encoding`: a single-channel image, i.e. thermal-only
  tracking, uses ``multi_kernel.thermal_colour_space``) and the tracks that are published
  (:func:`tracks_to_detections`).
* Debug images: :func:`tracker_debug_image` and :func:`detector_debug_image` (what the
  nodes publish on ``~/debug_image`` and the pipeline writes into its video).

No rclpy here: messages are duck-typed (``rclpy`` and ``rosbags`` messages both work).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Iterable, Sequence

import numpy as np

from mk_tracker.boxes import InvalidBoxError, as_box, transform_box
from mk_tracker.drawing.debug_image import (KernelEllipse, TrackDrawing, draw_detections,
                                      draw_text_lines, draw_tracks, thermal_to_display)
from mk_tracker.messages.detection_messages import Detection, DetectionMessageError
from mk_tracker.messages.image_conversion import (CAMERA_ENCODINGS, ImageConversionError,
                                                  image_to_numpy, to_bgr, to_gray)
from mk_tracker.tracking.multi_object_tracker import FrameDetection, FrameResult
from mk_tracker.parameters import ParameterError
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig
from mk_tracker.detection.background_detector import BackgroundDetector, BackgroundDetectorConfig
from mk_tracker.detection.ignore_regions import MaskedDetector, parse_regions
from mk_tracker.detection.threshold_detector import ThresholdDetector, ThresholdDetectorConfig

RGB_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8", "mono8", *CAMERA_ENCODINGS)
#: YUV 4:2:2 (a thermal camera behind a UVC driver) gives its luma; Bayer is never thermal.
THERMAL_ENCODINGS = ("mono8", "mono16", "16UC1", "32FC1", "yuv422", "yuv422_yuy2")
METHODS = ("kernel_covariance", "threshold", "background")
#: what the background-subtraction detector takes (an RGB camera, or grey)
BACKGROUND_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8", "mono8", "mono16", "16UC1")
#: ``last_mode`` values of a detector that mean "this frame was not used", with the reason.
SKIPPED_MODES = {
    "invalid_frame": "too few finite pixels (NaN-filled or empty frame)",
    "out_of_order": "its stamp equals the previous frame's (a repeated frame)",
    "repeated_frame": "identical to the previous frame (the camera froze: shutter / "
                      "flat-field correction, or a driver repeating a frame)",
}


# -- detector side --------------------------------------------------------------------------

def build_detector(method: str, kernel_config: ThermalDetectorConfig,
                   threshold_config: ThresholdDetectorConfig,
                   ignore_regions: Sequence[float] = (),
                   background_config: BackgroundDetectorConfig | None = None) -> Any:
    """The detector object of ``method`` (one of :data:`METHODS`): the sparse kernel
    covariance detector (Schizas et al. 2018, Algorithm 2), the threshold baseline, or
    background subtraction for a static RGB camera (Chu et al. 2013, Sec. IV-D), seeing its
    frames through the ``ignore_regions`` (flat ``[x, y, w, h, ...]``,
    :mod:`mk_tracker.detection.ignore_regions`) when there are any."""
    try:
        regions = parse_regions(ignore_regions)
    except ValueError as exc:
        raise ParameterError(str(exc)) from exc
    if method == "kernel_covariance":
        detector: Any = ThermalDetector(kernel_config)
    elif method == "threshold":
        detector = ThresholdDetector(threshold_config)
    elif method == "background":
        detector = BackgroundDetector(background_config)
    else:
        raise ParameterError(f"method: {method!r} is not one of {list(METHODS)}")
    return MaskedDetector(detector, regions) if regions else detector


def detector_input(msg: Any, method: str) -> np.ndarray:
    """The pixels a detector of ``method`` takes from ``msg``: :func:`thermal_input` for the
    thermal methods; RGB, grey or 16-bit grey for ``background``."""
    if method != "background":
        return thermal_input(msg)
    if msg.encoding not in BACKGROUND_ENCODINGS:
        raise ImageConversionError(
            f"encoding {msg.encoding!r} is not a background-subtraction input "
            f"(supported: {', '.join(BACKGROUND_ENCODINGS)})")
    return image_to_numpy(msg)


def thermal_input(msg: Any) -> np.ndarray:
    """The pixels of a thermal ``sensor_msgs/Image``; raises
    :class:`~mk_tracker.messages.image_conversion.ImageConversionError` for another encoding or
    broken data."""
    if msg.encoding not in THERMAL_ENCODINGS:
        raise ImageConversionError(
            f"encoding {msg.encoding!r} is not a thermal detector input "
            f"(supported: {', '.join(THERMAL_ENCODINGS)})")
    if msg.encoding in CAMERA_ENCODINGS:
        return to_gray(image_to_numpy(msg), msg.encoding)
    return image_to_numpy(msg)


def detector_outputs(found: Iterable[Any], class_id: str) -> tuple[list[Detection], list[str]]:
    """A detector's output as :class:`Detection` (empty id) plus one message per dropped
    bad detection (non-finite or empty box, non-finite score)."""
    out: list[Detection] = []
    errors: list[str] = []
    for det in found:
        try:
            out.append(Detection(box=tuple(det.box), score=float(det.score), class_id=class_id))
        except (DetectionMessageError, TypeError, ValueError) as exc:
            errors.append(f"dropping a bad detection: {exc}")
    return out, errors


def skipped_reason(detector: Any) -> str | None:
    """Why the detector did not use its last frame (:data:`SKIPPED_MODES`), or None."""
    return SKIPPED_MODES.get(getattr(detector, "last_mode", ""))


def detector_event(detector: Any) -> str | None:
    """What the detector's last frame changed in its state (a reset because time went
    backwards, or the frame size or encoding changed), in words, or None."""
    return getattr(detector, "last_event", None) or None


# -- tracker side ---------------------------------------------------------------------------

@dataclass
class DetectionBatch:
    """One received detection message: its header stamp (s), frame id and detections."""

    stamp: float
    frame_id: str
    detections: list[Detection]


#: Detections count as "expected" (a detector is running) while the last message arrived
#: at most this long (s, plus the wait itself) before a frame; see :class:`DetectionBuffer`.
DETECTOR_SILENCE = 1.0


class DetectionBuffer:
    """Detection messages waiting for the RGB frame they belong to (both nodes' and the
    offline pipeline's pairing rule, so they pair the same way).

    * :meth:`take` hands frame ``T`` every buffered batch stamped at or before ``T``;
      batches stamped after it stay for a later frame (a detection is never applied to a
      frame older than itself).  When frame time goes backwards (a bag restarted), batches
      from the old time line (stamped after the new frame) are discarded and counted.
    * With ``wait > 0``, :meth:`waiting` tells a frame to wait (at most ``wait`` seconds)
      until a batch stamped at or after it has arrived -- the detections of its own time, or
      a later message that proves they will not come -- so that which frame a detection
      lands on does not depend on whether the detector's answer or the next image arrived
      first.  Only while detections are arriving at all (one within
      :data:`DETECTOR_SILENCE` + ``wait`` s): without a detector nothing waits.
      ``wait = 0`` uses what has arrived (lowest latency; the pairing then follows arrival
      order).
    * At most ``capacity`` batches are held; the oldest goes first (:attr:`overflowed`).

    Times passed as ``now`` are any monotonic clock in seconds: the node's
    ``time.monotonic()``, the pipeline's bag time.  Not thread-safe (the node locks it).
    """

    def __init__(self, capacity: int, wait: float = 0.0) -> None:
        if int(capacity) < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        if not (math.isfinite(float(wait)) and float(wait) >= 0.0):
            raise ValueError(f"wait must be a finite number >= 0, got {wait}")
        self.capacity = int(capacity)
        self.wait = float(wait)
        self._batches: list[DetectionBatch] = []
        self._newest_stamp: float | None = None
        self._last_arrival: float | None = None
        self._last_frame: float | None = None
        self.overflowed = 0
        self.discarded = 0

    def __len__(self) -> int:
        return len(self._batches)

    def add(self, batch: DetectionBatch, now: float) -> bool:
        """Buffer ``batch`` (arrived at ``now``); True when the oldest one was dropped to make
        room."""
        dropped = len(self._batches) >= self.capacity
        if dropped:
            self._batches.pop(0)
            self.overflowed += 1
        self._batches.append(batch)
        self._last_arrival = float(now)
        if self._newest_stamp is None or batch.stamp > self._newest_stamp:
            self._newest_stamp = batch.stamp
        return dropped

    def waiting(self, stamp: float, now: float) -> bool:
        """Whether frame ``stamp`` should still wait for its detections at ``now``."""
        if self.wait <= 0.0 or self._last_arrival is None:
            return False
        if now - self._last_arrival > DETECTOR_SILENCE + self.wait:
            return False                      # no detector is running: nothing to wait for
        if self._last_frame is not None and stamp < self._last_frame:
            return False                      # time went backwards: take() sorts it out
        return self._newest_stamp is None or self._newest_stamp < stamp

    def take(self, stamp: float) -> list[DetectionBatch]:
        """Remove and return the batches for frame ``stamp`` (stamped at or before it)."""
        if self._last_frame is not None and stamp < self._last_frame:
            old = [b for b in self._batches if b.stamp > stamp]
            self.discarded += len(old)
            self._batches = [b for b in self._batches if b.stamp <= stamp]
            self._newest_stamp = max((b.stamp for b in self._batches), default=None)
        self._last_frame = stamp
        now = [b for b in self._batches if b.stamp <= stamp]
        self._batches = [b for b in self._batches if b.stamp > stamp]
        return now

    def clear(self) -> None:
        """Forget every batch (and what arrived when)."""
        self._batches.clear()
        self._newest_stamp = self._last_arrival = self._last_frame = None


def tracker_input(msg: Any) -> np.ndarray:
    """The BGR pixels of an RGB ``sensor_msgs/Image`` (contiguous); raises
    :class:`~mk_tracker.messages.image_conversion.ImageConversionError` for a non-RGB encoding or
    broken data."""
    if msg.encoding not in RGB_ENCODINGS:
        raise ImageConversionError(
            f"encoding {msg.encoding!r} is not an RGB tracker input "
            f"(supported: {', '.join(RGB_ENCODINGS)})")
    return np.ascontiguousarray(to_bgr(image_to_numpy(msg), msg.encoding))


#: Encodings of one channel (grey-replicated into BGR by :func:`tracker_input`): a thermal
#: camera (thermal-only tracking) or a monochrome one, with no colour for HSV to see.
SINGLE_CHANNEL_ENCODINGS = ("mono8", "mono16", "16UC1", "32FC1")


def tracker_config_for_encoding(config: Any, encoding: str) -> Any:
    """The tracker configuration (``MultiObjectTrackerConfig``) for images of ``encoding``:
    ``config`` itself, except that a single-channel encoding
    (:data:`SINGLE_CHANNEL_ENCODINGS`) makes ``multi_kernel.colour_space`` the configured
    ``multi_kernel.thermal_colour_space``.  The one rule of the node and the offline
    pipeline for thermal-only tracking (docs/ros_nodes.md)."""
    mk = config.multi_kernel
    if encoding not in SINGLE_CHANNEL_ENCODINGS or mk.thermal_colour_space == mk.colour_space:
        return config
    return replace(config, multi_kernel=replace(mk, colour_space=mk.thermal_colour_space))


def detection_plane(frame_id: str, image_frame_id: str, thermal_frame_id: str) -> str | None:
    """``"rgb"`` when detections are in the image's own frame, ``"thermal"`` in the thermal
    camera's frame (mapped by the tracker's homography), None for any other frame."""
    if frame_id == image_frame_id:
        return "rgb"
    if frame_id == thermal_frame_id:
        return "thermal"
    return None


def tracker_inputs(batches: Iterable[DetectionBatch], image_frame_id: str,
                   thermal_frame_id: str) -> tuple[list[FrameDetection], list[str]]:
    """The tracker's detections for one frame from the batches received since the last one.

    Every detection keeps its own message's stamp (the tracker brings it to the frame time,
    Schizas et al. 2018 (2.1)-(2.2)).  Returns ``(detections, unknown)``: ``unknown`` lists
    the frame ids of batches left out because they are in neither plane.
    """
    dets: list[FrameDetection] = []
    unknown: list[str] = []
    for batch in batches:
        plane = detection_plane(batch.frame_id, image_frame_id, thermal_frame_id)
        if plane is None:
            unknown.append(batch.frame_id)
            continue
        dets.extend(FrameDetection(box=d.box, score=d.score, stamp=batch.stamp, plane=plane)
                    for d in batch.detections)
    return dets, unknown


def step_detections(dets: list[FrameDetection], batches: Sequence[DetectionBatch]
                    ) -> list[FrameDetection] | None:
    """What :meth:`MultiObjectTracker.step` takes for a frame: its detections, or None when
    no detection message was paired with it (the detector is slower than the camera, or
    late): a frame the detector did not report on is not a frame in which it found nobody."""
    return dets if batches else None


def _finite(box: Sequence[float]) -> bool:
    return all(math.isfinite(float(v)) for v in box) and box[2] > 0 and box[3] > 0


def tracks_to_detections(reported: Iterable[Any], class_id: str) -> list[Detection]:
    """Published tracks: one :class:`Detection` per reported track with a finite box,
    ``id`` = the track id, score = the track score clipped to [0, 1]."""
    return [Detection(box=tuple(t.box), score=min(max(float(t.score), 0.0), 1.0),
                      class_id=class_id, id=str(t.id))
            for t in reported if _finite(t.box)]


# -- debug images ---------------------------------------------------------------------------

def kernel_drawings(result: FrameResult) -> dict[int, list[KernelEllipse]]:
    """Kernel ellipses per track id from a tracker step's output (``FrameResult.kernels``:
    the multiple-kernel targets' centres and half-axes, Chu et al. 2013, Sec. III)."""
    return {tid: [KernelEllipse(c, a) for c, a in zip(k.centres, k.half_axes)]
            for tid, k in result.kernels.items()}


def detection_boxes_in_rgb(dets: Iterable[FrameDetection], homography: np.ndarray
                           ) -> list[tuple[float, ...]]:
    """The tracker's input boxes in the RGB plane (unmappable boxes left out)."""
    out = []
    for d in dets:
        try:
            out.append(tuple(transform_box(d.box, homography)) if d.plane == "thermal"
                       else tuple(as_box(d.box)))
        except InvalidBoxError:
            continue
    return out


def tracker_debug_image(bgr: np.ndarray, reported: Iterable[Any],
                        kernels: dict[int, list[KernelEllipse]],
                        dets: Iterable[FrameDetection], homography: np.ndarray,
                        status: Sequence[str] = (),
                        ground_truth: Iterable[Sequence[float]] = ()) -> np.ndarray:
    """The tracker's debug image: detections (yellow), optional ground truth (thin white),
    tracks with id/state/score and their kernels, and ``status`` lines."""
    canvas = draw_detections(bgr, detection_boxes_in_rgb(dets, homography))
    truth = list(ground_truth)
    if truth:
        canvas = draw_detections(canvas, truth, color=(255, 255, 255))
    canvas = draw_tracks(canvas, [TrackDrawing(t.box, t.id, t.state, t.score,
                                               kernels.get(t.id, ())) for t in reported])
    return draw_text_lines(canvas, list(status)) if status else canvas


def detector_debug_image(frame: np.ndarray, encoding: str, detections: Sequence[Detection],
                         method: str) -> np.ndarray:
    """The detector's debug image: the colour-mapped thermal frame with the boxes."""
    canvas = draw_detections(thermal_to_display(frame, encoding),
                             [d.box for d in detections], [d.score for d in detections])
    return draw_text_lines(canvas, [f"{method}: {len(detections)} people"])
