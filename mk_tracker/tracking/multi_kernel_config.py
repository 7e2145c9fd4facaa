"""Every constant of the multiple-kernel tracker (:mod:`mk_tracker.tracking.multi_kernel`).

:class:`MultiKernelConfig` holds them as one frozen dataclass whose fields are the ROS
parameters ``tracker.multi_kernel.*`` (with a description and a range each); the defaults
are the values of Chu, Hwang, Pai & Lan 2013, Sec. IV-A, where the paper gives one, and the
settings the paper does not have say so.  :func:`paper_config` is the paper's printed
setting, :func:`mean_shift_baseline_config` the single-kernel mean shift of Comaniciu,
Ramesh and Meer that the paper compares against.
"""

from __future__ import annotations

from dataclasses import dataclass

from mk_tracker.parameters import parameter
from mk_tracker.tracking.background_weighting import BACKGROUND_WEIGHTINGS
from mk_tracker.tracking.kernel_histograms import COLOUR_SPACES, PIXEL_WEIGHTINGS, PROFILES
from mk_tracker.tracking.kernel_layouts import SUPPORTED_KERNEL_COUNTS
from mk_tracker.tracking.redetection import LEARNT_MEASURES
from mk_tracker.tracking.scale_estimation import ScaleEstimationConfig

__all__ = ["MultiKernelConfig", "paper_config", "mean_shift_baseline_config"]


