"""Multiple-kernel tracking with projected gradients (Chu, Hwang, Pai, Lan, IEEE TMM 2013).

One target is ``N`` elliptical kernels (layouts in :mod:`mk_tracker.tracking.kernel_layouts`) whose
centres form the state ``x = [x_1 y_1 ... x_N y_N]^T`` (Sec. IV-A).  Each kernel carries a
colour-histogram target model ``q_i`` and has a K-L cost ``J_i(x)`` (Appendix C,
:mod:`mk_tracker.tracking.kernel_histograms`).  Per frame the tracker solves (4)

    min_x  J(x) = sum_i W_i J_i(x)   (3), (7)   subject to  C(x) = 0   (12)-(13)

with the projected-gradient iteration of Algorithm 1 and the step (5)/(8):

    dx_A = alpha (-I + C_x (C_x^T C_x)^+ C_x^T) W J_x,     dx_B = -C_x (C_x^T C_x)^+ C(x)

where ``J_x`` is minus the kernels' mean-shift vectors (C.4).  Afterwards the scale is updated
from the bandwidth derivative of the density estimate (9)-(11), and the models are blended
towards the current candidates, both only when the mean similarity is above a gate (0.3).

Rank deficiency of ``C_x^T C_x`` and how the step (5)/(8) copes with it: see
:mod:`mk_tracker.tracking.projected_gradient`, which holds the constraints and the step.

Speed.  :meth:`MultiKernelTracker.refine` quantises only its search region and evaluates all
kernels of the target per iteration in one call of
:meth:`mk_tracker.tracking.search_region.SearchRegion.evaluate` (numba-compiled by default, numpy
with ``backend="numpy"`` or ``MK_TRACKER_NO_NUMBA=1``; both give the same results, tested).
The iteration of Algorithm 1 is sensitive to rounding: the two backends (or a first box moved
by 1e-9 px) give the same boxes for the first few to few tens of frames, then can drift apart
by pixels on sequences where the iteration does not settle within ``T`` steps; the benchmark
centre errors of both stay within the spread such 1e-9 px moves cause
(docs/profile_multi_kernel.md).

Constraint thresholds.  The paper sets ``eps_C`` per constraint "in the range 0.05 to 9
depending on the object size".  Here a single pixel tolerance ``e`` (``constraint_tolerance_px``)
is turned into each constraint's threshold ``((L + e)^2 - L^2) / (L^2 + 1)``, i.e. a kernel
pair may be ``e`` pixels off its initial offset, which is size dependent in the same way.

Cost threshold (deviation).  The paper stops Algorithm 1 once ``J < eps_J = 0.7 N``.  With
the K-L cost computed here (smoothed histograms, 512 HSV bins) a well-placed kernel has
``J_i ~ 0.01-0.05`` and a kernel 5-10 px off its target still has ``J_i < 0.3``, so
``0.7 N`` ends the iteration before the first step and the tracker does not follow the target
(docs/benchmark_single_target.md shows the ``eps_J = 0.7N`` row).  The default
``epsilon_j_factor`` is therefore 0 (iterate until ``T`` or until no kernel moves more than
``min_step_px``); :func:`paper_config` returns the paper's 0.7.

Model and scale gates (deviations, measured in docs/benchmark_single_target.md).  The paper
updates model and scale when the mean kernel similarity exceeds 0.3 and gives no blend rate.
Here a kernel's model is blended with rate ``model_update_rate`` (default 0: even 0.02 let
the models absorb background and drift), and only kernels whose own similarity is above the
gate are blended.  The scale (9)-(11) is updated only when the *minimum* kernel similarity
exceeds ``scale_similarity_gate`` = 0.8: with the paper's mean > 0.3, an occluded kernel
(ellipse edge covered by an occluder) biases ``r(h)`` and the box shrank or grew by the
5 %/frame limit until the target was lost.  :func:`paper_config` restores the paper's gates.
The step itself and its checks (a cost-decrease margin, the three-scale test of Comaniciu et
al.) are in :mod:`mk_tracker.tracking.scale_estimation` (``config.scale``).

Search additions (not in the paper; off by default, on for tracks started by hand, see
:mod:`mk_tracker.tracking.manual_track`; issue #16).  Algorithm 1 is a local descent: each
kernel's mean-shift vector (C.3) only sees pixels under the kernel, so a target that moved
further than about one kernel half-axis from the start is not found.  The additions live in
:mod:`mk_tracker.tracking.redetection`: (a) failure detection against the track's own history
(``similarity_reference_rate``: every decision uses each kernel's ``-J_i`` or Bhattacharyya
coefficient against the mean and spread learnt over the frames the track was seen); (b) a
coarse-to-fine start
on a grid around the prediction (``multi_start_radius``), tried when the search from the
prediction leaves the target unseen (``multi_start_similarity``); (c) re-detection after a
failure (``recovery_similarity``): a colour back-projection scan of a window that grows with
the time lost (``recovery_margin``, ``recovery_growth``), confirmed by the multiple-kernel
similarity and refined by Algorithm 1.  The Kalman prediction (Sec. IV-D) stays the first
start and wins ties.  (d) :meth:`MultiKernelTracker.start` lays the kernels out on the part of
a box inside the image, or on the whole box past the border (``outside=True``; the border as
an occluder, :mod:`mk_tracker.tracking.image_border`: models completed as kernels come into
view, the mean shift (C.3) of a cut kernel taken relative to its in-image support).

State and mutation.  :meth:`MultiKernelTracker.refine` *mutates* the :class:`TargetState` it
is given: on success the kernel centres move to the result; the scale and the models change
only above the gates described above.  When the result is ``lost`` the
state's kernels, scale and models are left as they were (only ``state.lost`` and
``state.similarity`` change).  Use :meth:`TargetState.copy` to refine without side effects.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from mk_tracker.boxes import BoxLike, InvalidBoxError, as_box, clip_box
from mk_tracker.tracking.kernel_histograms import (  # noqa: F401  (evaluate_kernel: re-exported)
    InvalidImageError, KernelBatch, check_image, evaluate_kernel, number_of_bins)
from mk_tracker.tracking.search_region import (KernelBackendError, SearchRegion,
                                               quantize_region, resolve_backend)
from mk_tracker.tracking.projected_gradient import (_compiled_step, constraint_jacobian,
                                                    constraint_thresholds, constraint_values,
                                                    kernel_pairs, pair_distances,
                                                    projected_gradient_step)
from mk_tracker.tracking.kernel_layouts import kernel_layout, kernels_bounding_box
from mk_tracker.tracking.peak_contrast import peak_contrasts
from mk_tracker.parameters import validate_config
from mk_tracker.tracking.image_border import complete_models, inside_fractions, support_offsets
from mk_tracker.tracking.background_weighting import (BackgroundModel, background_model,
                                                      corrected_costs, histogram_overlap,
                                                      reweighted, ring_histogram, ring_region)
from mk_tracker.tracking.redetection import (grid_start, redetect, relative_similarities,
                                             update_reference)
from mk_tracker.tracking.scale_estimation import ScaleStep, gated_step, scale_step
# MultiKernelConfig and its presets are re-exported from here
from mk_tracker.tracking.multi_kernel_config import (  # noqa: F401
    MultiKernelConfig, mean_shift_baseline_config, paper_config)


class TrackingInputError(ValueError):
    """A box or image given to the tracker cannot be used (empty, outside, NaN, uniform)."""


#: Statistics of the kernel similarities that say how well a target is seen (see
#: :func:`visibility_similarity`).
VISIBILITY_STATISTICS = ("mean", "weighted")


def visibility_similarity(similarities: np.ndarray, weights: np.ndarray | None = None,
                          statistic: str = "mean") -> float:
    """How well a target is seen, from its kernel similarities ``rho_i = exp(-J_i)``.

    ``"mean"``: ``sum_i rho_i / N``, the plain mean (the mean similarity of (5)).
    ``"weighted"``: ``sum_i W_i rho_i / N`` with the adaptive weights ``W_i`` of (7)-(8)
    (``W_i = N rho_i / sum_j rho_j``, so this is ``sum rho_i^2 / sum rho_i``); ``weights``
    defaults to those.  One occluded kernel (``rho ~ 0``) halves the plain mean of two
    kernels but hardly changes the weighted one, which follows the kernels that still see
    the target; with every kernel occluded both are low.  NaN similarities count as 0.
    Raises ``ValueError`` for an unknown statistic or mismatched shapes.
    """
    if statistic not in VISIBILITY_STATISTICS:
        raise ValueError(f"visibility statistic must be one of {VISIBILITY_STATISTICS}, "
                         f"got {statistic!r}")
    s = np.asarray(similarities, dtype=np.float64).reshape(-1)
    if s.size == 0:
        raise ValueError("no kernel similarities")
    s = np.where(np.isfinite(s), s, 0.0)
    if statistic == "mean":
        return float(s.mean())
    w = adaptive_weights(s) if weights is None else \
        np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != s.shape:
        raise ValueError(f"{w.size} weights for {s.size} kernel similarities")
    return float(np.sum(w * s) / s.size)


def adaptive_weights(similarities: np.ndarray) -> np.ndarray:
    """``W_i ~ sim_i`` normalised to sum ``N`` (7)-(8); uniform when every sim is 0."""
    s = np.asarray(similarities, dtype=np.float64)
    total = float(s.sum())
    if not total > 0:
        return np.ones_like(s)
    return s * (s.size / total)


# --------------------------------------------------------------------------------------------
# Per-target state and results
# --------------------------------------------------------------------------------------------

@dataclass
class TargetState:
    """Everything one target carries between frames.

    ``centres`` are the kernel centres (N, 2); the kernel half-axes are
    ``base_half_axes * scale``; the pair distances of (12)-(13) are ``base_lx * scale`` and
    ``base_ly * scale``; ``models`` are the target histograms ``q_i`` (N, m).
    """

    centres: np.ndarray
    base_half_axes: np.ndarray
    scale: float
    models: np.ndarray
    base_lx: np.ndarray
    base_ly: np.ndarray
    pairs: np.ndarray
    similarity: float = 1.0
    lost: bool = False
    frames: int = 0
    #: per kernel: the mean learnt_measure over the frames the track was seen
    #: (:func:`mk_tracker.tracking.redetection.update_reference`); None = all 1
    reference: np.ndarray | None = None
    #: per kernel: its learnt variance; None = similarity_spread_prior^2
    reference_var: np.ndarray | None = None
    #: consecutive frames whose result said the track failed (re-search window growth)
    failed_frames: int = 0
    #: the last scale update's record (:class:`~mk_tracker.tracking.scale_estimation.ScaleStep`)
    scale_step: ScaleStep | None = None
    #: per kernel: in-image share of its model (``start(outside=True)``); None = all seen
    seen: np.ndarray | None = None
    #: the background weighting (``background_weighting`` ``cbwh``): plain models, ring
    #: histogram, weights, cost offsets; ``models`` then holds the weighted models
    background: BackgroundModel | None = None

    @property
    def num_kernels(self) -> int:
        return int(self.centres.shape[0])

    @property
    def half_axes(self) -> np.ndarray:
        return self.base_half_axes * self.scale

    @property
    def box(self) -> tuple[float, float, float, float]:
        """Bounding box of the kernels' extremes, eq. (14)."""
        return kernels_bounding_box(self.centres, self.half_axes)

    @property
    def center(self) -> np.ndarray:
        """Centroid ``((x_min + x_max)/2, (y_min + y_max)/2)`` of eq. (14)."""
        x, y, w, h = self.box
        return np.array([x + w / 2.0, y + h / 2.0])

    def copy(self) -> "TargetState":
        return copy.deepcopy(self)


