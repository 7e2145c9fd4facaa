"""The scene of ``mk_tracker demo`` and its bag (:mod:`mk_tracker.tools.demo`, step 1).

The default scene (:func:`groups_scene`) has people walking in groups past pillars; the
``crowd`` preset has people wandering alone; the ``static_camera`` preset (the RGB-only
system: background subtraction -> tracker) has people crossing a far view with shadows, a
fading light and people who stop.  :func:`write_demo_bag` writes the scene with the
demo's bag times (thermal before RGB, pauses at the detector's slow passes).
"""

from __future__ import annotations

import json
import secrets
from pathlib import Path
from typing import Any

import numpy as np

from mk_tracker.bags.bag_io import BagWriter
from mk_tracker.synthetic.scene_bag import (GROUND_TRUTH_TOPIC, RGB_TOPIC, SCENE_INFO_TOPIC,
                                            THERMAL_TOPIC, build_preset)

#: share of a frame period between a thermal frame and its RGB frame in bag time
RGB_DELAY = 0.75
END_TOPIC = "/demo/end_of_scene"
SCENES = ("groups", "crowd", "static_camera")
#: the scene's frame rate and length by default: 200 frames at 20 fps = 10 s of scene
DEFAULT_FPS = 20.0
#: the static camera's default: 7 fps, as the outdoor clips of issue #13
STATIC_CAMERA_FPS = 7.0
DEFAULT_FRAMES = 200


class DemoError(ValueError):
    """Bad demo options or an output folder that is not ours to replace."""


def choose_seed(seed: int | None) -> int:
    """``seed`` if given, else a fresh one from the operating system's entropy (so every
    run without ``--seed`` shows another scene); small enough to type back."""
    return int(seed) if seed is not None else secrets.randbelow(1_000_000)


def groups_scene(seed: int, people: int | None = None, frames: int = DEFAULT_FRAMES,
                 fps: float = DEFAULT_FPS, width: int = 640, height: int = 480,
                 pillars: int = 3):
    """The demo's scene: ``people`` (default 6-10, drawn from ``seed``) in groups of 1-3.

    Each group walks back and forth between the left and the right third of the floor
    (waypoints alternate sides, each at a random depth), odd groups starting on the other
    side, so groups meet and cross in the middle, where the ``pillars`` stand (bottom edge
    at 60-80% of the height: people whose feet are higher up pass behind them).  Members of
    a group share the group's waypoints shifted by a fixed offset and its speed (60-100 px/s,
    about 0.7-1.2 m/s for a 1.7 m person 144 px tall), so they walk together: half of the
    groups side by side (each member 5-8% of the height deeper in the image than the one
    before and 0.3-0.6 body widths aside, so the nearer one partly hides the farther one
    while the group crosses the view), the others one after the other (1.6-2.2 body widths
    apart along x).  Returns ``(scene, groups)``, ``groups`` being the person ids of each
    group.
    """
    from mk_tracker.synthetic.scene import make_scene
    from mk_tracker.synthetic.scene_config import OccluderSpec, PersonSpec, SceneConfig

    rng = np.random.default_rng([int(seed), 0xDE30])
    n = int(rng.integers(6, 11)) if people is None else int(people)
    if n < 1:
        raise DemoError(f"need at least one person, got {n}")
    sizes: list[int] = []
    while sum(sizes) < n:
        sizes.append(min(n - sum(sizes), int(rng.choice([1, 2, 2, 3, 3]))))
    body_h = 0.3 * height
    body_w = body_h / 2.75
    floor_y = (0.5 * height, 0.9 * height)
    specs: list = []
    groups: list[list[int]] = []
    for g, size in enumerate(sizes):
        speed = float(rng.uniform(60.0, 100.0)) / fps          # px per frame
        legs = int(frames * speed / (0.4 * width)) + 3
        start_left = g % 2 == 0
        waypoints = np.empty((legs, 2))
        for j in range(legs):
            left = start_left == (j % 2 == 0)
            side = (0.08, 0.32) if left else (0.68, 0.92)
            waypoints[j] = rng.uniform(*side) * width, rng.uniform(*floor_y)
        members = []
        abreast = bool(rng.random() < 0.5)
        for m in range(size):
            rank = m - (size - 1) / 2
            if abreast:   # side by side, ~0.75 m apart: a row deeper per member
                offset = np.array([rank * rng.uniform(0.3, 0.6) * body_w,
                                   rank * rng.uniform(0.05, 0.08) * height])
            else:         # one after the other along the walk, ~1 m apart
                offset = np.array([rank * rng.uniform(1.6, 2.2) * body_w,
                                   rng.uniform(-0.02, 0.02) * height])
            members.append(len(specs))
            specs.append(PersonSpec(
                waypoints=tuple(map(tuple, (waypoints + offset).round(2).tolist())),
                speed=round(speed, 4), height=body_h,
                torso_temperature=float(rng.uniform(301.5, 304.0))))
        groups.append(members)
    occluders = []
    for k in range(pillars):
        w, h = 0.06 * width, 0.42 * height
        cx = width * (k + 1) / (pillars + 1) + float(rng.uniform(-0.04, 0.04)) * width
        bottom = float(rng.uniform(0.6, 0.8)) * height
        occluders.append(OccluderSpec(box=(cx - w / 2, bottom - h, w, h),
                                      color=tuple(int(v) for v in rng.integers(40, 120, 3))))
    config = SceneConfig(seed=int(seed), frames=int(frames), fps=float(fps), width=int(width),
                         height=int(height), perspective=0.6, people=tuple(specs),
                         occluders=tuple(occluders))
    return make_scene(config), groups


