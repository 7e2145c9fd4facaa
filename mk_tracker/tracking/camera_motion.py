"""Camera-motion compensation: the image motion between two frames, applied to every track.

The Kalman state of a track (:mod:`mk_tracker.kalman`, (2.1)) lives in image pixels, so the
constant-velocity model assumes a still camera: when the camera pans (a robot turning, OTB
Woman) every prediction (4.2) runs off with the image motion and the multiple-kernel search
(Chu et al. 2013, Sec. IV-D) starts in the wrong place.  Following BoT-SORT (Aharon et al.
2022, Sec. 3.2), the global motion of the image between the previous frame and this one is
estimated as a 2x3 affine map ``x' = L x + t`` and every track's state is moved by it
*before* the prediction (:func:`compensate`): the Kalman mean and covariance
(:meth:`~mk_tracker.kalman.ConstantVelocityKalman.warp`: ``s' = diag(L, L) s + (t, 0)``,
``P' = diag(L, L) P diag(L, L)^T``), the kernels' centres and the boxes the track remembers.

:class:`CameraMotionEstimator` estimates the map on a downscaled grey copy of the frames
(``method``):

* ``sparse``: Shi-Tomasi corners of the previous frame (``cv2.goodFeaturesToTrack``), outside
  the tracked boxes so that walking people do not count as camera motion, followed into this
  frame by pyramidal Lucas-Kanade (``cv2.calcOpticalFlowPyrLK``); a rotation + uniform scale
  + translation fitted with RANSAC (``cv2.estimateAffinePartial2D``);
* ``ecc``: the Euclidean (rotation + translation) map maximising the enhanced correlation
  coefficient (``cv2.findTransformECC``, Evangelidis & Psarakis 2008) with the tracked boxes
  masked out.

It must never make tracking worse than a still-camera model, so a frame where the estimate
cannot be trusted gives the identity and is counted (:attr:`CameraMotionEstimator.counts`):
a blank (featureless) frame, too few features or RANSAC inliers, a failed ECC, a frame of
another size, a map beyond the plausible bounds (``max_translation``, ``max_scale_change``).
A map that moves no pixel of the frame by ``min_motion`` or more is taken as the identity too
(status ``still``), so a static camera costs nothing in accuracy.  The figures that chose
the method and default are in docs/camera_motion.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import cv2
import numpy as np

from mk_tracker.parameters import parameter
from mk_tracker.tracking.scale_estimation import rescaled_centres

__all__ = ["CAMERA_MOTION_METHODS", "FALLBACK_STATUSES", "CameraMotionConfig", "CameraMotion",
           "CameraMotionEstimator", "compensate", "grey_frame"]

CAMERA_MOTION_METHODS = ("sparse", "ecc")

#: statuses of an estimate that fell back to the identity because it could not be trusted
FALLBACK_STATUSES = ("blank", "few_features", "few_inliers", "no_convergence", "implausible",
                     "size_change")


@dataclass(frozen=True)
class CameraMotionConfig:
    """How the image motion between consecutive frames is estimated (module docstring)."""

    enabled: bool = parameter(
        False, "Estimate the camera's image motion between consecutive frames and move every "
        "track's Kalman state and kernels by it before the prediction (BoT-SORT, Aharon et "
        "al. 2022); off by default (docs/camera_motion.md)")
    method: str = parameter(
        "sparse", "sparse = corners + Lucas-Kanade flow + RANSAC rotation/scale/translation; "
        "ecc = Euclidean map by cv2.findTransformECC", choices=CAMERA_MOTION_METHODS)
    downscale: float = parameter(
        0.5, "The estimate runs on the grey frame resized by this factor (1 = full size)",
        minimum=0.05, maximum=1.0)
    max_features: int = parameter(
        200, "sparse: most corners tracked from the previous frame", minimum=4,
        maximum=100000)
    feature_quality: float = parameter(
        0.01, "sparse: corner quality level relative to the best corner "
        "(cv2.goodFeaturesToTrack)", minimum=1e-6, maximum=1.0)
    min_feature_distance: float = parameter(
        8.0, "sparse: least distance between corners, px of the downscaled frame",
        minimum=0.0, maximum=1e4)
    ransac_threshold: float = parameter(
        1.0, "sparse: RANSAC inlier distance, px of the downscaled frame", minimum=0.01,
        maximum=100.0)
    min_inliers: int = parameter(
        15, "sparse: fewer corners followed or RANSAC inliers than this give the identity "
        "(counted)", minimum=3, maximum=100000)
    ecc_iterations: int = parameter(
        40, "ecc: most iterations of cv2.findTransformECC", minimum=1, maximum=10000)
    ecc_epsilon: float = parameter(
        1e-4, "ecc: stop when the correlation coefficient changes by less than this",
        minimum=1e-12, maximum=1.0)
    box_margin: float = parameter(
        0.1, "Tracked boxes, grown by this fraction of their size on each side, are left out "
        "of the estimate (moving people are not camera motion)", minimum=0.0, maximum=10.0)
    min_motion: float = parameter(
        0.25, "A map that moves no corner of the frame by this many px or more is taken as "
        "the identity (a still camera costs nothing)", minimum=0.0, maximum=1e4)
    max_translation: float = parameter(
        0.3, "A map moving the frame's centre by more than this fraction of the frame width "
        "gives the identity (counted as implausible)", minimum=0.0, maximum=10.0)
    max_scale_change: float = parameter(
        0.2, "A map scaling the image by more than this fraction gives the identity (counted "
        "as implausible)", minimum=0.0, maximum=10.0)
    min_contrast: float = parameter(
        2.0, "A downscaled grey frame whose grey-level std is below this is blank: the "
        "identity (counted)", minimum=0.0, maximum=255.0)


IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


@dataclass(frozen=True)
class CameraMotion:
    """One estimate: ``matrix`` (2x3) maps a pixel of the previous frame to this one.

    ``status``: ``estimated`` (the map is used), ``still`` (below ``min_motion``: identity),
    ``first`` (no previous frame: identity), or one of :data:`FALLBACK_STATUSES` (identity).
    ``support``: RANSAC inliers (``sparse``) or 0.
    """

    matrix: np.ndarray = field(default_factory=lambda: IDENTITY.copy())
    status: str = "first"
    support: int = 0

    @property
    def linear(self) -> np.ndarray:
        return self.matrix[:, :2]

    @property
    def translation(self) -> np.ndarray:
        return self.matrix[:, 2]

    @property
    def fallback(self) -> bool:
        return self.status in FALLBACK_STATUSES

    @property
    def identity(self) -> bool:
        return self.status != "estimated"


def grey_frame(image: np.ndarray, downscale: float) -> np.ndarray:
    """An 8-bit grey copy of ``image`` (HxW or HxWxC, any dtype) resized by ``downscale``."""
    img = np.asarray(image)
    if img.ndim == 3:
        if img.shape[2] == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.dtype == np.uint8 \
                else img.mean(axis=2)
        elif img.shape[2] == 4 and img.dtype == np.uint8:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
        else:
            img = img.mean(axis=2)
    if img.dtype != np.uint8:
        f = np.nan_to_num(np.asarray(img, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
        img = cv2.normalize(f, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    if downscale < 1.0:
        h, w = img.shape[:2]
        size = (max(int(round(w * downscale)), 8), max(int(round(h * downscale)), 8))
        img = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(img)


class CameraMotionEstimator:
    """Estimates the image motion from the previous frame to each new one (module docstring).

    :meth:`estimate` is called once per frame with the boxes tracked in the *previous* frame
    (they are left out of the estimate); :attr:`counts` counts every status.
    """

    def __init__(self, config: CameraMotionConfig | None = None) -> None:
        self.config = config or CameraMotionConfig()
        self._previous: np.ndarray | None = None
        self._full_size: tuple[int, int] | None = None
        self.counts: dict[str, int] = {}
        self.last: CameraMotion = CameraMotion()

    def reset(self) -> None:
        """Forget the previous frame (the next estimate is the identity, status ``first``)."""
        self._previous = None
        self._full_size = None

    def remember(self, image: np.ndarray) -> None:
        """Take ``image`` as the previous frame without estimating (a track started on it)."""
        self._previous = grey_frame(image, self.config.downscale)
        self._full_size = tuple(np.asarray(image).shape[:2])

    @property
    def fallbacks(self) -> int:
        """Frames whose estimate fell back to the identity (:data:`FALLBACK_STATUSES`)."""
        return sum(self.counts.get(s, 0) for s in FALLBACK_STATUSES)

    def estimate(self, image: np.ndarray, boxes: Iterable[Sequence[float]] = ()
                 ) -> CameraMotion:
        """The map from the previous frame to ``image``; ``boxes`` ``(x, y, w, h)`` are in
        the previous frame's pixels."""
        cfg = self.config
        size = tuple(np.asarray(image).shape[:2])
        grey = grey_frame(image, cfg.downscale)
        previous, previous_size = self._previous, self._full_size
        self._previous, self._full_size = grey, size
        if previous is None:
            motion = CameraMotion(status="first")
        elif previous_size != size or previous.shape != grey.shape:
            motion = CameraMotion(status="size_change")
        elif float(np.std(grey)) < cfg.min_contrast or float(np.std(previous)) < cfg.min_contrast:
            motion = CameraMotion(status="blank")
        else:
            scale = grey.shape[1] / float(size[1])
            mask = _free_mask(previous.shape, boxes, scale, cfg.box_margin)
            try:
                if cfg.method == "ecc":
                    matrix, status, support = _ecc(previous, grey, mask, cfg)
                else:
                    matrix, status, support = _sparse(previous, grey, mask, cfg)
            except cv2.error:           # e.g. a frame too small for the flow's pyramid
                matrix, status, support = None, "no_convergence", 0
            motion = self._checked(matrix, status, support, scale, size)
        self.counts[motion.status] = self.counts.get(motion.status, 0) + 1
        self.last = motion
        return motion

    def _checked(self, matrix: np.ndarray | None, status: str, support: int, scale: float,
                 size: tuple[int, int]) -> CameraMotion:
        """The downscaled map in full-size pixels, or the identity when implausible/still."""
        cfg = self.config
        if matrix is None or not np.all(np.isfinite(matrix)):
            return CameraMotion(status=status if status != "estimated" else "no_convergence",
                                support=support)
        full = np.array(matrix, dtype=np.float64)
        full[:, 2] /= scale                 # x_s = scale x: t_full = t_small / scale
        h, w = size
        lin = full[:, :2]
        zoom = math.sqrt(abs(float(np.linalg.det(lin))))
        centre = np.array([w / 2.0, h / 2.0])
        moved = float(np.hypot(*(lin @ centre + full[:, 2] - centre)))
        if moved > cfg.max_translation * w or abs(zoom - 1.0) > cfg.max_scale_change:
            return CameraMotion(status="implausible", support=support)
        corners = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
        shift = corners @ lin.T + full[:, 2] - corners
        if float(np.max(np.hypot(shift[:, 0], shift[:, 1]))) < cfg.min_motion:
            return CameraMotion(status="still", support=support)
        return CameraMotion(matrix=full, status="estimated", support=support)


