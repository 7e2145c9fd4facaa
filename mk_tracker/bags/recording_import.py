"""``mk_tracker import`` for recordings without annotations: a video file or an image
folder, RGB or thermal, as a rosbag2 bag (issues #13 and #19).

Topics written (frame ids as in the project's synthetic bags):

* RGB recording: ``/image_raw`` (``bgr8``, frame ``camera``);
* thermal recording (``thermal=True``): ``/thermal/image_raw`` (``mono8``, or ``mono16`` for
  16-bit frames; frame ``thermal_camera``), plus ``/image_raw`` from ``rgb`` when an RGB
  recording of the same scene is given (frames paired by index; the shorter one sets the
  length);
* ``/scene_info`` (``std_msgs/String``, JSON, once) when a homography is given
  (thermal pixel -> RGB pixel, 3x3): ``mk_tracker process`` takes the tracker's homography
  from it, as it does for generated scenes.

Frame ``k`` is stamped ``start + k / fps`` (header and bag time); ``fps`` is the video
container's unless given, and must be given for an image folder.
"""

from __future__ import annotations

import json
import shutil
from itertools import zip_longest
from pathlib import Path
from typing import Callable

import numpy as np

from mk_tracker.bags.bag_typestore import make_typestore
from mk_tracker.bags.bag_writer import BagWriter
from mk_tracker.bags.video_source import (FrameSource, FrameSourceError, open_frames,
                                          to_colour, to_thermal)
from mk_tracker.messages.compressed_image import image_message, transport_topic, transport_type
from mk_tracker.messages.message_types import bag_message_types, make_header

IMAGE_TOPIC = "/image_raw"
THERMAL_TOPIC = "/thermal/image_raw"
SCENE_INFO_TOPIC = "/scene_info"
RGB_FRAME_ID = "camera"
THERMAL_FRAME_ID = "thermal_camera"


def read_homography(path: str | Path) -> np.ndarray:
    """A 3x3 homography from a text file of 9 numbers (any whitespace or commas, ``#``
    comments) or a JSON file (a 3x3 list, or an object with ``"homography"``)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise FrameSourceError(f"{p}: cannot read the homography ({exc})") from exc
    try:
        if text.lstrip().startswith(("{", "[")):
            data = json.loads(text)
            values = data["homography"] if isinstance(data, dict) else data
        else:
            lines = [line.split("#", 1)[0] for line in text.splitlines()]
            values = [float(v) for v in " ".join(lines).replace(",", " ").split()]
        h = np.asarray(values, dtype=float).reshape(3, 3)
    except (ValueError, KeyError, TypeError) as exc:
        raise FrameSourceError(f"{p}: not a 3x3 homography (9 numbers): {exc}") from exc
    if not np.all(np.isfinite(h)) or abs(np.linalg.det(h)) < 1e-12:
        raise FrameSourceError(f"{p}: the homography must be finite and invertible")
    return h


def import_recording(source: FrameSource, out: Path, *, thermal: bool = False,
                     rgb: FrameSource | None = None, homography: np.ndarray | None = None,
                     storage: str = "mcap", start_ns: int = 0,
                     progress: Callable[[int], None] | None = None,
                     codec: str | None = None, jpeg_quality: int = 95) -> dict[str, int]:
    """Write ``source`` (and ``rgb``) to a new bag at ``out``; returns the message count per
    topic.  ``source.fps`` must be set.  On failure the partly written bag is removed.
    With ``codec`` (``"jpeg"``/``"png"``) every image topic becomes ``<topic>/compressed``
    holding CompressedImage messages."""
    if source.fps is None:
        raise FrameSourceError(f"{source.path}: no frame rate; give one (--fps)")
    if rgb is not None and not thermal:
        raise FrameSourceError("an RGB pair is only for a thermal recording (--thermal)")
    store = make_typestore()
    types = bag_message_types(store)
    period_ns = 1e9 / source.fps
    out = Path(out)
    created = False
    try:
        with BagWriter(out, storage, typestore=store) as bag:
            created = True
            thermal_topic = transport_topic(THERMAL_TOPIC, codec)
            image_topic = transport_topic(IMAGE_TOPIC, codec)
            main_topic = thermal_topic if thermal else image_topic
            bag.add_topic(main_topic, transport_type(codec))
            if rgb is not None:
                bag.add_topic(image_topic, transport_type(codec))
            if homography is not None:
                bag.add_topic(SCENE_INFO_TOPIC, "std_msgs/msg/String")
                info = {"homography": [float(v) for v in np.asarray(homography).reshape(9)],
                        "frame_ids": {"rgb": RGB_FRAME_ID, "thermal": THERMAL_FRAME_ID},
                        "source": str(source.path)}
                string_type = store.types["std_msgs/msg/String"]
                bag.write(SCENE_INFO_TOPIC, start_ns, string_type(data=json.dumps(info)))
            pairs = (zip(source.frames(), rgb.frames()) if rgb is not None
                     else zip_longest(source.frames(), ()))
            for k, (frame, colour) in enumerate(pairs):
                stamp = start_ns + round(k * period_ns)
                if thermal:
                    grey, encoding = to_thermal(frame)
                    header = make_header(types, THERMAL_FRAME_ID, stamp)
                    bag.write(thermal_topic, stamp, image_message(
                        grey, encoding, header, types=types, codec=codec,
                        jpeg_quality=jpeg_quality))
                else:
                    header = make_header(types, RGB_FRAME_ID, stamp)
                    bag.write(image_topic, stamp, image_message(
                        to_colour(frame), "bgr8", header, types=types, codec=codec,
                        jpeg_quality=jpeg_quality))
                if colour is not None:
                    header = make_header(types, RGB_FRAME_ID, stamp)
                    bag.write(image_topic, stamp, image_message(
                        to_colour(colour), "bgr8", header, types=types, codec=codec,
                        jpeg_quality=jpeg_quality))
                if progress is not None:
                    progress(k + 1)
            counts = dict(bag.counts)
    except BaseException:
        if created and out.exists():
            shutil.rmtree(out, ignore_errors=True)
        raise
    main = counts.get(main_topic, 0)
    if main == 0:
        shutil.rmtree(out, ignore_errors=True)
        raise FrameSourceError(f"{source.path}: no frame could be read")
    return counts


def open_recording(path: str | Path, fps: float | None) -> FrameSource:
    """:func:`open_frames` with the frame-rate rule of the import: ``fps`` given, else the
    container's; an image folder needs ``fps``."""
    source = open_frames(path, fps)
    if source.fps is None:
        what = "an image folder" if source.kind == "folder" else "this video (no rate stored)"
        raise FrameSourceError(f"{path}: {what} has no frame rate; give --fps")
    return source