def write_demo_bag(scene: Any, out: Path, pauses: dict[int, float] | None = None,
                   lead_s: float = 0.0, preset: str = "", thermal: bool = True) -> int:
    """Render ``scene`` into a new bag at ``out`` with the demo's bag times (module
    docstring, step 1); the topics, messages and header stamps are those of
    :func:`mk_tracker.synthetic.scene_bag.write_scene_bag` (without ``/thermal/ground_truth``,
    which nothing here reads).  Thermal frame ``k`` is logged at its stamp plus ``lead_s``
    (time after ``/scene_info`` for the player's subscribers to settle) plus every pause
    ``pauses[j]`` with ``j < k``; its RGB frame and ground truth ``RGB_DELAY`` periods later
    plus ``pauses[k]`` too.  A last ``END_TOPIC`` message ``lead_s`` (at least a period)
    after the last frame keeps the player (and its publishers) alive until the last frame
    has been delivered.  Frames are rendered and written one at a time, straight to their
    final times (no second copy of a bag of ~1.2 MB a frame).  Without ``thermal`` (the
    RGB-only system) the bag has no thermal topic.  Returns the frames written."""
    from mk_tracker.messages.detection_messages import make_detection_array
    from mk_tracker.messages.image_conversion import numpy_to_image
    from mk_tracker.messages.message_types import bag_message_types, make_header
    from mk_tracker.synthetic.scene_bag import (RGB_FRAME_ID, THERMAL_FRAME_ID,
                                                ground_truth_detections)

    pauses = dict(pauses or {})
    period_ns = 1e9 / float(scene.config.fps)
    encoding = scene.config.thermal_encoding
    info = scene.info()
    info["preset"] = preset
    info["topics"] = {"rgb": RGB_TOPIC, "ground_truth": GROUND_TRUTH_TOPIC,
                      **({"thermal": THERMAL_TOPIC} if thermal else {})}
    info["frame_ids"] = {"rgb": RGB_FRAME_ID, "thermal": THERMAL_FRAME_ID}
    with BagWriter(out) as writer:
        types = bag_message_types(writer.typestore)
        string = writer.typestore.types["std_msgs/msg/String"]
        for topic, msgtype in ((SCENE_INFO_TOPIC, "std_msgs/msg/String"),
                               (RGB_TOPIC, "sensor_msgs/msg/Image"),
                               (THERMAL_TOPIC, "sensor_msgs/msg/Image"),
                               (GROUND_TRUTH_TOPIC, "vision_msgs/msg/Detection2DArray"),
                               (END_TOPIC, "std_msgs/msg/String")):
            if thermal or topic != THERMAL_TOPIC:
                writer.add_topic(topic, msgtype)
        first = round(scene.stamp(0) * 1e9)
        writer.write(SCENE_INFO_TOPIC, first, string(data=json.dumps(info)))
        paused = 0.0                        # pauses before frame k, seconds
        last = first
        for k in range(len(scene)):
            frame = scene.frame(k)
            ns = round(frame.stamp * 1e9)
            thermal_t = round(ns + 1e9 * (lead_s + paused))
            paused += pauses.get(k, 0.0)
            rgb_t = round(ns + 1e9 * (lead_s + paused) + RGB_DELAY * period_ns)
            rgb_header = make_header(types, RGB_FRAME_ID, ns)
            thermal_header = make_header(types, THERMAL_FRAME_ID, ns)
            if thermal:
                writer.write(THERMAL_TOPIC, thermal_t, numpy_to_image(
                    frame.thermal, encoding, thermal_header, types=types))
            writer.write(RGB_TOPIC, rgb_t, numpy_to_image(frame.rgb, "bgr8", rgb_header,
                                                          types=types))
            writer.write(GROUND_TRUTH_TOPIC, rgb_t, make_detection_array(
                ground_truth_detections(scene, frame, "rgb"), rgb_header, types))
            last = rgb_t
        writer.write(END_TOPIC, last + round(max(lead_s * 1e9, period_ns)),
                     string(data="end of the demo scene"))
    return len(scene)


