"""``mk_tracker process BAG --out DIR``: detection and tracking over a bag, offline.

The same libraries and the same per-frame decisions as ``detector_node`` and
``tracker_node`` (:mod:`mk_tracker.frame_processing`), without DDS, as fast as the machine
allows.  Messages are taken in bag-time order; messages of one time stamp are handled in
the order "scene info, detector inputs and detection messages, ground truth, RGB images", so
an RGB frame is tracked with the detections of the thermal frame taken at the same instant
(what the nodes do when the detector answers before the next RGB frame arrives; the demo
plays slowly enough for that).  As in the tracker node, detection messages are buffered
(``detection_buffer`` newest) and each RGB frame gets those stamped at or before it, with
their own stamps; with ``detection_wait`` > 0 an RGB frame is held until a detection message
stamped at or after it has been read, or until the bag time has moved ``detection_wait``
past it (:class:`~mk_tracker.frame_processing.DetectionBuffer`, the node's rule with bag
time as its clock).

Detection source (``--detections``): ``thermal`` runs the detector node's detector
(``method`` parameter) on ``/thermal/image_raw``; ``topic:NAME`` uses Detection2DArray
messages already in the bag (e.g. ``/detections`` of a MOTChallenge import); ``none`` tracks
without detections (single-target runs); ``auto`` picks thermal if the bag has thermal
images, else a detection topic (``/thermal/detections``, ``/detections``), else none.
Detections of another detector (a topic other than ``/thermal/detections``) scored in
[0, 1] are tracked with ``config/tracker_public_detections.yaml`` on top of
``config/tracker.yaml``, the background detector's boxes with
``config/tracker_background_detections.yaml`` (``--tracker-profile``,
:func:`~mk_tracker.tools.pipeline_config.tracker_profile`).

Single target (the protocol of Chu et al. 2013, Table I): ``--init x,y,w,h`` starts a track
on the first frame, ``--init-from-gt [ID]`` on the first ground-truth box of ID (default:
the first box in the bag); detections default to none then.

Outputs in ``DIR``: ``bag/`` (the input topics plus ``/thermal/detections`` and
``/tracks``), ``tracks.txt`` (MOTChallenge: frame = 1-based index of the RGB image in the
bag), ``video.mp4`` (annotated), ``errors.png`` (per-frame errors) and ``summary.json``
(counts, timings, scores) when the bag carries ``/ground_truth``.  A bad message (broken
image, undecodable bytes) is logged, counted and skipped; it never ends the run.

Parameters come from the nodes' YAML files: ``config/detector.yaml`` and
``config/tracker.yaml`` of the package, overridden by each ``--params-file``.  When the
tracker's homography is the identity and the bag has ``/scene_info`` (a synthetic scene),
the scene's thermal-to-RGB homography is used.

This module holds the options, the run over the bag (:func:`process_bag`) and the command
line; the parameter files are read by :mod:`~mk_tracker.tools.pipeline_config`, the scores
and the files written after the run by :mod:`~mk_tracker.tools.pipeline_outputs`.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from mk_tracker.bags.bag_errors import BagError
from mk_tracker.bags.video_source import FrameSourceError, image_files, is_video_file
from mk_tracker.bags.bag_io import open_bag
from mk_tracker.bags.bag_writer import BagWriter
from mk_tracker.boxes import InvalidBoxError, as_box, iou
from mk_tracker.messages.detection_messages import (Detection, DetectionMessageError,
                                           make_detection_array, read_detection_array)
from mk_tracker.evaluation.metrics import MotRow
from mk_tracker.frame_processing import (DetectionBatch, DetectionBuffer, build_detector,
                                         detector_outputs,
                                         kernel_drawings, skipped_reason, detector_input,
                                         detector_event, step_detections,
                                         tracker_config_for_encoding, tracker_debug_image,
                                         tracker_input, tracker_inputs,
                                         tracks_to_detections)
from mk_tracker.bags.image_topics import ImageTopicError, check_image_topic, compressed_topics
from mk_tracker.messages.compressed_image import as_image
from mk_tracker.messages.image_conversion import ImageConversionError
from mk_tracker.messages.message_types import bag_message_types, stamp_to_nanoseconds, stamp_to_seconds
from mk_tracker.tracking.multi_object_tracker import (IDENTITY_HOMOGRAPHY, MultiObjectTracker,
                                             TrackerInputError)
from mk_tracker.parameters import ParameterError
# the parameters and the outputs of a run live in their own modules; CONFIG_DIR,
# DETECTOR_NODE_DEFAULTS, TRACKER_NODE_DEFAULTS, PipelineConfig and format_metrics are
# imported here too so that ``from mk_tracker.tools.pipeline import ...`` keeps working
from mk_tracker.tools.pipeline_config import (CONFIG_DIR, DETECTOR_NODE_DEFAULTS,  # noqa: F401
                                              TRACKER_NODE_DEFAULTS, TRACKER_PROFILES,
                                              PipelineConfig, PipelineError,
                                              load_pipeline_config, tracker_profile)
from mk_tracker.tools.pipeline_outputs import format_metrics, write_outputs

IMAGE_TOPIC = "/image_raw"
THERMAL_TOPIC = "/thermal/image_raw"
DETECTIONS_OUT_TOPIC = "/thermal/detections"
TRACKS_TOPIC = "/tracks"
GROUND_TRUTH_TOPIC = "/ground_truth"
SCENE_INFO_TOPIC = "/scene_info"
DETECTION_TOPIC_CANDIDATES = ("/thermal/detections", "/detections")
DETECTION_TYPE = "vision_msgs/msg/Detection2DArray"
#: below this fraction of tracked image messages a run exits non-zero (``--min-usable``)
MIN_USABLE_FRACTION = 0.1


# -- options and results --------------------------------------------------------------------

@dataclass(frozen=True)
class PipelineOptions:
    detections: str = "auto"                  # auto | thermal | none | topic:NAME
    init_box: tuple[float, float, float, float] | None = None
    init_from_gt: bool = False
    init_gt_id: int | None = None
    image_topic: str = IMAGE_TOPIC
    thermal_topic: str = THERMAL_TOPIC
    ground_truth_topic: str = GROUND_TRUTH_TOPIC
    write_bag: bool = True
    write_video: bool = True
    write_plots: bool = True
    storage: str = "mcap"
    progress: bool = True
    use_scene_homography: bool = True
    tracker_profile: str = "auto"             # auto | own | external | background

    @property
    def single_target(self) -> bool:
        return self.init_box is not None or self.init_from_gt


@dataclass
class PipelineResult:
    """What one run produced; ``tracks`` maps an RGB stamp (ns) to ``[(id, box), ...]``."""

    frames: int = 0
    tracked_frames: int = 0
    bad_frames: int = 0
    bad_messages: int = 0
    problems: list[str] = field(default_factory=list)
    detection_source: str = "none"
    #: "own" (config/tracker.yaml) or "external" (+ the public-detections overlay)
    tracker_profile: str = "own"
    #: True when the bag had no RGB topic and the thermal image itself was tracked
    thermal_only: bool = False
    detections: int = 0
    detection_frames: int = 0
    rejected_detector_frames: int = 0
    unknown_frame_batches: int = 0
    seconds: float = 0.0
    track_ids: set = field(default_factory=set)
    tracks: dict[int, list[tuple[int, tuple[float, float, float, float]]]] = \
        field(default_factory=dict)
    mot_rows: list[MotRow] = field(default_factory=list)
    gt_rows: list[MotRow] = field(default_factory=list)
    frame_stamps: list[int] = field(default_factory=list)
    single_target_id: int | None = None
    single_target_gt_id: int | None = None
    metrics: dict[str, Any] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)
    homography: tuple = IDENTITY_HOMOGRAPHY
    video_frames: int = 0
    #: what the detector changed in its own state, in words (a reset when time went
    #: backwards, a kernel bandwidth widened to a noisy stream): the node logs the same
    detector_events: list[str] = field(default_factory=list)

    def event(self, text: str) -> None:
        if len(self.detector_events) < 50:
            self.detector_events.append(text)
        if len(self.detector_events) <= 10:
            print(f"mk_tracker process: {text}", file=sys.stderr)

    def problem(self, text: str) -> None:
        self.bad_messages += 1
        if len(self.problems) < 50:
            self.problems.append(text)
        if len(self.problems) <= 10:
            print(f"mk_tracker process: {text}", file=sys.stderr)


def parse_box(text: str) -> tuple[float, float, float, float]:
    """``"x,y,w,h"`` -> a valid box, or :class:`PipelineError`."""
    try:
        values = [float(v) for v in text.replace(" ", ",").split(",") if v]
        b = as_box(values)
    except (ValueError, InvalidBoxError) as exc:
        raise PipelineError(f"--init needs x,y,w,h with w, h > 0, got {text!r}: {exc}") from exc
    return float(b[0]), float(b[1]), float(b[2]), float(b[3])


def choose_detection_source(option: str, topics: Mapping[str, Any], single_target: bool,
                            thermal_topic: str = THERMAL_TOPIC) -> str:
    """``"thermal"``, ``"background"``, ``"none"`` or ``"topic:NAME"`` for the
    ``--detections`` option (``background``: background subtraction on the tracked image
    itself, for a static RGB camera without a thermal one)."""
    if option == "auto":
        if single_target:
            return "none"
        if thermal_topic in topics and topics[thermal_topic].count > 0:
            return "thermal"
        for name in DETECTION_TOPIC_CANDIDATES:
            if (name in topics and topics[name].msgtype == DETECTION_TYPE
                    and topics[name].count > 0):
                return f"topic:{name}"
        return "none"
    if option == "thermal":
        if thermal_topic not in topics:
            raise PipelineError(f"--detections thermal: the bag has no {thermal_topic}")
        return "thermal"
    if option in ("none", "background"):
        return option
    if option.startswith("topic:"):
        name = option[len("topic:"):]
        if name not in topics:
            raise PipelineError(f"--detections {option}: the bag has no topic {name}")
        if topics[name].msgtype != DETECTION_TYPE:
            raise PipelineError(f"--detections {option}: {name} is a {topics[name].msgtype}, "
                                f"not a {DETECTION_TYPE}")
        return option
    raise PipelineError(f"--detections must be auto, thermal, background, none or "
                        f"topic:NAME, got "
                        f"{option!r}")


def _scene_homography(msg: Any) -> tuple | None:
    try:
        info = json.loads(msg.data)
        h = np.asarray(info["homography"], dtype=float).reshape(9)
    except (ValueError, KeyError, TypeError, AttributeError):
        return None
    return tuple(float(v) for v in h) if np.all(np.isfinite(h)) else None


def _median_fps(stamps_ns: Sequence[int], default: float = 10.0) -> float:
    if len(stamps_ns) < 2:
        return default
    d = np.diff(np.asarray(stamps_ns, dtype=np.int64)) / 1e9
    d = d[d > 0]
    if d.size == 0:
        return default
    fps = 1.0 / float(np.median(d))
    return fps if math.isfinite(fps) and 0.1 <= fps <= 1000 else default


# -- the run --------------------------------------------------------------------------------

_ORDER_SCENE, _ORDER_DETECTION, _ORDER_TRUTH, _ORDER_IMAGE, _ORDER_OTHER = range(5)


class _Run:
    """State of one pipeline run (see :func:`process_bag`)."""

    def __init__(self, bag: Path, out: Path, config: PipelineConfig, options: PipelineOptions):
        self.bag, self.out, self.config, self.options = bag, out, config, options
        self.result = PipelineResult()
        self.tracker: MultiObjectTracker | None = None
        self.tracker_config = config.tracker
        self.detector = None
        self.detector_method = "kernel_covariance"
        self.detections = DetectionBuffer(config.detection_buffer, config.detection_wait)
        #: RGB images held back for their detections: (message or None when undecodable,
        #: bag time ns, stamp s, bag time s when read)
        self.pending: deque[tuple[Any, int, float, float]] = deque()
        self.now = 0.0                   # bag time (s) of the message being handled
        self.truth_by_stamp: dict[int, list[Detection]] = {}
        self.first_truth: dict[int, tuple[int, tuple]] = {}   # gt id -> (stamp, box)
        self.pending_start: tuple | None = options.init_box
        self.video = None
        self.writer: BagWriter | None = None
        self.types = None
        self.last_detector_stamp: float | None = None
        #: topics holding sensor_msgs/CompressedImage, decoded on reading (from the bag's
        #: topic types: no option needed)
        self.compressed_topics: set[str] = set()

    # per-topic handlers ------------------------------------------------------------------
    def scene_info(self, msg: Any) -> None:
        h = _scene_homography(msg)
        if (h is not None and self.options.use_scene_homography
                and tuple(self.tracker_config.homography) == IDENTITY_HOMOGRAPHY
                and self.tracker is None):
            self.tracker_config = replace(self.tracker_config, homography=h)

    def thermal_image(self, msg: Any) -> None:
        r = self.result
        try:
            frame = detector_input(msg, self.detector_method)
        except ImageConversionError as exc:
            r.problem(f"skipping a detector image: {exc}")
            return
        stamp = stamp_to_seconds(msg.header.stamp)
        try:
            found = self.detector.process(frame, stamp, encoding=msg.encoding)
        except ValueError as exc:
            r.rejected_detector_frames += 1
            r.problem(f"detector skipped a frame: {exc}")
            return
        reason = skipped_reason(self.detector)
        if reason:
            r.rejected_detector_frames += 1
            r.problem(f"detector skipped the frame of stamp {stamp:.3f}: {reason}")
        event = detector_event(self.detector)
        if event:
            r.event(f"detector at stamp {stamp:.3f}: {event}")
        dets, errors = detector_outputs(found, self.config.detector_class_id)
        for e in errors:
            r.problem(e)
        r.detection_frames += 1
        r.detections += len(dets)
        if self.writer is not None:
            self.writer.write(DETECTIONS_OUT_TOPIC, stamp_to_nanoseconds(msg.header.stamp),
                              make_detection_array(dets, msg.header, self.types))
        self.detections.add(DetectionBatch(stamp, msg.header.frame_id, dets), self.now)

    def detection_message(self, msg: Any) -> None:
        try:
            dets, skipped = read_detection_array(msg, on_error="skip")
            stamp = stamp_to_seconds(msg.header.stamp)
        except (DetectionMessageError, ValueError, AttributeError) as exc:
            self.result.problem(f"skipping a detections message: {exc}")
            return
        if skipped:
            self.result.problem(f"skipped {skipped} bad detection(s) in a message")
        self.result.detection_frames += 1
        self.result.detections += len(dets)
        self.detections.add(DetectionBatch(stamp, msg.header.frame_id, dets), self.now)

    def ground_truth(self, msg: Any) -> None:
        try:
            dets, _ = read_detection_array(msg, on_error="skip")
            ns = stamp_to_nanoseconds(msg.header.stamp)
        except (DetectionMessageError, ValueError, AttributeError) as exc:
            self.result.problem(f"skipping a ground-truth message: {exc}")
            return
        self.truth_by_stamp[ns] = dets

    def _start_single_target(self, bgr: np.ndarray, stamp: float, ns: int,
                             truth: list[Detection]) -> None:
        opts = self.options
        box = None
        if opts.init_box is not None and self.pending_start is not None:
            box = self.pending_start
            if truth:
                best = max(truth, key=lambda d: iou(d.box, box))
                if iou(best.box, box) > 0 and best.id.lstrip("-").isdigit():
                    self.result.single_target_gt_id = int(best.id)
        elif opts.init_from_gt and self.pending_start is None:
            wanted = [d for d in truth if d.id.lstrip("-").isdigit()
                      and (opts.init_gt_id is None or int(d.id) == opts.init_gt_id)]
            if wanted:
                first = min(wanted, key=lambda d: int(d.id)) if opts.init_gt_id is None \
                    else wanted[0]
                box = first.box
                self.result.single_target_gt_id = int(first.id)
        if box is None:
            return
        try:
            self.result.single_target_id = self.tracker.start_track(bgr, stamp, box)
        except ValueError as exc:
            raise PipelineError(f"cannot start the target on {box}: {exc}") from exc
        self.pending_start = ()   # started (an empty tuple: never again)

    def new_frame(self, ns: int) -> tuple[int, list[Detection]]:
        """Count an RGB frame (good or bad) and bind its ground truth to its number, so a
        skipped frame's people count as misses and later frames keep their numbers."""
        r = self.result
        r.frames += 1
        truth = self.truth_by_stamp.pop(ns, [])
        for d in truth:
            if d.id.lstrip("-").isdigit():
                r.gt_rows.append(MotRow(r.frames, int(d.id), d.box))
        return r.frames, truth

    def rgb_image(self, msg: Any | None, timestamp_ns: int) -> None:
        """Queue an RGB image (None: an undecodable one) for tracking, in bag order."""
        try:
            stamp = stamp_to_seconds(msg.header.stamp)
        except (AttributeError, TypeError, ValueError):
            stamp = timestamp_ns * 1e-9
        self.pending.append((msg, timestamp_ns, stamp, self.now))

    def release_images(self, final: bool = False) -> None:
        """Track the queued images whose detections are in (or whose wait is over)."""
        while self.pending:
            msg, timestamp_ns, stamp, since = self.pending[0]
            if (not final and msg is not None and self.now - since < self.detections.wait
                    and self.detections.waiting(stamp, self.now)):
                return
            self.pending.popleft()
            if msg is None:
                self.new_frame(timestamp_ns)
                self.result.bad_frames += 1
            else:
                self._track_image(msg, timestamp_ns)

    def _track_image(self, msg: Any, timestamp_ns: int) -> None:
        r = self.result
        try:
            ns = stamp_to_nanoseconds(msg.header.stamp)
        except (AttributeError, TypeError, ValueError):
            ns = timestamp_ns
        frame_no, truth = self.new_frame(ns)
        try:
            bgr = tracker_input(msg)
        except ImageConversionError as exc:
            r.bad_frames += 1
            r.problem(f"skipping image #{frame_no}: {exc}")
            return
        stamp = stamp_to_seconds(msg.header.stamp)
        if self.tracker is None:
            try:
                self.tracker = MultiObjectTracker(
                    tracker_config_for_encoding(self.tracker_config, msg.encoding))
            except TrackerInputError as exc:
                raise PipelineError(f"tracker configuration rejected: {exc}") from exc
            r.homography = tuple(self.tracker_config.homography)
        discarded = self.detections.discarded
        batches = self.detections.take(stamp)
        dets, unknown = tracker_inputs(batches, msg.header.frame_id,
                                       self.config.thermal_frame_id)
        if self.detections.discarded > discarded:
            r.problem(f"image #{frame_no}: time went backwards; dropped "
                      f"{self.detections.discarded - discarded} detection message(s) of the "
                      f"old time line")
        for frame_id in unknown:
            r.unknown_frame_batches += 1
            r.problem(f"skipping detections in unknown frame {frame_id!r} (image frame "
                      f"{msg.header.frame_id!r}, thermal_frame_id "
                      f"{self.config.thermal_frame_id!r})")
        try:
            if self.options.single_target and self.pending_start != ():
                self._start_single_target(bgr, stamp, ns, truth)
            result = self.tracker.step(bgr, stamp, step_detections(dets, batches))
        except (TrackerInputError, ValueError) as exc:
            if isinstance(exc, PipelineError):
                raise
            r.bad_frames += 1
            r.problem(f"tracker rejected image #{frame_no}: {exc}")
            return
        r.tracked_frames += 1
        r.frame_stamps.append(ns)
        reported = result.reported()
        published = tracks_to_detections(reported, self.config.class_id)
        r.tracks[ns] = [(int(d.id), d.box) for d in published]
        for d in published:
            r.track_ids.add(int(d.id))
            r.mot_rows.append(MotRow(frame_no, int(d.id), d.box, d.score))
        if self.writer is not None:
            self.writer.write(TRACKS_TOPIC, timestamp_ns,
                              make_detection_array(published, msg.header, self.types))
        if self.video is not None:
            canvas = tracker_debug_image(
                bgr, [t for t in reported], kernel_drawings(result), dets,
                self.tracker.homography, [f"frame {frame_no}  tracks {len(published)}"],
                ground_truth=[d.box for d in truth])
            self.video.write(canvas)