@dataclass(frozen=True)
class MultiKernelConfig:
    """Parameters of the multiple-kernel tracker; defaults are the paper's values (Sec. IV-A)."""

    num_kernels: int = parameter(
        2, "Kernels per target (1 = single-kernel mean shift; 2/4 Fig. 4; 5/6 Fig. 14)",
        choices=SUPPORTED_KERNEL_COUNTS)
    colour_space: str = parameter("hsv", "Colour space of the histograms (Sec. IV-A: HSV; "
                                  "grey: the luminance alone, grey_bins bins)",
                                  choices=COLOUR_SPACES)
    thermal_colour_space: str = parameter(
        "hsv", "Colour space used instead of colour_space when the tracked image is "
        "single-channel (mono8/mono16/16UC1/32FC1: thermal-only tracking; "
        "frame_processing.tracker_config_for_encoding)", choices=COLOUR_SPACES)
    grey_bins: int = parameter(4, "Histogram bins of the grey colour space (luminance "
                               "L goes to bin L * grey_bins >> 8)", minimum=1, maximum=256)
    hue_bins: int = parameter(16, "Histogram bins along hue (or blue for bgr)",
                              minimum=1, maximum=180)
    saturation_bins: int = parameter(8, "Histogram bins along saturation (or green)",
                                     minimum=1, maximum=256)
    value_bins: int = parameter(4, "Histogram bins along value (or red)",
                                minimum=1, maximum=256)
    profile: str = parameter("roof", "Kernel profile k: roof (piecewise linear, g constant, "
                             "Sec. V-A) or truncated gaussian", choices=PROFILES)
    pixel_weighting: str = parameter(
        "kl", "Pixel weights of the mean shift: q/p for the K-L cost (Appendix C) or "
        "sqrt(q/p) (Bhattacharyya, Comaniciu et al.)", choices=PIXEL_WEIGHTINGS)
    histogram_epsilon: float = parameter(
        0.01, "Mass eps mixed uniformly into candidate histograms, (1-eps)p + eps/m, so the "
        "K-L cost stays finite", minimum=1e-9, maximum=0.5)
    max_iterations: int = parameter(5, "T, the iteration limit of Algorithm 1",
                                    minimum=1, maximum=100)
    epsilon_j_factor: float = parameter(
        0.0, "eps_J = factor * N: Algorithm 1 stops when J < eps_J and |C| < eps_C (paper: "
        "0.7; with these K-L values that stops before the first step, see module docs)",
        minimum=0.0, maximum=100.0)
    constraint_tolerance_px: float = parameter(
        1.0, "Pixel tolerance e giving each constraint's eps_C = ((L+e)^2-L^2)/(L^2+1)",
        minimum=0.0, maximum=100.0)
    alpha: float = parameter(1.0, "Step size alpha of (5)/(8)", minimum=0.0, maximum=10.0)
    use_projected_gradient: bool = parameter(
        True, "Keep C_x(C_x^T C_x)^+ C_x^T in dx_A; False is the 'without projected "
        "gradient' ablation of Table II")
    adaptive_weights: bool = parameter(
        True, "Weights W_i proportional to sim_i, summing to N (7)-(8); False: W = I")
    scale_update: bool = parameter(True, "Update the scale with (9)-(11)")
    beta: float = parameter(9e3, "beta of (10), gain of the scale change", minimum=0.0)
    similarity_gate: float = parameter(
        0.3, "Model and scale are updated only when the mean kernel similarity exceeds this",
        minimum=0.0, maximum=1.0)
    scale_gate_statistic: str = parameter(
        "min", "Kernel similarity statistic compared with scale_similarity_gate before a scale "
        "update: min (default: no update while any kernel is occluded) or mean (paper)",
        choices=("mean", "min"))
    scale_similarity_gate: float = parameter(
        0.8, "The scale is updated only when the statistic above exceeds this (paper: the "
        "mean above 0.3, which let occluded kernels inflate or shrink the box)",
        minimum=0.0, maximum=1.0)
    verify_scale_step: bool = parameter(
        True, "Keep a scale step of (10)-(11) only if it does not raise the cost (7) (not in "
        "the paper; rejects steps biased by occluded kernel rims)")
    max_scale_change: float = parameter(
        0.05, "Largest |Delta s| per frame (not in the paper; bounds a noisy (10))",
        minimum=0.0, maximum=1.0)
    scale: ScaleEstimationConfig = parameter(
        ScaleEstimationConfig(), "How the scale step is proposed and checked "
        "(mk_tracker.tracking.scale_estimation)")
    min_scale: float = parameter(0.25, "Smallest scale relative to the first box",
                                 minimum=0.01, maximum=1.0)
    max_scale: float = parameter(4.0, "Largest scale relative to the first box",
                                 minimum=1.0, maximum=100.0)
    model_update_rate: float = parameter(
        0.0, "Blend rate of a kernel's model towards its current candidate when above the "
        "gate (the paper gives no rate; 0, the default, keeps the first frame's models: "
        "0.02 and 0.1 drifted onto the background in docs/benchmark_single_target.md)",
        minimum=0.0, maximum=1.0)
    lost_similarity: float = parameter(
        0.1, "A result whose mean kernel similarity is below this is reported lost",
        minimum=0.0, maximum=1.0)
    search_margin: float = parameter(
        0.5, "Search region = box at the start position grown by this fraction of its size "
        "on every side; no pixel outside it is read", minimum=0.05, maximum=5.0)
    min_step_px: float = parameter(
        0.25, "Stop iterating when no kernel moves more than this (Comaniciu's epsilon; "
        "0 disables)", minimum=0.0, maximum=10.0)
    max_step_fraction: float = parameter(
        1.0, "Largest move of a kernel per iteration, as a fraction of its half-axes",
        minimum=0.01, maximum=10.0)
    max_kernel_pixels: int = parameter(
        1500, "Kernels covering more pixels are sampled on a regular grid of stride "
        "ceil(sqrt(area / this)) (speed; not in the paper)", minimum=50, maximum=10**7)
    rank_tolerance: float = parameter(
        1e-6, "Singular values of the scaled C_x below this times the largest are dropped",
        minimum=1e-15, maximum=0.1)
    multi_start_radius: float = parameter(
        0.0, "Coarse-to-fine start (not in the paper): the layout is scored (mean kernel "
        "similarity) at a (2k+1)^2 grid of translations of the predicted start, k = "
        "multi_start_steps, out to this many box widths in x and y, and Algorithm 1 runs from "
        "the prediction and from the best grid point; the result with the higher mean "
        "similarity is kept.  0 = start from the prediction only (Sec. IV-D)",
        minimum=0.0, maximum=5.0)
    multi_start_similarity: float = parameter(
        1.01, "The coarse-to-fine start runs only when the weighted visibility sum_i W_i "
        "rho_i / N ((7)-(8)) of the search from the prediction is below this, i.e. when the "
        "local search failed; 1.01 (above any visibility) = in every frame",
        minimum=0.0, maximum=1.01)
    multi_start_steps: int = parameter(
        1, "k of multi_start_radius: grid points on each side of the prediction",
        minimum=1, maximum=5)
    recovery_similarity: float = parameter(
        0.0, "Failure re-search (not in the paper): when a result's weighted visibility "
        "sum_i W_i rho_i / N ((7)-(8)) is below this, the region around the start box is "
        "scanned with the back-projection of the target's colour model, the layout is "
        "evaluated at the scan's peaks and Algorithm 1 runs from the best one; its result "
        "replaces the first one when its weighted visibility reaches this value and its mean "
        "similarity is higher.  0 = never",
        minimum=0.0, maximum=1.0)
    recovery_margin: float = parameter(
        2.0, "Scan region of the failure re-search: the start box grown by this many box "
        "sizes on every side, clipped to the image", minimum=0.1, maximum=100.0)
    recovery_growth: float = parameter(
        0.0, "The re-search window grows by this many box sizes on every side for each "
        "earlier frame of the same failure (so a long failure scans the whole frame); "
        "0 = a fixed window of recovery_margin", minimum=0.0, maximum=100.0)
    similarity_reference_rate: float = parameter(
        0.0, "Failure detection against the track's own history (not in the paper; "
        "mk_tracker.tracking.redetection): > 0 reports each kernel's similarity as its "
        "learnt_measure v_i against the mean m_i and spread sd_i learnt at this rate over "
        "the frames the track was seen, clip(1 - (m_i - v_i) / (k sd_i), 0, 1), and every "
        "test (lost, coarse-to-fine start, re-search) uses it; 0 = the absolute exp(-J_i)",
        minimum=0.0, maximum=1.0)
    learnt_measure: str = parameter(
        "kl", "What similarity_reference_rate learns the level on: each kernel's negated K-L "
        "cost -J_i (Appendix C) or its Bhattacharyya coefficient B_i",
        choices=LEARNT_MEASURES)
    failure_sigmas: float = parameter(
        4.0, "k of similarity_reference_rate: a kernel's similarity is 0 at k learnt spreads "
        "below its learnt mean", minimum=0.1, maximum=20.0)
    similarity_spread_prior: float = parameter(
        0.5, "Spread of the learnt measure assumed before any frame was learnt (the first "
        "frames after the start drift from the model by pose and noise; 0 = only the floor)",
        minimum=0.0, maximum=10.0)
    similarity_spread_floor: float = parameter(
        0.05, "Smallest learnt spread sd_i of the learnt measure (a steady target would "
        "otherwise fail on any small change)", minimum=1e-3, maximum=1.0)
    recovery_candidates: int = parameter(
        3, "Back-projection peaks (at least one box apart) at which the failure re-search "
        "evaluates the kernel layout (Algorithm 1 then runs from the best)",
        minimum=1, maximum=20)
    border_model_gain: float = parameter(
        0.02, "A kernel of a target started past the image border completes its model when its "
        "in-image share grew by more than this (image_border.complete_models)",
        minimum=0.0, maximum=1.0)
    background_weighting: str = parameter(
        "none", "Target models weighted by how rare each colour is in a ring of background "
        "around the box (not in Chu et al.): none, or cbwh, the corrected background-weighted "
        "histogram of Ning et al. 2012 (v_u = min(o*/o_u, 1) on the model only; decisions "
        "use the cost above the first box's, mk_tracker.tracking.background_weighting)",
        choices=BACKGROUND_WEIGHTINGS)
    background_ring: float = parameter(
        0.5, "Background ring of cbwh: the box grown by this many box sizes on every side, "
        "minus the box (Ning et al.: three times the target's area, about 0.37)",
        minimum=0.05, maximum=5.0)
    background_weight_floor: float = parameter(
        0.25, "Smallest background weight v_u of cbwh (0 = Ning et al.'s weights, which lost "
        "to 0.25 in the leave-one-clip-out protocol of bench_single_target.py; 1 = no "
        "weighting)", minimum=0.0, maximum=1.0)
    background_update_similarity: float = parameter(
        0.5, "cbwh re-computes the ring histogram at the tracked box in a frame where the "
        "target is seen and replaces it when its Bhattacharyya coefficient with the old one "
        "is below this (the background changed enough, Ning et al.); 0 = first frame only",
        minimum=0.0, maximum=1.0)
    recovery_scan_cells: int = parameter(
        8, "Sampling of the back-projection scan: about this many samples across the box "
        "width (stride ceil(w / this) px)", minimum=2, maximum=64)

    @property
    def bins(self) -> tuple[int, int, int]:
        """Bins per channel of ``colour_space``: ``(1, 1, grey_bins)`` for grey."""
        if self.colour_space == "grey":
            return (1, 1, self.grey_bins)
        return (self.hue_bins, self.saturation_bins, self.value_bins)


def paper_config(**overrides) -> MultiKernelConfig:
    """Every constant as printed in Sec. IV-A: eps_J = 0.7 N, model and scale updated when the
    mean similarity exceeds 0.3 (the model replaced by the current candidate)."""
    base = dict(epsilon_j_factor=0.7, scale_gate_statistic="mean", scale_similarity_gate=0.3,
                model_update_rate=1.0)
    base.update(overrides)
    return MultiKernelConfig(**base)


def mean_shift_baseline_config(**overrides) -> MultiKernelConfig:
    """Single-kernel mean shift of Comaniciu, Ramesh and Meer (the paper's baseline [2]).

    One kernel, Bhattacharyya pixel weights ``sqrt(q/p)``, iterate until the step is below
    ``min_step_px`` (no cost threshold), no adaptive weights (meaningless with one kernel) and
    no scale update.
    """
    base = dict(num_kernels=1, pixel_weighting="bhattacharyya", epsilon_j_factor=0.0,
                max_iterations=20, adaptive_weights=False, scale_update=False)
    base.update(overrides)
    return MultiKernelConfig(**base)
