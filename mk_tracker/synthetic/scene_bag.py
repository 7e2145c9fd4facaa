"""Write a synthetic scene (:mod:`mk_tracker.synthetic.scene`) to a rosbag2 bag; ``mk_tracker generate``.

Topics of the bag (every header stamp is the frame's stamp, which is also the log time):

=========================  ======================================  ===================
topic                      type                                    frame_id
=========================  ======================================  ===================
``/image_raw``             sensor_msgs/Image, ``bgr8``             ``camera``
``/thermal/image_raw``     sensor_msgs/Image, mono8/mono16/32FC1   ``thermal_camera``
``/ground_truth``          vision_msgs/Detection2DArray (RGB px)   ``camera``
``/thermal/ground_truth``  vision_msgs/Detection2DArray (thermal)  ``thermal_camera``
``/scene_info``            std_msgs/String (JSON), once, first     --
=========================  ======================================  ===================

Ground truth follows :mod:`mk_tracker.messages.detection_messages`: ``Detection2D.id`` is the person
id as a string, ``class_id`` is ``"person"``, ``score`` is the ``visible_fraction``; only
people with ``visible_fraction > 0`` whose box reaches into that image are listed, and the
boxes are clipped to the image (:func:`mk_tracker.boxes.clip_box`).
``/scene_info`` holds :meth:`mk_tracker.synthetic.scene.SyntheticScene.info`: the homography
``H`` (row-major 3x3, **thermal pixel -> RGB pixel**), the image sizes, the seed, the preset
and the full config, so a reader can map thermal boxes into the RGB image.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import sys
from pathlib import Path
from typing import Any

from mk_tracker.synthetic.presets import PRESETS
from mk_tracker.synthetic.scene import make_scene
from mk_tracker.synthetic.scene_config import THERMAL_ENCODINGS, SceneFrame
from mk_tracker.boxes import clip_box
from mk_tracker.synthetic.scene import SyntheticScene
from mk_tracker.synthetic.scene_config import SceneError

RGB_TOPIC = "/image_raw"
THERMAL_TOPIC = "/thermal/image_raw"
GROUND_TRUTH_TOPIC = "/ground_truth"
THERMAL_GROUND_TRUTH_TOPIC = "/thermal/ground_truth"
SCENE_INFO_TOPIC = "/scene_info"
RGB_FRAME_ID = "camera"
THERMAL_FRAME_ID = "thermal_camera"


class SceneBagError(ValueError):
    """A scene cannot be written (bad arguments, bag exists, unknown preset)."""


def ground_truth_detections(scene: SyntheticScene, frame: SceneFrame,
                            plane: str = "rgb") -> list:
    """The :class:`~mk_tracker.messages.detection_messages.Detection` list written for ``frame``.

    ``plane`` is ``"rgb"`` or ``"thermal"``; people with ``visible_fraction == 0`` or
    entirely outside that image are left out, boxes are clipped to the image.
    """
    from mk_tracker.messages.detection_messages import Detection

    if plane == "rgb":
        width, height = scene.rgb_size
    elif plane == "thermal":
        width, height = scene.thermal_size
    else:
        raise SceneBagError(f"plane must be 'rgb' or 'thermal', got {plane!r}")
    out = []
    for obj in frame.objects:
        if obj.visible_fraction <= 0.0:
            continue
        box = obj.box_rgb if plane == "rgb" else obj.box_thermal
        clipped = clip_box(box, width, height)
        if clipped is None:
            continue
        out.append(Detection(box=clipped, score=obj.visible_fraction, class_id="person",
                             id=str(obj.id)))
    return out


def write_scene_bag(scene: SyntheticScene, path: str | Path, storage: str = "mcap",
                    preset: str = "", progress: bool = False,
                    thermal_step: int = 1) -> dict[str, int]:
    """Render every frame of ``scene`` into a new bag at ``path``; returns per-topic counts.

    ``storage`` is ``"mcap"`` or ``"sqlite3"``; the bag directory must not exist.  ``preset``
    is only recorded in ``/scene_info``.  Frames are rendered and written one at a time.
    ``thermal_step`` N > 1 writes the thermal image (and its ground truth) of every N-th
    frame only: a thermal camera slower than the RGB one (9 Hz beside 25 fps).
    """
    if int(thermal_step) < 1:
        raise SceneBagError(f"thermal_step must be at least 1, got {thermal_step}")
    from mk_tracker.bags.bag_errors import BagError
    from mk_tracker.bags.bag_writer import BagWriter
    from mk_tracker.messages.detection_messages import make_detection_array
    from mk_tracker.messages.image_conversion import numpy_to_image
    from mk_tracker.messages.message_types import bag_message_types, make_header

    if not isinstance(scene, SyntheticScene):
        raise SceneBagError(f"expected a SyntheticScene, got {type(scene).__name__}")
    encoding = scene.config.thermal_encoding
    try:
        writer = BagWriter(path, storage=storage)
    except BagError as exc:
        raise SceneBagError(str(exc)) from exc
    types = bag_message_types(writer.typestore)
    string_type = writer.typestore.types["std_msgs/msg/String"]
    info = scene.info()
    info["preset"] = preset
    info["topics"] = {"rgb": RGB_TOPIC, "thermal": THERMAL_TOPIC,
                      "ground_truth": GROUND_TRUTH_TOPIC,
                      "thermal_ground_truth": THERMAL_GROUND_TRUTH_TOPIC}
    info["frame_ids"] = {"rgb": RGB_FRAME_ID, "thermal": THERMAL_FRAME_ID}
    frames = range(len(scene))
    if progress:
        try:
            from tqdm import tqdm
            frames = tqdm(frames, desc=f"writing {path}", unit="frame")
        except ImportError:
            pass
    with writer:
        writer.add_topic(SCENE_INFO_TOPIC, "std_msgs/msg/String")
        writer.add_topic(RGB_TOPIC, "sensor_msgs/msg/Image")
        writer.add_topic(THERMAL_TOPIC, "sensor_msgs/msg/Image")
        writer.add_topic(GROUND_TRUTH_TOPIC, "vision_msgs/msg/Detection2DArray")
        writer.add_topic(THERMAL_GROUND_TRUTH_TOPIC, "vision_msgs/msg/Detection2DArray")
        first_ns = round(scene.stamp(0) * 1e9)
        writer.write(SCENE_INFO_TOPIC, first_ns, string_type(data=json.dumps(info)))
        for i in frames:
            frame = scene.frame(i)
            ns = round(frame.stamp * 1e9)
            rgb_header = make_header(types, RGB_FRAME_ID, ns)
            thermal_header = make_header(types, THERMAL_FRAME_ID, ns)
            writer.write(RGB_TOPIC, ns, numpy_to_image(frame.rgb, "bgr8", rgb_header,
                                                       types=types))
            thermal = i % int(thermal_step) == 0
            if thermal:
                writer.write(THERMAL_TOPIC, ns, numpy_to_image(frame.thermal, encoding,
                                                               thermal_header, types=types))
            writer.write(GROUND_TRUTH_TOPIC, ns, make_detection_array(
                ground_truth_detections(scene, frame, "rgb"), rgb_header, types))
            if thermal:
                writer.write(THERMAL_GROUND_TRUTH_TOPIC, ns, make_detection_array(
                    ground_truth_detections(scene, frame, "thermal"), thermal_header, types))
        counts = dict(writer.counts)
    return counts


def read_scene_info(path: str | Path) -> dict[str, Any]:
    """The ``/scene_info`` JSON of a bag written by :func:`write_scene_bag`."""
    from mk_tracker.bags.bag_io import open_bag

    with open_bag(path) as bag:
        for _, msg in bag.read_messages([SCENE_INFO_TOPIC]):
            return json.loads(msg.data)
    raise SceneBagError(f"{path}: no {SCENE_INFO_TOPIC} message")


# --------------------------------------------------------------------------------------------
# the ``mk_tracker generate`` sub-command


def build_preset(name: str, seed: int = 0, people: int | None = None,
                 frames: int | None = None, width: int | None = None,
                 height: int | None = None, fps: float | None = None) -> SyntheticScene:
    """Call preset ``name`` of :data:`mk_tracker.synthetic.presets.PRESETS` with the arguments it
    takes; an argument the preset does not take raises :class:`SceneBagError`."""
    try:
        factory = PRESETS[name]
    except KeyError:
        raise SceneBagError(f"unknown preset {name!r}; choose from "
                            f"{sorted(PRESETS)}") from None
    accepted = inspect.signature(factory).parameters
    kwargs: dict[str, Any] = {"seed": seed}
    for arg, value in (("n_people", people), ("frames", frames), ("width", width),
                       ("height", height), ("fps", fps)):
        if value is None:
            continue
        if arg not in accepted:
            flag = "--people" if arg == "n_people" else f"--{arg}"
            raise SceneBagError(f"preset {name!r} does not take {flag}")
        kwargs[arg] = value
    return factory(**kwargs)


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", default="crowd", choices=sorted(PRESETS),
                        help="scene preset (default: crowd)")
    parser.add_argument("--people", type=int, default=None,
                        help="number of people (crowd preset)")
    parser.add_argument("--frames", type=int, default=None, help="number of frames")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument("--width", type=int, default=None, help="image width (crowd preset)")
    parser.add_argument("--height", type=int, default=None,
                        help="image height (crowd preset)")
    parser.add_argument("--fps", type=float, default=None,
                        help="frame rate (far_view and static_camera presets)")
    parser.add_argument("--thermal-encoding", choices=THERMAL_ENCODINGS,
                        default=None, help="override the preset's thermal encoding")
    parser.add_argument("--missing-pixels", type=float, default=None,
                        help="fraction of thermal pixels dropped per frame (0..1)")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    parser.add_argument("--out", required=True, help="bag directory to create")
    parser.add_argument("--progress", action="store_true", help="show a progress bar")


def run(args: argparse.Namespace) -> int:
    try:
        scene = build_preset(args.preset, seed=args.seed, people=args.people,
                             frames=args.frames, width=args.width, height=args.height,
                             fps=args.fps)
        changes: dict[str, Any] = {}
        if args.thermal_encoding is not None:
            changes["thermal_encoding"] = args.thermal_encoding
        if args.missing_pixels is not None:
            changes["missing_pixel_fraction"] = args.missing_pixels
        if changes:
            scene = make_scene(dataclasses.replace(scene.config, **changes))
        counts = write_scene_bag(scene, args.out, storage=args.storage, preset=args.preset,
                                 progress=args.progress)
    except (SceneError, SceneBagError, ValueError) as exc:
        print(f"mk_tracker generate: {exc}", file=sys.stderr)
        return 2
    summary = ", ".join(f"{topic} {n}" for topic, n in sorted(counts.items()))
    print(f"wrote {args.out}: preset {args.preset}, seed {args.seed}, {len(scene)} frames, "
          f"RGB {scene.rgb_size[0]}x{scene.rgb_size[1]}, thermal "
          f"{scene.thermal_size[0]}x{scene.thermal_size[1]} {scene.config.thermal_encoding}"
          f" ({summary})")
    return 0