def _free_mask(shape: tuple[int, ...], boxes: Iterable[Sequence[float]], scale: float,
               margin: float) -> np.ndarray:
    """255 where the estimate may look, 0 inside the (grown, downscaled) tracked boxes."""
    mask = np.full(shape[:2], 255, dtype=np.uint8)
    h, w = shape[:2]
    for box in boxes:
        try:
            x, y, bw, bh = (float(v) for v in box)
        except (TypeError, ValueError):
            continue
        if not all(math.isfinite(v) for v in (x, y, bw, bh)) or bw <= 0 or bh <= 0:
            continue
        x0 = int(max(math.floor((x - margin * bw) * scale), 0))
        y0 = int(max(math.floor((y - margin * bh) * scale), 0))
        x1 = int(min(math.ceil((x + bw * (1 + margin)) * scale), w))
        y1 = int(min(math.ceil((y + bh * (1 + margin)) * scale), h))
        if x1 > x0 and y1 > y0:
            mask[y0:y1, x0:x1] = 0
    return mask


def _sparse(previous: np.ndarray, current: np.ndarray, mask: np.ndarray,
            cfg: CameraMotionConfig) -> tuple[np.ndarray | None, str, int]:
    """Corners + pyramidal Lucas-Kanade + RANSAC rotation/scale/translation."""
    points = cv2.goodFeaturesToTrack(previous, maxCorners=cfg.max_features,
                                     qualityLevel=cfg.feature_quality,
                                     minDistance=cfg.min_feature_distance, mask=mask,
                                     blockSize=3)
    if points is None or len(points) < cfg.min_inliers:
        return None, "few_features", 0 if points is None else len(points)
    moved, found, _ = cv2.calcOpticalFlowPyrLK(previous, current, points, None,
                                               winSize=(15, 15), maxLevel=3)
    ok = found.reshape(-1) == 1
    if int(ok.sum()) < cfg.min_inliers:
        return None, "few_features", int(ok.sum())
    matrix, inliers = cv2.estimateAffinePartial2D(points[ok], moved[ok], method=cv2.RANSAC,
                                                  ransacReprojThreshold=cfg.ransac_threshold,
                                                  maxIters=500, confidence=0.99)
    support = 0 if inliers is None else int(inliers.sum())
    if matrix is None or support < cfg.min_inliers:
        return None, "few_inliers", support
    return matrix, "estimated", support