def _order(topic: str, options: PipelineOptions, source: str) -> int:
    if topic == SCENE_INFO_TOPIC:
        return _ORDER_SCENE
    if (source == "thermal" and topic == options.thermal_topic) or \
            (source.startswith("topic:") and topic == source[6:]):
        return _ORDER_DETECTION
    if topic == options.ground_truth_topic:
        return _ORDER_TRUTH
    if topic == options.image_topic:
        return _ORDER_IMAGE
    return _ORDER_OTHER


def _grouped(messages: Iterable[Any]) -> Iterable[list[Any]]:
    group: list[Any] = []
    for m in messages:
        if group and m.timestamp_ns != group[0].timestamp_ns:
            yield group
            group = []
        group.append(m)
    if group:
        yield group


def _scores_in_unit_range(reader: Any, topic: str) -> bool:
    """Whether every readable detection score on ``topic`` lies in [0, 1] (a first pass
    over the topic's messages; unreadable ones are left to the run to report)."""
    for m in reader.messages([topic]):
        try:
            dets, _ = read_detection_array(reader.deserialize(m), on_error="skip")
        except Exception:                # reported when the run reads it
            continue
        if any(not 0.0 <= d.score <= 1.0 for d in dets):
            return False
    return True


def process_bag(bag: str | Path, out: str | Path, config: PipelineConfig | None = None,
                options: PipelineOptions | None = None) -> PipelineResult:
    """Run detection and tracking over ``bag``, writing the outputs into ``out``."""
    from mk_tracker.drawing.video_output import VideoOutput

    config = config or load_pipeline_config()
    options = options or PipelineOptions()
    bag, out = Path(bag), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if options.write_bag and (out / "bag").exists():
        raise PipelineError(f"{out / 'bag'} exists already; choose another --out")
    try:
        reader = open_bag(bag, on_error="skip")
    except BagError as exc:
        raise PipelineError(str(exc)) from exc
    run = _Run(bag, out, config, options)
    r = run.result
    t0 = time.perf_counter()
    with reader:
        for text in reader.problems:
            r.problem(f"bag: {text}")
        topics = reader.topics
        if (options.image_topic not in topics and options.thermal_topic in topics
                and f"{options.image_topic}/compressed" not in topics):
            # thermal-only mode (issue #19): no RGB camera, so the people found in the
            # thermal image are tracked in that same image (detections in its own frame)
            options = replace(options, image_topic=options.thermal_topic)
            run.options = options
            r.thermal_only = True
        try:   # before any message is read: a missing or non-image topic stops here
            check_image_topic(topics, options.image_topic,
                              "--thermal-topic" if r.thermal_only else "--image-topic")
        except ImageTopicError as exc:
            raise PipelineError(f"{bag}: {exc}") from exc
        run.compressed_topics = compressed_topics(topics)
        source = choose_detection_source(options.detections, topics, options.single_target,
                                         options.thermal_topic)
        r.detection_source = source
        unit_scores = (options.tracker_profile != "auto" or not source.startswith("topic:")
                       or _scores_in_unit_range(reader, source[len("topic:"):]))
        r.tracker_profile = tracker_profile(options.tracker_profile, source, unit_scores)
        if r.tracker_profile != "own":
            run.tracker_config = config.tracker_for(r.tracker_profile)
        if source == "thermal":
            run.detector = build_detector(config.method, config.detector, config.threshold,
                                          config.ignore_regions, config.background)
            run.detector_method = config.method
        elif source == "background":
            run.detector = build_detector("background", config.detector, config.threshold,
                                          config.ignore_regions, config.background)
            run.detector_method = "background"
        has_truth = (options.ground_truth_topic in topics
                     and topics[options.ground_truth_topic].count > 0)
        if options.init_from_gt and not has_truth:
            raise PipelineError(f"--init-from-gt: the bag has no {options.ground_truth_topic}")
        if options.write_bag:
            run.writer = BagWriter(out / "bag", storage=options.storage,
                                   typestore=reader.typestore)
            run.writer.open()
            run.types = bag_message_types(reader.typestore)
            for t in topics.values():
                if t.msgtype and t.name not in (TRACKS_TOPIC,) and not (
                        source == "thermal" and t.name == DETECTIONS_OUT_TOPIC):
                    run.writer.add_topic(t.name, t.msgtype)
            if source == "thermal":
                run.writer.add_topic(DETECTIONS_OUT_TOPIC, DETECTION_TYPE)
            run.writer.add_topic(TRACKS_TOPIC, DETECTION_TYPE)
        image_stamps = []
        if options.write_video:
            # the frame rate from the first frames (raw messages, nothing deserialized)
            image_stamps = [m.timestamp_ns for m in
                            itertools.islice(reader.messages([options.image_topic]), 25)]
            run.video = VideoOutput(out / "video.mp4", fps=_median_fps(image_stamps))
        total = reader.message_count
        bar = None
        if options.progress:
            from tqdm import tqdm
            bar = tqdm(total=total, desc=f"processing {bag.name}", unit="msg",
                       file=sys.stderr)
        try:
            for group in _grouped(reader.messages()):
                group.sort(key=lambda m: _order(m.topic, options, source))
                for m in group:
                    run.now = m.timestamp_ns * 1e-9
                    try:
                        _handle(run, reader, m, source)
                        run.release_images()
                    except PipelineError:
                        raise
                    except Exception as exc:  # like the nodes' frame workers: log, go on
                        r.problem(f"processing a {m.topic} message failed "
                                  f"({type(exc).__name__}: {exc}); message skipped")
                if bar is not None:
                    bar.update(len(group))
            while run.pending:                # the bag has ended: no detection will come
                try:
                    run.release_images(final=True)
                except PipelineError:
                    raise
                except Exception as exc:
                    r.problem(f"processing an image failed ({type(exc).__name__}: {exc}); "
                              f"image skipped")
        finally:
            if bar is not None:
                bar.close()
            if run.writer is not None:
                run.writer.close()
            if run.video is not None:
                run.video.close()
                r.video_frames = run.video.frames
        for text in reader.problems[len(r.problems):]:
            r.problem(f"bag: {text}")
    r.seconds = time.perf_counter() - t0
    write_outputs(r, run.bag, run.out, run.options, has_truth)
    return r


