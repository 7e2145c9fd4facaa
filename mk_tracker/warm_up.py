"""Compile (or load from numba's on-disk cache) the compiled kernels before the first frame.

The multiple-kernel tracker (:mod:`mk_tracker.tracking.search_region`,
:mod:`mk_tracker.tracking.multi_kernel`) and the thermal detector (:mod:`mk_tracker.detection.kernel_covariance`,
:mod:`mk_tracker.detection.sparse_factorization`, :mod:`mk_tracker.detection.thermal_detector`) run their inner
loops as numba functions, compiled on first use: several seconds the first time on a
machine (numba then caches them next to the modules, or in ``NUMBA_CACHE_DIR``), about a
second to load from that cache afterwards.  Paid on the first frame, that stall makes a node
drop the frames that arrive meanwhile; the nodes therefore call these functions while they
start, and the test suite calls them once before any node test.

Each function pushes a tiny synthetic input through the real code path with the given
configuration (no second implementation: the same public calls as a real frame) and
returns a :class:`WarmUp`: the seconds it took and which paths ran.  With ``MK_TRACKER_NO_NUMBA=1`` there is nothing to compile
and they return quickly.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
from mk_tracker.detection.pixel_clustering import load_valley_split
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig


@dataclass(frozen=True)
class WarmUp:
    """What a warm-up did: ``seconds`` of wall time, ``paths`` it went through (the
    tracker's calls, or the detector's ``last_mode`` values)."""

    seconds: float
    paths: frozenset[str]


def _person_image(shift: int) -> np.ndarray:
    """A 120x160 BGR frame: textured grey background, a red-over-blue 'person' at x=60+shift."""
    rng = np.random.default_rng(7)
    image = rng.integers(90, 140, size=(120, 160, 3), dtype=np.uint8)
    x = 60 + shift
    image[20:60, x:x + 24] = (40, 40, 200)
    image[60:100, x:x + 24] = (150, 60, 20)
    return image


def warm_up_tracker(config: MultiKernelConfig | None = None) -> WarmUp:
    """Start a target, refine it twice and compare an appearance with ``config``."""
    t0 = time.perf_counter()
    paths = set()
    tracker = MultiKernelTracker(config or MultiKernelConfig())
    state = tracker.start(_person_image(0), (60.0, 20.0, 24.0, 80.0))
    paths.add("start")
    for shift in (2, 4):
        if not tracker.refine(_person_image(shift), state).lost:
            paths.add("refine")
    tracker.appearance_similarity(_person_image(4), state, (64.0, 20.0, 24.0, 80.0))
    paths.add("appearance_similarity")
    return WarmUp(time.perf_counter() - t0, frozenset(paths))


def warm_up_detector(config: ThermalDetectorConfig | None = None) -> WarmUp:
    """Run the detector with ``config`` over the first frames of the paper's synthetic scene
    (a start-up pass, then tracking frames)."""
    from mk_tracker.synthetic.presets import paper_scene

    t0 = time.perf_counter()
    cfg = config or ThermalDetectorConfig()
    detector = ThermalDetector(cfg)
    scene = paper_scene()
    frames = min(len(scene), cfg.startup_frames + cfg.window_frames + 2)
    paths = set()
    for i in range(frames):
        frame = scene.frame(i)
        detector.process(frame.thermal, frame.stamp, encoding="mono8")
        paths.add(detector.last_mode)
    if cfg.split_by_valleys:
        load_valley_split()       # the paper scene has nobody who touches
        paths.add("valley_split")
    return WarmUp(time.perf_counter() - t0, frozenset(paths))