def _ecc(previous: np.ndarray, current: np.ndarray, mask: np.ndarray,
         cfg: CameraMotionConfig) -> tuple[np.ndarray | None, str, int]:
    """The Euclidean map of the enhanced correlation coefficient (cv2.findTransformECC).

    ECC finds ``W`` with ``current(W x) ~ previous(x)``: a pixel ``x`` of the previous frame
    is at ``W x`` in this one, the direction of :class:`CameraMotion`."""
    warp = np.eye(2, 3, dtype=np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, cfg.ecc_iterations,
                cfg.ecc_epsilon)
    try:
        _, warp = cv2.findTransformECC(previous, current, warp, cv2.MOTION_EUCLIDEAN,
                                       criteria, mask, 3)
    except cv2.error:
        return None, "no_convergence", 0
    return warp.astype(np.float64), "estimated", 0


def compensate(tracks: Iterable[Any], motion: CameraMotion) -> int:
    """Move every track by ``motion`` (before its prediction); returns how many moved.

    Per track (:class:`~mk_tracker.tracking.track.Track`): the Kalman filter
    (:meth:`~mk_tracker.kalman.ConstantVelocityKalman.warp`) and the one kept for the
    observation-centric re-update, the remembered centre, the reported (smoothed) velocity
    (turned and scaled by ``L``), the last detected box (centre mapped, size scaled) and
    the smoothed size, scaled by the map's zoom
    ``sqrt(|det L|)``; the multiple-kernel target's centroid is mapped and its kernels
    rescaled about it (14) with its ``scale`` (the layout is not rotated: the kernels are
    axis-aligned, Sec. IV-A).  The identity moves nothing."""
    if motion.identity:
        return 0
    lin, shift = motion.linear, motion.translation
    zoom = math.sqrt(abs(float(np.linalg.det(lin))))
    n = 0
    for t in tracks:
        t.kf.warp(lin, shift)
        if getattr(t, "seen_filter", None) is not None:
            t.seen_filter.warp(lin, shift)
        if getattr(t, "seen_center", None) is not None:
            t.seen_center = lin @ t.seen_center + shift
        if getattr(t, "detected_box", None) is not None:
            t.detected_box = _warped_box(t.detected_box, lin, shift, zoom)
        t.size = np.asarray(t.size, dtype=np.float64) * zoom
        if getattr(t, "smoothed_velocity", None) is not None:
            t.smoothed_velocity = lin @ np.asarray(t.smoothed_velocity, dtype=np.float64)
        target = getattr(t, "target", None)
        centres = getattr(target, "centres", None)
        if centres is not None and isinstance(getattr(target, "scale", None), float):
            c = np.asarray(target.center, dtype=np.float64)
            moved = rescaled_centres(np.asarray(centres, dtype=np.float64), c, zoom)
            target.centres = moved + (lin @ c + shift - c)
            target.scale = float(target.scale) * zoom
        n += 1
    return n


def _warped_box(box: np.ndarray, lin: np.ndarray, shift: np.ndarray, zoom: float
                ) -> np.ndarray:
    x, y, w, h = (float(v) for v in box)
    c = lin @ np.array([x + w / 2.0, y + h / 2.0]) + shift
    w, h = w * zoom, h * zoom
    return np.array([c[0] - w / 2.0, c[1] - h / 2.0, w, h])