def _handle(run: _Run, reader: Any, m: Any, source: str) -> None:
    opts = run.options
    topic = m.topic
    if run.writer is not None and topic in run.writer.counts:
        try:
            run.writer.write_raw(topic, m.timestamp_ns, m.data)
        except BagError as exc:
            run.result.problem(f"cannot copy a {topic} message: {exc}")
    wanted = {SCENE_INFO_TOPIC, opts.ground_truth_topic, opts.image_topic}
    if source == "thermal":
        wanted.add(opts.thermal_topic)
    elif source.startswith("topic:"):
        wanted.add(source[6:])
    if topic not in wanted:
        return
    try:
        msg = reader.deserialize(m)
    except BagError as exc:
        if topic == opts.image_topic:   # no header to read: the bag time is the stamp
            run.rgb_image(None, m.timestamp_ns)
        run.result.problem(f"undecodable message: {exc}")
        return
    if topic in run.compressed_topics:
        try:
            msg = as_image(msg)           # JPEG/PNG decoded into an Image-like message
        except ImageConversionError as exc:
            if topic == opts.image_topic:
                run.rgb_image(None, m.timestamp_ns)
            run.result.problem(f"undecodable compressed image on {topic}: {exc}")
            return
    if topic == SCENE_INFO_TOPIC:
        run.scene_info(msg)
    elif topic == opts.image_topic:
        if (source == "thermal" and topic == opts.thermal_topic) or source == "background":
            run.thermal_image(msg)        # thermal-only mode, or background subtraction
        run.rgb_image(msg, m.timestamp_ns)
    elif topic == opts.ground_truth_topic:
        run.ground_truth(msg)
    elif source == "thermal":
        run.thermal_image(msg)
    else:
        run.detection_message(msg)