@dataclass
class RefinementResult:
    """Outcome of one :meth:`MultiKernelTracker.refine`.

    ``box`` is (x, y, w, h) from the kernels' extremes (14), ``center`` its centroid;
    ``similarity`` the mean of ``kernel_similarities`` (each ``exp(-J_i)`` in [0, 1]);
    ``weights`` the adaptive W_i (``weighted_similarity`` = ``sum_i W_i rho_i / N``); ``kernel_centres``/``kernel_axes`` the ellipses for drawing;
    ``lost`` with ``reason`` ("" when tracked, else "outside_image", "nan_pixels" or
    "low_similarity").
    """

    box: tuple[float, float, float, float]
    center: tuple[float, float]
    similarity: float
    kernel_similarities: np.ndarray
    weights: np.ndarray
    kernel_centres: np.ndarray
    kernel_axes: np.ndarray
    iterations: int
    lost: bool
    reason: str = ""
    cost: float = float("nan")
    scale: float = 1.0
    cost_history: list = field(default_factory=list)

    @property
    def weighted_similarity(self) -> float:
        """``sum_i W_i rho_i / N`` (:func:`visibility_similarity`, ``"weighted"``)."""
        return visibility_similarity(self.kernel_similarities, self.weights, "weighted")


# --------------------------------------------------------------------------------------------
# The tracker
# --------------------------------------------------------------------------------------------

