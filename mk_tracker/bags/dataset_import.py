"""``mk_tracker import PATH --out BAG``: a MOTChallenge or OTB folder as a rosbag2 bag; a
video file or a plain image folder goes to :mod:`mk_tracker.bags.recording_import`.

Topics written (project conventions, frame id ``camera``, one message per frame each):

* ``/image_raw``     ``sensor_msgs/msg/Image``, ``bgr8`` (with ``--compressed jpeg|png``:
  ``/image_raw/compressed``, ``sensor_msgs/msg/CompressedImage``, as image_transport writes);
* ``/ground_truth``  ``vision_msgs/msg/Detection2DArray``: id = ground-truth identity as a
  string, score 1.0 (an empty array for frames without ground truth);
* ``/detections``    ``vision_msgs/msg/Detection2DArray`` of the public detections when the
  sequence has them (MOTChallenge ``det/det.txt``): empty id, score = the raw score.

Every message of frame ``k`` has header stamp and bag time ``start + k / fps``.  Boxes are
the files' own coordinates (see :mod:`mk_tracker.bags.datasets`).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path
from typing import Callable

from mk_tracker.bags.bag_errors import BagError
from mk_tracker.bags.bag_typestore import make_typestore
from mk_tracker.bags.bag_writer import BagWriter
from mk_tracker.bags.datasets import DatasetError, Sequence, detect_layout, read_sequence
from mk_tracker.bags.recording_import import import_recording, open_recording, read_homography
from mk_tracker.bags.video_source import FrameSourceError, is_video_file
from mk_tracker.messages.detection_messages import Detection, make_detection_array
from mk_tracker.messages.compressed_image import (CODECS, image_message, transport_topic,
                                                  transport_type)
from mk_tracker.messages.image_conversion import ImageConversionError
from mk_tracker.messages.message_types import bag_message_types, make_header

IMAGE_TOPIC = "/image_raw"
GROUND_TRUTH_TOPIC = "/ground_truth"
DETECTIONS_TOPIC = "/detections"
FRAME_ID = "camera"


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folder", type=Path, metavar="PATH",
                        help="MOTChallenge or OTB sequence folder, a video file (mp4, avi, "
                             "...) or a folder of images (png, tiff, jpg; 8 or 16 bit)")
    parser.add_argument("--out", type=Path, required=True,
                        help="bag directory to create (must not exist)")
    parser.add_argument("--fps", type=float, default=None,
                        help="frame rate for the time stamps (default: seqinfo.ini's "
                             "frameRate, else 25; a video's own rate; required for an "
                             "image folder)")
    parser.add_argument("--thermal", action="store_true",
                        help="the video/image folder is a thermal camera: write it as "
                             "/thermal/image_raw (mono8, or mono16 for 16-bit frames)")
    parser.add_argument("--rgb", type=Path, default=None, metavar="PATH",
                        help="with --thermal: the RGB video/image folder of the same scene, "
                             "written as /image_raw (frames paired by index)")
    parser.add_argument("--homography", type=Path, default=None, metavar="FILE",
                        help="with --thermal: 3x3 thermal->RGB pixel homography (9 numbers, "
                             "or JSON), stored in /scene_info for mk_tracker process")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap",
                        help="bag storage format (default mcap)")
    parser.add_argument("--start-time", type=float, default=0.0,
                        help="time stamp of the first frame in seconds (default 0)")
    parser.add_argument("--class-id", default="person",
                        help="class_id of the ground-truth and detection boxes")
    parser.add_argument("--quiet", action="store_true", help="no progress output")
    parser.add_argument("--compressed", choices=sorted(CODECS), default=None,
                        help="write the images as sensor_msgs/CompressedImage on "
                        "<topic>/compressed, as a robot's image_transport records them "
                        "(16-bit thermal needs png)")
    parser.add_argument("--jpeg-quality", type=int, default=95, metavar="Q",
                        help="JPEG quality 0..100 with --compressed jpeg (default 95)")


def import_sequence(sequence: Sequence, out: Path, storage: str = "mcap",
                    start_ns: int = 0, class_id: str = "person",
                    progress: Callable[[int, int], None] | None = None,
                    codec: str | None = None, jpeg_quality: int = 95) -> dict[str, int]:
    """Write ``sequence`` to a new bag at ``out``; returns the message count per topic.
    With ``codec`` the images are CompressedImage messages on ``/image_raw/compressed``.

    On failure the partly written bag directory is removed and the error re-raised.
    """
    store = make_typestore()
    types = bag_message_types(store)
    out = Path(out)
    created = False
    try:
        with BagWriter(out, storage, typestore=store) as bag:
            created = True
            image_topic = transport_topic(IMAGE_TOPIC, codec)
            bag.add_topic(image_topic, transport_type(codec))
            bag.add_topic(GROUND_TRUTH_TOPIC, "vision_msgs/msg/Detection2DArray")
            if sequence.detections is not None:
                bag.add_topic(DETECTIONS_TOPIC, "vision_msgs/msg/Detection2DArray")
            for k in range(len(sequence)):
                stamp = sequence.timestamp_ns(k, start_ns)
                header = make_header(types, FRAME_ID, stamp)
                image = sequence.image(k)
                bag.write(image_topic, stamp, image_message(image, "bgr8", header, types=types,
                                                            codec=codec,
                                                            jpeg_quality=jpeg_quality))
                truth = [Detection(box, 1.0, class_id, str(identity))
                         for identity, box in sorted(sequence.ground_truth[k].items())]
                bag.write(GROUND_TRUTH_TOPIC, stamp, make_detection_array(truth, header, types))
                if sequence.detections is not None:
                    public = [Detection(d.box, d.score, class_id, "")
                              for d in sequence.detections[k]]
                    bag.write(DETECTIONS_TOPIC, stamp,
                              make_detection_array(public, header, types))
                if progress is not None:
                    progress(k + 1, len(sequence))
            counts = dict(bag.counts)
    except BaseException:
        if created and out.exists():
            shutil.rmtree(out, ignore_errors=True)
        raise
    return counts


def run(args: argparse.Namespace) -> int:
    def fail(message: str) -> int:
        print(f"mk_tracker import: error: {message}", file=sys.stderr)
        return 1

    if args.out.exists():
        return fail(f"{args.out} exists already; choose a new --out path")
    if not (args.start_time >= 0):
        return fail(f"--start-time must be >= 0, got {args.start_time}")
    if not 0 <= args.jpeg_quality <= 100:
        return fail(f"--jpeg-quality must be 0..100, got {args.jpeg_quality}")
    if _is_recording(args.folder) or args.thermal:
        return _run_recording(args, fail)
    if args.rgb is not None or args.homography is not None:
        return fail("--rgb and --homography are for a thermal recording (--thermal)")
    try:
        sequence = read_sequence(args.folder, args.fps)
    except DatasetError as exc:
        return fail(str(exc))
    if not args.quiet:
        n_det = "none" if sequence.detections is None else \
            str(sum(len(d) for d in sequence.detections))
        print(f"{sequence.name} ({sequence.layout}): {len(sequence)} frames at "
              f"{sequence.frame_rate:g} fps, {len(sequence.identities)} identities, "
              f"{sequence.ground_truth_count} ground-truth boxes, public detections: {n_det}",
              file=sys.stderr)

    def progress(done: int, total: int) -> None:
        if done == total or done % 25 == 0:
            print(f"  {done}/{total} frames", file=sys.stderr)

    try:
        counts = import_sequence(sequence, args.out, args.storage,
                                 round(args.start_time * 1e9), args.class_id,
                                 None if args.quiet else progress, args.compressed,
                                 args.jpeg_quality)
    except (DatasetError, BagError, ImageConversionError) as exc:
        return fail(str(exc))
    if not args.quiet:
        summary = ", ".join(f"{topic} {n}" for topic, n in counts.items())
        print(f"wrote {args.out} ({args.storage}): {summary}", file=sys.stderr)
    return 0


def _is_recording(path: Path) -> bool:
    """A video file, or a folder that is neither MOTChallenge nor OTB."""
    if is_video_file(path):
        return True
    if not path.is_dir():
        return False
    try:
        detect_layout(path)
    except DatasetError:
        return True
    return False


def _run_recording(args: argparse.Namespace, fail: Callable[[str], int]) -> int:
    if (args.rgb is not None or args.homography is not None) and not args.thermal:
        return fail("--rgb and --homography are for a thermal recording (--thermal)")
    try:
        source = open_recording(args.folder, args.fps)
        rgb = open_recording(args.rgb, source.fps) if args.rgb is not None else None
        homography = read_homography(args.homography) if args.homography else None
    except FrameSourceError as exc:
        return fail(str(exc))
    if not args.quiet:
        kind = "thermal" if args.thermal else "RGB"
        print(f"{args.folder} ({source.kind}, {kind}): {source.declared} frames declared at "
              f"{source.fps:g} fps", file=sys.stderr)

    def progress(done: int) -> None:
        if not args.quiet and done % 100 == 0:
            print(f"  {done} frames", file=sys.stderr)

    try:
        counts = import_recording(source, args.out, thermal=args.thermal, rgb=rgb,
                                  homography=homography, storage=args.storage,
                                  start_ns=round(args.start_time * 1e9), progress=progress,
                                  codec=args.compressed, jpeg_quality=args.jpeg_quality)
    except (FrameSourceError, BagError) as exc:
        return fail(str(exc))
    except ImageConversionError as exc:
        return fail(f"{exc}; choose another --compressed")
    if not args.quiet:
        summary = ", ".join(f"{topic} {n}" for topic, n in counts.items())
        print(f"wrote {args.out} ({args.storage}): {summary}", file=sys.stderr)
    for src in (source, rgb):
        if src is None or not src.unreadable:
            continue
        if src.kind == "folder":
            print(f"mk_tracker import: warning: {src.path}: {src.unreadable} image file(s) "
                  "could not be read and were left out", file=sys.stderr)
        else:        # a container's frame count is often an estimate: say what was decoded
            print(f"mk_tracker import: note: {src.path}: the container declares "
                  f"{src.declared} frames, {src.declared - src.unreadable} were decoded",
                  file=sys.stderr)
    return 0