# -- command line ---------------------------------------------------------------------------

def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", type=Path, help="rosbag2 bag (directory or .mcap/.db3), or a "
                        "video file / image folder (imported into OUT/input_bag first)")
    parser.add_argument("--thermal", action="store_true",
                        help="the video / image folder is a thermal camera (thermal-only "
                             "mode); default: an RGB camera, detected by background "
                             "subtraction")
    parser.add_argument("--fps", type=float, default=None,
                        help="frame rate of an image folder (a video's own rate otherwise)")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--detections", default="auto", metavar="SOURCE",
                        help="auto | thermal | background | none | topic:NAME (default auto; "
                             "background: background subtraction on the RGB image)")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--init", metavar="X,Y,W,H", default=None,
                       help="single target: start a track on this box in the first frame")
    group.add_argument("--init-from-gt", nargs="?", const=-1, type=int, default=None,
                       metavar="ID", help="single target: start on the first ground-truth "
                       "box (of ID, default the first one in the bag)")
    parser.add_argument("--params-file", action="append", default=[], type=Path,
                        help="ROS 2 parameters YAML (repeatable; after config/*.yaml)")
    parser.add_argument("--tracker-profile", choices=TRACKER_PROFILES, default="auto",
                        help="tracker parameters: own = config/tracker.yaml (the project's "
                             "detectors); external = plus config/tracker_public_detections"
                             ".yaml (another detector's boxes scored in [0, 1]); background "
                             "= plus config/tracker_background_detections.yaml (the "
                             "background-subtraction detector's boxes); auto (default): "
                             "background for --detections background, external for "
                             "--detections topic:NAME other than /thermal/detections whose "
                             "scores lie in [0, 1], else own")
    parser.add_argument("--image-topic", default=IMAGE_TOPIC)
    parser.add_argument("--thermal-topic", default=THERMAL_TOPIC)
    parser.add_argument("--ground-truth-topic", default=GROUND_TRUTH_TOPIC)
    parser.add_argument("--no-scene-homography", action="store_true",
                        help="do not take the homography from /scene_info")
    parser.add_argument("--no-video", action="store_true", help="do not write video.mp4")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--min-usable", type=float, default=MIN_USABLE_FRACTION,
                        metavar="FRACTION", help="exit non-zero (3) when fewer than this "
                        "fraction of the image messages could be tracked (default "
                        f"{MIN_USABLE_FRACTION})")