def _checked_image(image: np.ndarray) -> np.ndarray:
    try:
        return check_image(image)
    except InvalidImageError as exc:
        raise TrackingInputError(str(exc)) from exc


def _region(box: tuple[float, float, float, float], margin: float, width: int, height: int,
            extra_px: float = 0.0) -> tuple[int, int, int, int] | None:
    """Integer search region ``(x0, y0, x1, y1)`` of ``box`` grown by ``margin`` (a fraction
    of its width in x, of its height in y) plus ``extra_px`` pixels on every side, clipped."""
    x, y, w, h = box
    mx, my = margin * w + extra_px, margin * h + extra_px
    grown = (x - mx, y - my, w + 2 * mx, h + 2 * my)
    clipped = clip_box(grown, width, height)
    if clipped is None:
        return None
    cx, cy, cw, ch = clipped
    x0, y0 = int(np.floor(cx)), int(np.floor(cy))
    x1, y1 = int(np.ceil(cx + cw)), int(np.ceil(cy + ch))
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1, y1


class MultiKernelTracker:
    """The projected-gradient multiple-kernel tracker; holds only its configuration.

    Targets are :class:`TargetState` objects created by :meth:`start`, so one tracker serves
    any number of targets.  ``backend`` selects the kernel evaluation: ``"auto"`` (compiled
    when numba is available), ``"compiled"`` or ``"numpy"`` (the reference); an unknown or
    unavailable backend raises :class:`TrackingInputError`.
    """

    def __init__(self, config: MultiKernelConfig | None = None, backend: str = "auto"):
        self.config = config if config is not None else MultiKernelConfig()
        validate_config(self.config)
        self.n_bins = number_of_bins(self.config.bins)
        try:
            self.backend = resolve_backend(backend)
        except KernelBackendError as exc:
            raise TrackingInputError(str(exc)) from exc
        if self.backend == "compiled":
            _compiled_step()        # compiled (or loaded) with the tracker, not on a frame

    # -- helpers ---------------------------------------------------------------------------
    def _stride(self, axes: np.ndarray) -> int:
        """Sampling stride so that no kernel holds much more than ``max_kernel_pixels``."""
        area = float(np.pi * np.max(axes[:, 0] * axes[:, 1]))
        return max(1, int(np.ceil(np.sqrt(area / self.config.max_kernel_pixels))))

    def _search_region(self, image: np.ndarray, region: tuple[int, int, int, int],
                       stride: int) -> SearchRegion | None:
        """The region's bin indices sampled every ``stride`` px on a grid fixed in the image,
        ready for kernel evaluations; None when the region holds NaN pixels."""
        cfg = self.config
        x0, y0, x1, y1 = region
        x0, y0 = (x0 // stride) * stride, (y0 // stride) * stride
        bins = quantize_region(image, (x0, y0, x1, y1), stride, cfg.colour_space, cfg.bins,
                               self.backend)
        if bins is None:
            return None
        return SearchRegion(bins, (x0, y0), stride, self.n_bins, cfg.profile, self.backend)

    def _evaluate(self, region: SearchRegion, axes: np.ndarray, centres: np.ndarray,
                  models: np.ndarray) -> KernelBatch:
        cfg = self.config
        return region.evaluate(axes, centres, models, cfg.histogram_epsilon,
                               cfg.pixel_weighting)

    def _ring_histogram(self, image: np.ndarray, box: tuple[float, float, float, float],
                        stride: int) -> np.ndarray | None:
        """The background histogram ``o`` of the ring around ``box`` (``background_ring``
        box sizes, :func:`~mk_tracker.tracking.background_weighting.ring_histogram`),
        sampled on the kernels' grid; all zero for an empty ring, None for NaN pixels."""
        height, width = image.shape[:2]
        region = ring_region(box, self.config.background_ring, width, height)
        if region is None:
            return np.zeros(self.n_bins)
        search = self._search_region(image, region, stride)
        if search is None:
            return None
        return ring_histogram(search.bins, search.origin, search.stride, box, self.n_bins)

    def gate_similarities(self, ev: KernelBatch, state: TargetState,
                          n_layouts: int = 1) -> np.ndarray:
        """``exp(-J_i)`` of Sec. III-A per kernel; with a background weighting
        ``exp(-max(J_i - J0_i, 0))``, the cost above the one the weighted model gives the
        target's first-frame histogram, so every level keeps its meaning
        (:mod:`mk_tracker.tracking.background_weighting`).  0 for a kernel without
        pixels."""
        if state.background is None:
            return ev.similarities
        c = corrected_costs(ev.costs, state.background, n_layouts)
        with np.errstate(invalid="ignore"):
            return np.where(np.isfinite(c), np.exp(-np.maximum(c, 0.0)), 0.0)

    def _update_background(self, image: np.ndarray, state: TargetState) -> None:
        """Ning et al.'s re-computation: the ring histogram at the located box replaces the
        old one when their Bhattacharyya coefficient is below
        ``background_update_similarity``; the weights, weighted models and offsets follow."""
        cfg = self.config
        bg = state.background
        if bg is None or cfg.background_update_similarity <= 0:
            return
        o = self._ring_histogram(image, state.box, self._stride(state.half_axes))
        if o is None or not o.sum() > 0:
            return
        if histogram_overlap(o, bg.histogram) < cfg.background_update_similarity:
            bg.histogram = o
            bg.updates += 1
            state.models = reweighted(bg, cfg.background_weight_floor, cfg.histogram_epsilon)

    # -- public API ------------------------------------------------------------------------
    def start(self, image_bgr: np.ndarray, box: BoxLike, outside: bool = False) -> TargetState:
        """Build a target from ``box`` (x, y, w, h) in ``image_bgr`` (H x W x 3 BGR).

        The kernels of the configured layout are placed in the box (in its part inside the
        image when it reaches outside, e.g. a person entering at an edge), each kernel's model
        is the histogram under it, and ``L_x``, ``L_y`` are set so (12)-(13) hold; with
        ``outside=True`` on the whole box, past the border (each model from the kernel's
        part in the image; :mod:`mk_tracker.tracking.image_border`).  Raises
        :class:`TrackingInputError` for an empty, zero-area, non-finite or out-of-image box,
        a bad image, NaN pixels, a kernel with no pixel, or a uniform-colour target (its
        histogram puts everything in one bin, so there is nothing to track).
        """
        image = _checked_image(image_bgr)
        try:
            b = tuple(float(v) for v in as_box(box))
        except InvalidBoxError as exc:
            raise TrackingInputError(str(exc)) from exc
        height, width = image.shape[:2]
        clipped = clip_box(b, width, height)
        if clipped is None:
            raise TrackingInputError(f"box {b} is entirely outside the {width}x{height} image")
        # a box reaching outside the image: kernels on its visible part (no q_i of the void),
        # or with ``outside`` on the whole box, each q_i from the kernel's part in the image
        cfg = self.config
        centres, axes = kernel_layout(b if outside else clipped, cfg.num_kernels)
        b = tuple(float(v) for v in clipped)
        region = _region(b, 0.0, width, height)
        if region is None:
            raise TrackingInputError(f"box {b} covers no whole pixel of the image")
        stride = self._stride(axes)
        search = self._search_region(image, region, stride)
        if search is None:
            raise TrackingInputError("the target region holds NaN or infinite pixels")
        uniform = np.full((cfg.num_kernels, self.n_bins), 1.0 / self.n_bins)
        batch = self._evaluate(search, axes, centres, uniform)
        for i in np.flatnonzero(batch.n_pixels == 0):
            raise TrackingInputError(
                f"kernel {i} of box {b} has no pixel inside the image (box too small or "
                f"mostly outside)")
        models = batch.p.copy()
        if float(models.mean(axis=0).max()) >= 0.999:
            raise TrackingInputError(
                "the target has a uniform colour (one histogram bin holds all its mass); a "
                "colour-histogram tracker cannot localise it")
        pairs = kernel_pairs(cfg.num_kernels)
        lx, ly = pair_distances(centres, pairs)
        seen = inside_fractions(centres, axes, width, height) if outside else None
        background = None
        if cfg.background_weighting == "cbwh":
            o = self._ring_histogram(image, kernels_bounding_box(centres, axes), stride)
            if o is None:
                raise TrackingInputError("the background ring holds NaN or infinite pixels")
            background, models = background_model(models, o, cfg.background_weight_floor,
                                                   cfg.histogram_epsilon)
        return TargetState(centres=centres, base_half_axes=axes, scale=1.0, models=models,
                           base_lx=lx, base_ly=ly, pairs=pairs, similarity=1.0, seen=seen,
                           background=background)

    def refine(self, image_bgr: np.ndarray, state: TargetState,
               predicted_center: tuple[float, float] | np.ndarray | None = None
               ) -> RefinementResult:
        """Run Algorithm 1 on ``image_bgr`` for one target and update ``state``.

        The search starts from the state's kernels, translated so their centroid (14) is at
        ``predicted_center`` when given (Sec. IV-D: the Kalman prediction initialises the
        search; the result is the measurement).  Only pixels of the search region (the start
        box grown by ``search_margin``) are read.  Two optional additions (both off by
        default; tracks started by hand turn them on, :mod:`mk_tracker.tracking.manual_track`):

        * ``multi_start_radius`` > 0: a coarse grid of start translations is scored first
          (:func:`~mk_tracker.tracking.redetection.grid_start`) and Algorithm 1 also runs
          from its best point; the result with the higher mean similarity (5) is kept;
        * ``recovery_similarity`` > 0: a result whose weighted visibility (7)-(8) is below it
          is a failure; a window growing with the failure's length is scanned with the
          target's back-projection and Algorithm 1 runs from its best confirmed peak
          (:func:`~mk_tracker.tracking.redetection.redetect`);
        * ``similarity_reference_rate`` > 0: those tests, the lost test and the reported
          ``kernel_similarities`` use each kernel's ``-J_i`` (or ``B_i``) against the
          level learnt from the track's history (:meth:`decision_similarities`); the model
          and scale gates
          keep ``exp(-J_i)``.

        See the module docstring for how the state is mutated.  Never raises for a bad
        frame: a target outside the image, NaN pixels or a similarity below
        ``lost_similarity`` give ``lost=True`` with a ``reason``; a badly shaped image raises
        :class:`TrackingInputError`.
        """
        cfg = self.config
        image = _checked_image(image_bgr)
        height, width = image.shape[:2]
        axes = state.half_axes
        x = state.centres.astype(np.float64).copy()
        if predicted_center is not None:
            pc = np.asarray(predicted_center, dtype=np.float64).reshape(-1)
            if pc.shape != (2,) or not np.all(np.isfinite(pc)):
                raise TrackingInputError(f"predicted_center {predicted_center!r} is not two "
                                         f"finite numbers")
            x += pc - state.center
        start_box = kernels_bounding_box(x, axes)
        # the region also covers the grid of starts: multi_start_radius box widths in x and,
        # in the same pixels, in y
        reach = cfg.multi_start_radius * start_box[2]
        region = _region(start_box, cfg.search_margin, width, height, extra_px=reach)
        if region is None:
            return self._lost(state, x, axes, "outside_image")
        stride = self._stride(axes)
        search = self._search_region(image, region, stride)
        if search is None:
            return self._lost(state, x, axes, "nan_pixels")
        best = self._algorithm1(search, region, x, state)
        first = self.decision_similarities(best[1], state)
        if cfg.multi_start_radius > 0 and \
                visibility_similarity(first, None, "weighted") < cfg.multi_start_similarity:
            alt_start, alt_score = grid_start(self, search, x, state, start_box[2])
            # the second run only when the grid point already beats where the first one ended
            if alt_start is not None and alt_score > float(first.mean()):
                alt = self._algorithm1(search, region, alt_start, state)
                alt_sims = self.decision_similarities(alt[1], state)
                if float(alt_sims.mean()) > float(first.mean()):
                    best, first = alt, alt_sims
        failing = visibility_similarity(first, None, "weighted") < cfg.recovery_similarity
        if cfg.recovery_similarity > 0 and failing:
            found = self._recover(image, state, start_box, float(first.mean()))
            if found is not None:
                best, search = found
                first = self.decision_similarities(best[1], state)
                failing = False
        state.failed_frames = state.failed_frames + 1 if failing else 0
        x, ev, iterations, history = best
        n_k = state.num_kernels
        sims = first
        w = adaptive_weights(sims) if cfg.adaptive_weights else np.ones(n_k)
        total = _weighted_cost(w, ev.costs)
        mean_sim = float(sims.mean())
        if not mean_sim >= cfg.lost_similarity or mean_sim == 0.0:
            result = self._lost(state, x, axes, "low_similarity", sims, w)
            result.iterations = iterations
            return result

        state.centres = x
        state.similarity = mean_sim
        state.lost = False
        state.frames += 1
        if cfg.similarity_reference_rate > 0 and not failing:
            update_reference(state, ev.p, sims, cfg.recovery_similarity,
                             cfg.similarity_reference_rate, cfg.similarity_spread_prior,
                             corrected_costs(ev.costs, state.background), cfg.learnt_measure)
        # the model and scale gates keep the paper's similarity exp(-J_i) (with a background
        # weighting, above the first box's cost)
        sims = self.gate_similarities(ev, state)
        mean_sim = float(sims.mean())
        bg = state.background
        # the plain models learn; weighted ones are derived from them
        models = state.models if bg is None else bg.plain
        changed = 0
        if state.seen is not None:      # kernels coming into view (image_border.py)
            changed = complete_models(models, state.seen, ev.p, sims, inside_fractions(
                x, axes, width, height), cfg.similarity_gate, cfg.border_model_gain)
        state.scale_step = gated_step(mean_sim, state.scale)
        if mean_sim > cfg.similarity_gate:
            if cfg.model_update_rate > 0:
                rate = cfg.model_update_rate
                for i in range(n_k):
                    if sims[i] > cfg.similarity_gate and ev.n_pixels[i] > 0:
                        models[i] = (1.0 - rate) * models[i] + rate * ev.p[i]
                        changed += 1
        if bg is not None and changed:
            state.models = reweighted(bg, cfg.background_weight_floor, cfg.histogram_epsilon)
        if mean_sim > cfg.similarity_gate:
            scale_sim = mean_sim if cfg.scale_gate_statistic == "mean" else float(sims.min())
            if cfg.scale_update and cfg.beta > 0 and scale_sim > cfg.scale_similarity_gate:
                state.scale_step = self._update_scale(search, state, w, ev, scale_sim)
            else:
                state.scale_step = gated_step(scale_sim, state.scale)
            self._update_background(image, state)
        axes = state.half_axes
        box = kernels_bounding_box(state.centres, axes)
        return RefinementResult(box=box, center=(box[0] + box[2] / 2, box[1] + box[3] / 2),
                                similarity=state.similarity, kernel_similarities=first,
                                weights=w,
                                kernel_centres=state.centres.copy(), kernel_axes=axes.copy(),
                                iterations=iterations, lost=False, cost=total,
                                scale=state.scale, cost_history=history)

    def _algorithm1(self, search: SearchRegion, region: tuple[int, int, int, int],
                    x: np.ndarray, state: TargetState
                    ) -> tuple[np.ndarray, KernelBatch, int, list]:
        """Algorithm 1 from the kernel centres ``x`` inside ``search``: projected-gradient
        steps dx_A + dx_B of (5)/(8) on the weighted cost (7) under (12)-(13), until
        ``J < eps_J`` and ``|C| < eps_C``, ``T`` steps or a step below ``min_step_px``.
        Returns ``(x, evaluation at x, iterations, cost history)``; ``state`` is not
        changed."""
        cfg = self.config
        n_k = state.num_kernels
        axes = state.half_axes
        x = x.copy()
        lo = np.array([region[0], region[1]], dtype=np.float64)
        hi = np.array([region[2], region[3]], dtype=np.float64)
        lx, ly = state.base_lx * state.scale, state.base_ly * state.scale
        eps_c = constraint_thresholds(lx, ly, cfg.constraint_tolerance_px)
        eps_j = cfg.epsilon_j_factor * n_k
        max_step = cfg.max_step_fraction * axes
        models = state.models

        # the compiled closed-form step (same results as the numpy functions, tested)
        step_loops = _compiled_step() if self.backend == "compiled" else None
        if step_loops is not None:
            c = np.empty(2 * len(state.pairs))
            dx_a, dx_b = np.empty(2 * n_k), np.empty(2 * n_k)
        ev = self._evaluate(search, axes, x, models)
        iterations = 0
        history = []
        for _ in range(cfg.max_iterations):
            w = adaptive_weights(self.gate_similarities(ev, state)) if cfg.adaptive_weights \
                else np.ones(n_k)
            total = _weighted_cost(w, ev.costs)
            history.append(total)
            ms = ev.mean_shift
            if state.seen is not None:      # pixels past the border are unseen, not background
                ms = ms - support_offsets(x, axes, lo, hi)
            jx = -ms.reshape(-1)
            if step_loops is not None:
                step_loops(x, state.pairs, lx, ly, jx, w, cfg.alpha,
                           cfg.use_projected_gradient, c, dx_a, dx_b)
            else:
                c = constraint_values(x, state.pairs, lx, ly)
            c_ok = bool(np.all(np.abs(c) < eps_c))
            j_ok = total < eps_j
            if c_ok and j_ok:
                break
            if step_loops is None:
                jac = constraint_jacobian(x, state.pairs, lx, ly)
                dx_a, dx_b = projected_gradient_step(jx, jac, c, w, cfg.alpha,
                                                     cfg.use_projected_gradient,
                                                     cfg.rank_tolerance)
            if c_ok:
                dx = dx_a
            elif j_ok:
                dx = dx_b
            else:
                dx = dx_a + dx_b
            step = np.clip(dx.reshape(n_k, 2), -max_step, max_step)
            step[np.isnan(step)] = 0.0
            x = np.clip(x + step, lo, hi)
            iterations += 1
            ev = self._evaluate(search, axes, x, models)
            if float(np.abs(step).max()) < cfg.min_step_px:
                break
        return x, ev, iterations, history

    def decision_similarities(self, ev: KernelBatch, state: TargetState,
                              n_layouts: int = 1) -> np.ndarray:
        """The per-kernel similarities every decision uses (lost, coarse-to-fine start,
        re-search) and the result reports: ``exp(-J_i)`` (Sec. III-A), or with
        ``similarity_reference_rate`` > 0 each kernel's ``-J_i`` (or ``B_i``) against the
        level learnt from the track's history
        (:func:`~mk_tracker.tracking.redetection.relative_similarities`)."""
        if self.config.similarity_reference_rate > 0:
            cfg = self.config
            return relative_similarities(state, ev.p, n_layouts, cfg.failure_sigmas,
                                         cfg.similarity_spread_floor,
                                         cfg.similarity_spread_prior,
                                         corrected_costs(ev.costs, state.background,
                                                         n_layouts), cfg.learnt_measure)
        return self.gate_similarities(ev, state, n_layouts)

    def _recover(self, image: np.ndarray, state: TargetState,
                 start_box: tuple[float, float, float, float], score: float):
        """The re-detection after a failure (:func:`mk_tracker.tracking.redetection.redetect`)."""
        return redetect(self, image, state, start_box, score)

    def _update_scale(self, search: SearchRegion, state: TargetState, weights: np.ndarray,
                      ev: KernelBatch, statistic: float = float("nan")) -> ScaleStep:
        """Eqs. (9)-(11), ``Delta s = beta r(h)``, ``s_t = s_{t-1}(1 + Delta s)``, with the
        checks of ``config.scale`` (:func:`mk_tracker.tracking.scale_estimation.scale_step`:
        with ``verify_scale_step`` the weighted cost (7) of the rescaled kernels decides).

        With a background weighting the step is taken with the *plain* models (one more
        evaluation at the located kernels): the weighted model's density (1) leaves out the
        colours the person shares with the background, so ``r(h)`` of (9) measures the
        extent of the target-specific colours, not of the person, and the box shrank onto
        them (generator persons: success AUC 0.65-0.71 against 0.84-0.89 with the plain
        models' step; docs/benchmark_single_target.md, "Findings")."""
        bg = state.background
        if bg is None:
            return scale_step(self._evaluate, search, state, weights, ev, self.config, statistic)
        weighted = state.models
        state.models = bg.plain
        try:
            plain_ev = self._evaluate(search, state.half_axes, state.centres, bg.plain)
            return scale_step(self._evaluate, search, state, weights, plain_ev, self.config,
                              statistic)
        finally:
            state.models = weighted

    def _lost(self, state: TargetState, x: np.ndarray, axes: np.ndarray, reason: str,
              sims: np.ndarray | None = None, weights: np.ndarray | None = None
              ) -> RefinementResult:
        n_k = state.num_kernels
        sims = np.zeros(n_k) if sims is None else sims
        state.lost = True
        state.similarity = float(sims.mean())
        box = kernels_bounding_box(x, axes)
        return RefinementResult(box=box, center=(box[0] + box[2] / 2, box[1] + box[3] / 2),
                                similarity=float(sims.mean()), kernel_similarities=sims,
                                weights=np.ones(n_k) if weights is None else weights,
                                kernel_centres=x.copy(), kernel_axes=axes.copy(),
                                iterations=0, lost=True, reason=reason, scale=state.scale)

    def peak_contrast(self, image_bgr: np.ndarray, state: TargetState,
                      result: RefinementResult, distance: float = 1.0) -> float:
        """Mean over kernels of the contrast of ``result``'s located layout to a ring of
        copies moved ``distance`` box sizes (:mod:`~mk_tracker.tracking.peak_contrast`): ~1
        for a peak that stands out from its surroundings whatever its absolute level (5),
        ~0 on a flat neighbourhood.  0 for a lost result or when the ring cannot be read."""
        if result.lost or len(result.kernel_similarities) != state.num_kernels:
            return 0.0
        rho = np.clip(np.asarray(result.kernel_similarities, dtype=np.float64), 1e-300, 1.0)
        contrasts = peak_contrasts(self, _checked_image(image_bgr), state,
                                   np.asarray(result.kernel_centres, dtype=np.float64),
                                   -np.log(rho), distance)
        return float(np.mean(contrasts))

    def appearance_similarity(self, image_bgr: np.ndarray, state: TargetState, box: BoxLike
                              ) -> float:
        """Mean over kernels of ``exp(-J_i)`` for the state's layout placed in ``box``.

        In [0, 1]; 0 when the box is outside the image or its pixels are NaN.  Only the
        pixels of ``box`` are read; the state is not changed.  Raises
        :class:`TrackingInputError` for a non-finite or zero-area box or a bad image.
        """
        image = _checked_image(image_bgr)
        try:
            b = tuple(float(v) for v in as_box(box))
        except InvalidBoxError as exc:
            raise TrackingInputError(str(exc)) from exc
        height, width = image.shape[:2]
        region = _region(b, 0.0, width, height)
        if region is None:
            return 0.0
        centres, axes = kernel_layout(b, state.num_kernels)
        stride = self._stride(axes)
        search = self._search_region(image, region, stride)
        if search is None:
            return 0.0
        sims = self.gate_similarities(self._evaluate(search, axes, centres, state.models),
                                      state)
        return float(np.clip(np.mean(sims), 0.0, 1.0))


def _weighted_cost(weights: np.ndarray, costs: np.ndarray) -> float:
    """``J = sum_i W_i J_i`` of (7); a kernel without pixels (infinite cost) adds nothing."""
    return float(np.sum(weights * np.where(np.isfinite(costs), costs, 0.0)))
