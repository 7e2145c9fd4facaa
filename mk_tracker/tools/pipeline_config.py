"""The parameters of ``mk_tracker process``: the nodes' parameter files read as a PipelineConfig.

* :func:`load_pipeline_config` -- the package's ``config/detector.yaml`` and
  ``config/tracker.yaml``, then each ``--params-file`` (later files win), validated by
  building the detector and the tracker once.  Beside it, the tracker's parameters for
  detections from another detector (:data:`EXTERNAL_DETECTIONS_PARAMS_FILE` between the
  defaults and the ``--params-file`` files): the tracker profile ``external``; and for the
  project's background-subtraction detector (:data:`BACKGROUND_DETECTIONS_PARAMS_FILE`, in
  the same place): the profile ``background``.
* :func:`read_node_parameters` -- a node's dotted parameters from parameter files (sections
  ``node``, ``/node`` and ``/**``), without rclpy.
* :func:`split_parameters` -- prefixed parameters (``tracker.*``, ``detector.*``,
  ``threshold.*``) into their config dataclasses (:func:`mk_tracker.parameters.updated`),
  the node-level ones apart.
* :data:`TRACKER_NODE_DEFAULTS` / :data:`DETECTOR_NODE_DEFAULTS` -- the node-level parameters
  the pipeline uses, with the nodes' defaults.
* :class:`PipelineError` -- bad options, parameters or bag for the pipeline.

So the offline pipeline (:mod:`mk_tracker.tools.pipeline`) runs with the parameters the
nodes would have.  The names stay importable from :mod:`mk_tracker.tools.pipeline`.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig
from mk_tracker.detection.threshold_detector import ThresholdDetectorConfig
from mk_tracker.detection.background_detector import BackgroundDetectorConfig
from mk_tracker.frame_processing import build_detector
from mk_tracker.parameters import ParameterError, parameter_specs, updated
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker, MultiObjectTrackerConfig

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
DEFAULT_PARAMS_FILES = ("detector.yaml", "tracker.yaml")
#: the tracker overlay for detections of another detector scored in [0, 1] (issue #16:
#: the leave-one-sequence-out protocol's values where they differ from the defaults, which
#: are kept for the project's own detectors; docs/benchmark_multi_object.md)
EXTERNAL_DETECTIONS_PARAMS_FILE = "tracker_public_detections.yaml"
#: the tracker overlay for the background-subtraction detector's boxes (issue #13: the
#: leave-one-sequence-out choice of benchmarks/background_tracker_profile.py on that
#: detector's boxes, docs/background_tracker_profile.md)
BACKGROUND_DETECTIONS_PARAMS_FILE = "tracker_background_detections.yaml"
TRACKER_PROFILES = ("auto", "own", "external", "background")
#: node-level parameters the pipeline uses, with the nodes' defaults (a test keeps these
#: equal to TrackerNodeConfig / DetectorNodeConfig, which live in rclpy modules)
TRACKER_NODE_DEFAULTS = {"thermal_frame_id": "thermal_camera", "detection_buffer": 5,
                         "detection_wait": 0.0, "class_id": "person"}
DETECTOR_NODE_DEFAULTS = {"method": "kernel_covariance", "class_id": "person",
                          "ignore_regions": (0.0, 0.0, 0.0, 0.0)}


class PipelineError(ValueError):
    """Bad options or an unusable bag (nothing to track, output exists, ...)."""


def _flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(_flatten(value, name + "."))
        else:
            flat[name] = value
    return flat


def read_node_parameters(paths: Iterable[str | Path], node_name: str) -> dict[str, Any]:
    """Dotted parameters of ``node_name`` from ROS 2 parameter files (later files win).

    Sections ``/**``, ``node_name``, ``/node_name`` and ``/**/node_name`` (the shipped
    files' key: the node in any namespace) are read, in that order.
    """
    import yaml

    params: dict[str, Any] = {}
    for path in paths:
        p = Path(path)
        try:
            data = yaml.safe_load(p.read_text(encoding="utf-8")) or {}
        except (OSError, yaml.YAMLError) as exc:
            raise PipelineError(f"cannot read parameters file {p}: {exc}") from exc
        if not isinstance(data, Mapping):
            raise PipelineError(f"{p}: not a ROS 2 parameters file (top level is not a map)")
        for section in ("/**", node_name, f"/{node_name}", f"/**/{node_name}"):
            node = data.get(section)
            if isinstance(node, Mapping) and isinstance(node.get("ros__parameters"), Mapping):
                params.update(_flatten(node["ros__parameters"]))
    return params


def split_parameters(params: Mapping[str, Any], configs: Mapping[str, Any]
                     ) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(configs updated by their prefixed parameters, remaining node-level values)``.

    ``configs`` maps a parameter prefix (``"tracker"``) to a default config; a parameter
    whose first component is such a prefix is validated into it
    (:func:`mk_tracker.parameters.updated`), the others are returned as node-level values.
    """
    out = dict(configs)
    changes: dict[str, dict[str, Any]] = {k: {} for k in configs}
    rest: dict[str, Any] = {}
    for name, value in params.items():
        head, _, tail = name.partition(".")
        if head in configs and tail:
            changes[head][tail] = value
        else:
            rest[name] = value
    for prefix, config in configs.items():
        known = {s.name for s in parameter_specs(config)}
        usable = {k: v for k, v in changes[prefix].items() if k in known}
        unknown = sorted(set(changes[prefix]) - known)
        if unknown:
            print(f"mk_tracker process: ignoring unknown parameter(s) "
                  f"{', '.join(prefix + '.' + u for u in unknown)}", file=sys.stderr)
        try:
            out[prefix] = updated(config, usable)
        except ParameterError as exc:
            raise PipelineError(f"parameter {prefix}.{exc}") from exc
    return out, rest


@dataclass(frozen=True)
class PipelineConfig:
    """Everything the pipeline takes from the parameter files."""

    tracker: MultiObjectTrackerConfig = field(default_factory=MultiObjectTrackerConfig)
    detector: ThermalDetectorConfig = field(default_factory=ThermalDetectorConfig)
    threshold: ThresholdDetectorConfig = field(default_factory=ThresholdDetectorConfig)
    background: BackgroundDetectorConfig = field(default_factory=BackgroundDetectorConfig)
    method: str = DETECTOR_NODE_DEFAULTS["method"]
    ignore_regions: tuple = DETECTOR_NODE_DEFAULTS["ignore_regions"]
    detector_class_id: str = DETECTOR_NODE_DEFAULTS["class_id"]
    thermal_frame_id: str = TRACKER_NODE_DEFAULTS["thermal_frame_id"]
    detection_buffer: int = TRACKER_NODE_DEFAULTS["detection_buffer"]
    detection_wait: float = TRACKER_NODE_DEFAULTS["detection_wait"]
    class_id: str = TRACKER_NODE_DEFAULTS["class_id"]
    #: the tracker with :data:`EXTERNAL_DETECTIONS_PARAMS_FILE` after the defaults and
    #: before the given files (None when the package's config/ is not there)
    tracker_external: MultiObjectTrackerConfig | None = None
    #: the same with :data:`BACKGROUND_DETECTIONS_PARAMS_FILE`
    tracker_background: MultiObjectTrackerConfig | None = None

    def tracker_for(self, profile: str) -> MultiObjectTrackerConfig:
        """The tracker parameters of a profile of :func:`tracker_profile` (``own``,
        ``external`` or ``background``); PipelineError when its overlay file is missing."""
        if profile == "own":
            return self.tracker
        config, name = {"external": (self.tracker_external, EXTERNAL_DETECTIONS_PARAMS_FILE),
                        "background": (self.tracker_background,
                                       BACKGROUND_DETECTIONS_PARAMS_FILE)}[profile]
        if config is None:
            raise PipelineError(f"--tracker-profile {profile} needs the package's "
                                f"config/{name}")
        return config


def tracker_profile(option: str, source: str, unit_scores: bool = True) -> str:
    """``"own"``, ``"external"`` or ``"background"``: which tracker parameters a run uses.

    ``auto`` gives ``external`` for detections read from a bag topic other than the
    project's own detector output (``/thermal/detections``), e.g. the public detections
    of a MOTChallenge import, when their scores lie in [0, 1] (``unit_scores``: the
    overlay's score floor and the leave-one-sequence-out choice of its values assume that
    scale; on TUD-Campus's raw 0-133 scores it makes MOTA 0.45 -> 0.26), ``background``
    for the background-subtraction detector run on the tracked image (the RGB-only
    system, what a video gets), and ``own`` for the thermal detector, for no detections and
    for other scales.
    """
    if option not in TRACKER_PROFILES:
        raise PipelineError(f"--tracker-profile must be one of {', '.join(TRACKER_PROFILES)}, "
                            f"got {option!r}")
    if option != "auto":
        return option
    if source == "background":
        return "background"
    external = source.startswith("topic:") and source != "topic:/thermal/detections"
    return "external" if external and unit_scores else "own"


def load_pipeline_config(params_files: Sequence[str | Path] = (), *,
                         include_defaults: bool = True) -> PipelineConfig:
    """The package's ``config/*.yaml`` (when present) and then ``params_files``."""
    files: list[Path] = []
    if include_defaults:
        files += [CONFIG_DIR / n for n in DEFAULT_PARAMS_FILES if (CONFIG_DIR / n).is_file()]
    given = len(files)
    for p in params_files:
        if not Path(p).is_file():
            raise PipelineError(f"parameters file {p} does not exist")
        files.append(Path(p))
    det_cfgs, det_rest = split_parameters(
        read_node_parameters(files, "detector_node"),
        {"detector": ThermalDetectorConfig(), "threshold": ThresholdDetectorConfig(),
         "background": BackgroundDetectorConfig()})
    trk_cfgs, trk_rest = split_parameters(read_node_parameters(files, "tracker_node"),
                                          {"tracker": MultiObjectTrackerConfig()})
    overlays = {}
    for name in (EXTERNAL_DETECTIONS_PARAMS_FILE, BACKGROUND_DETECTIONS_PARAMS_FILE):
        overlay = CONFIG_DIR / name
        overlays[name] = None
        if include_defaults and overlay.is_file():
            # the overlay sits between the defaults and the given files: a value of a given
            # file wins over it
            mine = set(read_node_parameters(files[given:], "tracker_node"))
            extra = {k.partition(".")[2]: v
                     for k, v in read_node_parameters([overlay], "tracker_node").items()
                     if k.startswith("tracker.") and k not in mine}
            try:
                overlays[name] = updated(trk_cfgs["tracker"], extra)
            except ParameterError as exc:
                raise PipelineError(f"{overlay}: {exc}") from exc
    try:
        buffer = int(trk_rest.get("detection_buffer", TRACKER_NODE_DEFAULTS["detection_buffer"]))
    except (TypeError, ValueError) as exc:
        raise PipelineError(f"detection_buffer: {exc}") from exc
    if buffer < 1:
        raise PipelineError(f"detection_buffer must be >= 1, got {buffer}")
    try:
        wait = float(trk_rest.get("detection_wait", TRACKER_NODE_DEFAULTS["detection_wait"]))
    except (TypeError, ValueError) as exc:
        raise PipelineError(f"detection_wait: {exc}") from exc
    if not (math.isfinite(wait) and 0.0 <= wait <= 2.0):
        raise PipelineError(f"detection_wait must be in [0, 2] s, got {wait}")
    config = PipelineConfig(
        tracker=trk_cfgs["tracker"], detector=det_cfgs["detector"],
        threshold=det_cfgs["threshold"], background=det_cfgs["background"],
        method=str(det_rest.get("method", DETECTOR_NODE_DEFAULTS["method"])),
        ignore_regions=_float_tuple(det_rest.get("ignore_regions",
                                                 DETECTOR_NODE_DEFAULTS["ignore_regions"])),
        detector_class_id=str(det_rest.get("class_id", DETECTOR_NODE_DEFAULTS["class_id"])),
        thermal_frame_id=str(trk_rest.get("thermal_frame_id",
                                          TRACKER_NODE_DEFAULTS["thermal_frame_id"])),
        detection_buffer=buffer,
        detection_wait=wait,
        class_id=str(trk_rest.get("class_id", TRACKER_NODE_DEFAULTS["class_id"])),
        tracker_external=overlays[EXTERNAL_DETECTIONS_PARAMS_FILE],
        tracker_background=overlays[BACKGROUND_DETECTIONS_PARAMS_FILE])
    try:
        build_detector(config.method, config.detector, config.threshold,
                       config.ignore_regions, config.background)
        MultiObjectTracker(config.tracker)
    except ValueError as exc:
        raise PipelineError(f"parameters rejected: {exc}") from exc
    return config


def _float_tuple(value: object) -> tuple:
    """A parameter file's list of numbers as a tuple of floats (PipelineError otherwise)."""
    try:
        return tuple(float(v) for v in value)            # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise PipelineError(f"ignore_regions must be a list of numbers, got {value!r}") from exc