def detector_pauses(config: Any, frames: int, warmup_s: float, full_pass_s: float
                    ) -> dict[int, float]:
    """Wall seconds to wait before the RGB frames whose thermal frame gets a full-frame
    pass of the detector (Schizas et al. 2018, Algorithm 2: the start-up pass after
    ``startup_frames`` frames, then one every ``reconfigure_period`` frames), which take
    several times a tracking pass (the first one also compiles the numba kernels)."""
    first = config.startup_frames - 1
    pauses = {first: warmup_s}
    for k in range(first + config.reconfigure_period, frames, config.reconfigure_period):
        pauses[k] = full_pass_s
    return pauses


def write_params_file(path: Path, homography: Any, method: str = "kernel_covariance"
                      ) -> None:
    """One parameters file for both nodes and the offline pipeline: the detector's
    ``method`` (``background`` for the RGB-only system, with the tracker's values for that
    detector's boxes, config/tracker_background_detections.yaml, as ``mk_tracker process``
    gives them), the scene's homography (thermal -> RGB) and reliable detection delivery;
    everything else stays default."""
    h = ", ".join(repr(float(v)) for v in np.asarray(homography, dtype=float).reshape(9))
    extra = ""
    if method == "background":
        import yaml

        from mk_tracker.tools.pipeline_config import (BACKGROUND_DETECTIONS_PARAMS_FILE,
                                                      CONFIG_DIR)
        overlay = CONFIG_DIR / BACKGROUND_DETECTIONS_PARAMS_FILE
        if overlay.is_file():
            tree = yaml.safe_load(overlay.read_text())["/**/tracker_node"]["ros__parameters"]
            extra = "".join("      " + line + "\n" for line in
                            yaml.safe_dump(tree["tracker"], sort_keys=True).splitlines())
    path.write_text(
        f"detector_node:\n  ros__parameters:\n    method: {method}\n"
        "tracker_node:\n  ros__parameters:\n"
        "    detections_qos:\n      reliability: reliable\n"
        f"    tracker:\n      homography: [{h}]\n{extra}", encoding="utf-8")


def make_demo_scene(name: str, seed: int, people: int | None, frames: int,
                    fps: float | None, width: int, height: int):
    """``(scene, groups, preset name)`` of scene ``name`` (one of :data:`SCENES`)."""
    if name == "crowd":
        if fps is not None:
            raise DemoError("--fps applies to the groups and static_camera scenes only "
                            "(crowd is 25 fps)")
        scene = build_preset("crowd", seed=seed, people=people or 5, frames=frames,
                             width=width, height=height)
        return scene, [[k] for k in range(len(scene.config.people))], "crowd"
    if name == "static_camera":
        if (width, height) != (640, 480):
            raise DemoError("the static_camera scene is 640x480")
        scene = build_preset("static_camera", seed=seed, people=people or 10, frames=frames,
                             fps=fps or STATIC_CAMERA_FPS)
        return scene, [[k] for k in range(len(scene.config.people))], "static_camera"
    scene, groups = groups_scene(seed, people=people, frames=frames, fps=fps or DEFAULT_FPS,
                                 width=width, height=height)
    return scene, groups, "demo_groups"