def options_from_args(args: argparse.Namespace) -> PipelineOptions:
    init_box = parse_box(args.init) if args.init else None
    from_gt = args.init_from_gt is not None
    gt_id = args.init_from_gt if from_gt and args.init_from_gt >= 0 else None
    return PipelineOptions(detections=args.detections, init_box=init_box, init_from_gt=from_gt,
                           init_gt_id=gt_id, image_topic=args.image_topic,
                           thermal_topic=args.thermal_topic,
                           ground_truth_topic=args.ground_truth_topic,
                           write_video=not args.no_video, storage=args.storage,
                           progress=not args.quiet,
                           use_scene_homography=not args.no_scene_homography,
                           tracker_profile=args.tracker_profile)


def is_recording(path: Path) -> bool:
    """A video file, or a folder of images that is not a bag (no metadata.yaml / .mcap /
    .db3 in it)."""
    path = Path(path)
    if is_video_file(path):
        return True
    if not path.is_dir() or (path / "metadata.yaml").exists():
        return False
    if any(path.glob("*.mcap")) or any(path.glob("*.db3")):
        return False
    return bool(image_files(path))


def import_for_processing(path: Path, out: Path, options: PipelineOptions, *,
                          thermal: bool, fps: float | None) -> tuple[Path, PipelineOptions]:
    """Import the recording ``path`` into ``out/input_bag`` (RGB, or thermal with
    ``thermal``) and the options to process it: ``--detections auto`` becomes background
    subtraction for an RGB recording (issue #13) and the thermal detector for a thermal
    one (thermal-only mode, issue #19)."""
    from mk_tracker.bags.recording_import import import_recording, open_recording
    bag = out / "input_bag"
    if bag.exists():
        raise PipelineError(f"{bag} exists already; choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    import_recording(open_recording(path, fps), bag, thermal=thermal)
    if options.detections == "auto" and not options.single_target:
        options = replace(options, detections="thermal" if thermal else "background")
    return bag, options


def run(args: argparse.Namespace) -> int:
    try:
        options = options_from_args(args)
        config = load_pipeline_config(args.params_file)
        bag = args.bag
        if is_recording(bag):          # a video or image folder: import it first
            bag, options = import_for_processing(bag, Path(args.out), options,
                                                 thermal=args.thermal, fps=args.fps)
        result = process_bag(bag, args.out, config, options)
    except (PipelineError, BagError, ParameterError, FrameSourceError) as exc:
        print(f"mk_tracker process: {exc}", file=sys.stderr)
        return 2
    fps = result.frames / result.seconds if result.seconds > 0 else float("nan")
    print(f"processed {result.frames} frames ({result.bad_frames} bad, "
          f"{result.bad_messages} bad messages) in {result.seconds:.1f} s ({fps:.1f} fps); "
          f"detections: {result.detection_source} ({result.detections}); "
          f"tracker parameters: {result.tracker_profile}; "
          f"{len(result.track_ids)} track ids")
    if result.metrics:
        print("scores: " + format_metrics(result.metrics))
    for name, path in result.files.items():
        print(f"  {name}: {path}")
    unusable = usable_frames_problem(result, args.min_usable, args.image_topic)
    if unusable:
        print(f"mk_tracker process: {unusable}", file=sys.stderr)
        return 3
    return 0


def usable_frames_problem(result: PipelineResult, min_fraction: float,
                          image_topic: str) -> str | None:
    """Why a run is a failure although it ended (too few of its image messages were
    tracked: fewer than ``min_fraction``), with its first problems; None when it is not."""
    if result.frames > 0 and result.tracked_frames >= min_fraction * result.frames:
        return None
    share = result.tracked_frames / result.frames if result.frames else 0.0
    first = "; ".join(result.problems[:3]) or "no problem was logged"
    return (f"only {result.tracked_frames} of {result.frames} image messages on "
            f"{image_topic} could be tracked ({share:.0%}, below --min-usable "
            f"{min_fraction:g}); first problems: {first}. Check the image topic and its "
            f"encoding (--image-topic; the supported encodings are in the README)")
