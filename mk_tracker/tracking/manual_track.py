"""Tracks started by hand: their settings and the column re-centring of their search.

A track started by hand
(:meth:`mk_tracker.tracking.multi_object_tracker.MultiObjectTracker.start_track`) follows one
person with no detector to correct it: the single-target protocol of Chu, Hwang,
Pai & Lan (IEEE TMM 2013), Sec. IV-B, in which the multiple-kernel search from the Kalman
prediction (Sec. IV-D; the projected-gradient iteration of Algorithm 1 with the step (5)/(8))
is the only measurement.  :class:`ManualTrackConfig` holds the settings such tracks use
instead of those of tracks born from detections, and :func:`manual_track_kalman`,
:func:`manual_track_lifecycle` and :func:`manual_track_multi_kernel` build their Kalman,
lifecycle and multiple-kernel configurations.

Search (issue #16): a coarse-to-fine start around the Kalman prediction and a failure
re-search by colour back-projection (``multi_start_radius``, ``recovery_similarity``; the
mechanisms are in :mod:`mk_tracker.tracking.redetection`, called by
:meth:`~mk_tracker.tracking.multi_kernel.MultiKernelTracker.refine`, which these settings
switch on for tracks started by hand only).  Failure detection against a level learnt from
the track's history (``similarity_reference_rate``, ``failure_sigmas``,
``similarity_spread_prior``) and a re-detection window growing with the time lost
(``recovery_growth``, ``recovery_margin``) are there too, off by
default: they lost in the leave-one-clip-out protocol (docs/benchmark_single_target.md).

Column re-centring (``ManualTrackConfig.column_recentre``): a two-column layout (4-6 kernels,
Fig. 14b) has a stable wrong optimum with one column on the person and the other on
background; :func:`columns_cover` says whether both columns of a result see the target and
:func:`recentre_shift` how far to move the box towards the seeing column for a second search
(run by ``MultiObjectTracker._refine``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from mk_tracker.kalman import KalmanConfig
from mk_tracker.parameters import parameter
from mk_tracker.tracking.background_weighting import BACKGROUND_WEIGHTINGS
from mk_tracker.tracking.kernel_layouts import (COLUMN_SPACING, column_best, column_coverage,
                                                has_columns)
from mk_tracker.tracking.kernel_layouts import SUPPORTED_KERNEL_COUNTS
from mk_tracker.tracking.multi_kernel import VISIBILITY_STATISTICS
from mk_tracker.tracking.multi_kernel_config import MultiKernelConfig
from mk_tracker.tracking.redetection import LEARNT_MEASURES
from mk_tracker.tracking.track import LifecycleConfig

if TYPE_CHECKING:
    from mk_tracker.tracking.multi_object_tracker import MultiObjectTrackerConfig

__all__ = ["ManualTrackConfig", "manual_track_kalman", "manual_track_lifecycle",
           "manual_track_multi_kernel", "columns_cover", "recentre_shift"]


@dataclass(frozen=True)
class ManualTrackConfig:
    """Settings of tracks started by hand (:meth:`MultiObjectTracker.start_track`: the node's
    ``initial_box`` and ``~/start_track``, ``mk_tracker process --init-from-gt``).

    Such a track follows one person with no detector to correct it (the single-target
    protocol of Chu et al. 2013, Sec. IV-B), so the multiple-kernel refinement from the Kalman
    prediction (Sec. IV-D) is its only measurement.  The defaults for tracks born from
    detections were chosen for the multi-object benchmark, where a detection corrects the
    track every frame; here they fail (docs/benchmark_single_target.md, "Findings"):

    * a velocity prior of 50 px/s (``kalman.initial_velocity_var`` 2500) is far below the
      ~250 px/s at which the TUD-Campus people walk, so the filter has not learnt the speed
      when it first has to coast;
    * on real video a matching target scores 0.45-0.65 (plain mean), below the 0.6 of
      ``lifecycle.occlusion_similarity``, so the track coasts while in plain view;
    * with one kernel hidden (legs behind a wall) the plain mean halves although the other
      kernel places the target (hence the ``weighted`` visibility statistic);
    * the refinement's similarity was mapped to a measurement quality of ~0 (range
      0.5-0.95, times 0.5 without a detection), so the filter ignored its only measurement
      and drifted behind a walking person on its own velocity;
    * two stacked kernels give no left/right structure once the legs are hidden;
    * a two-column box can settle with one column on the person's half whose colours look
      like the other half and the other column on background, which the weighted
      visibility still calls visible (hence ``column_recentre``).
    * with no detector to come back with, such a track is never lost by coasting time, so a
      coasting prediction extrapolated the last velocity until the box left the image
      (hence ``max_coast_position_std``: once the predicted centre's std exceeds the
      search's reach the track holds its position, :meth:`Track.hold_if_uncertain`).

    Issue #16 (unseen walking-people clips, 7 fps, people entering at the image edge) added
    two searches around the paper's core, both in
    :meth:`~mk_tracker.tracking.multi_kernel.MultiKernelTracker.refine`: a coarse-to-fine
    start on a grid around the Kalman prediction (``multi_start_radius``) and a failure
    re-search with the target's colour back-projection, confirmed by the multiple-kernel
    similarity (``recovery_similarity``).  ``num_kernels``, ``multi_start_radius``,
    ``recovery_similarity``, ``max_coast_position_std`` and ``background_weighting`` (the
    corrected background-weighted histograms of Ning et al. 2012,
    :mod:`mk_tracker.tracking.background_weighting`) are the settings chosen by the
    leave-one-clip-out protocol of ``benchmarks/bench_single_target.py``
    (docs/benchmark_single_target.md); the others were set earlier (above).

    Every field replaces one field of the tracker's ``kalman`` / ``lifecycle`` /
    ``multi_kernel`` sections for these tracks only; the rest of those sections applies to
    them unchanged.  ``border_person_aspect`` and ``border_margin_px`` treat the image border
    as an occluder (:mod:`mk_tracker.tracking.image_border`, docs/image_border.md).
    """

    initial_velocity_var: float = parameter(
        4.0e4, "Initial variance of the velocity of a track started by hand, (px/s)^2 "
        "(replaces kalman.initial_velocity_var: a walking person may move at ~250 px/s)",
        minimum=1e-9, maximum=1e12)
    occlusion_similarity: float = parameter(
        0.4, "Visibility statistic below which a track started by hand is occluded "
        "(replaces lifecycle.occlusion_similarity)", minimum=0.0, maximum=1.0)
    visibility_statistic: str = parameter(
        "weighted", "Visibility statistic of a track started by hand: mean or weighted "
        "(replaces lifecycle.visibility_statistic)", choices=VISIBILITY_STATISTICS)
    refinement_similarity_range: tuple = parameter(
        (0.2, 0.8), "Visibility statistics (low, high) mapped linearly to match quality 0..1 "
        "for a track started by hand (replaces refinement_similarity_range: its refinement "
        "is its only measurement, and on real video a matching target scores 0.45-0.65)")
    undetected_quality_factor: float = parameter(
        1.0, "Factor on the refinement's quality of a track started by hand in frames "
        "without a detection (replaces undetected_quality_factor)", minimum=0.0, maximum=1.0)
    num_kernels: int = parameter(
        2, "Kernels of a track started by hand (replaces multi_kernel.num_kernels; 2 = upper "
        "and lower body, Fig. 4a, chosen by the leave-one-clip-out protocol of "
        "bench_single_target.py over 6 = 3 rows x 2 columns, Fig. 14b)",
        choices=SUPPORTED_KERNEL_COUNTS)
    scale_gate_statistic: str = parameter(
        "mean", "Scale gate statistic of a track started by hand (replaces "
        "multi_kernel.scale_gate_statistic; with 6 small kernels the minimum is almost never "
        "above the gate, so the scale would never follow)", choices=("mean", "min"))
    scale_similarity_gate: float = parameter(
        0.7, "Scale gate of a track started by hand (replaces "
        "multi_kernel.scale_similarity_gate)", minimum=0.0, maximum=1.0)
    column_recentre: bool = parameter(
        True, "When the search of a track started by hand sees the target with one kernel "
        "column only (the other below min_column_similarity), also search from the box "
        "moved 0.45 w towards the seeing column and keep that result if both its columns "
        "see the target (a two-column box locked half on the person, half on background)")
    min_column_similarity: float = parameter(
        0.2, "A kernel column of a track started by hand sees the target when one of its "
        "kernels has at least this similarity (column_coverage; 0.2 = the low end of "
        "refinement_similarity_range, no information; 0 = column_recentre never runs)",
        minimum=0.0, maximum=1.0)
    max_coast_position_std: float = parameter(
        1.0, "A coasting track started by hand stops extrapolating its velocity once the std "
        "of its predicted centre exceeds this many box widths: it holds that position (box "
        "still, reported velocity 0, state occluded) and keeps searching from it until the "
        "refinement sees the target again.  1 = the reach of the search (the start box "
        "grown by multi_kernel.search_margin 0.5 on each side spans 1 box width either side "
        "of the predicted centre); 0 = extrapolate until the box leaves the image",
        minimum=0.0, maximum=100.0)

    multi_start_radius: float = parameter(
        0.5, "Coarse-to-fine search of a track started by hand (replaces "
        "multi_kernel.multi_start_radius): the kernel layout is also scored at a 3x3 grid of "
        "translations of the Kalman prediction out to this many box widths, and Algorithm 1 "
        "also runs from the best of them when the first search leaves the track unseen "
        "(below occlusion_similarity) and the grid point beats its result (a target that moved "
        "beyond the kernels' reach: low frame rate, fast walker, velocity not yet learnt); "
        "0 = from the prediction only",
        minimum=0.0, maximum=5.0)
    recovery_similarity: float = parameter(
        0.25, "Failure re-search of a track started by hand (replaces "
        "multi_kernel.recovery_similarity): when the search's weighted visibility is below "
        "this (chosen by the leave-one-clip-out protocol over 0.4), a region of "
        "recovery_margin box sizes around it is scanned with the target's "
        "colour back-projection, the layout is evaluated at its peaks and Algorithm 1 runs "
        "from the best one, kept if the multiple-kernel similarity confirms it; 0 = never",
        minimum=0.0, maximum=1.0)

    similarity_reference_rate: float = parameter(
        0.0, "Failure detection of a track started by hand against its own history (replaces "
        "multi_kernel.similarity_reference_rate): each kernel's similarity is its "
        "learnt_measure (-J_i or B_i) against the mean and spread learnt at this rate over "
        "the frames the track was seen, so occlusion_similarity, recovery_similarity and the "
        "measurement quality compare with what this target has scored so far "
        "(mk_tracker.tracking.redetection); 0 = the absolute exp(-J_i)",
        minimum=0.0, maximum=1.0)
    learnt_measure: str = parameter(
        "kl", "What the learnt level of a track started by hand is learnt on "
        "(replaces multi_kernel.learnt_measure): bhattacharyya or kl", choices=LEARNT_MEASURES)
    failure_sigmas: float = parameter(
        4.0, "Learnt spreads below its learnt mean at which a kernel's similarity reaches 0, "
        "for a track started by hand (replaces multi_kernel.failure_sigmas)",
        minimum=0.1, maximum=20.0)
    similarity_spread_prior: float = parameter(
        0.5, "Spread of the learnt measure assumed before anything was learnt, for a track "
        "started by hand (replaces multi_kernel.similarity_spread_prior: on real video the "
        "first frames after the start drift from the model by pose and noise)",
        minimum=0.0, maximum=10.0)
    recovery_margin: float = parameter(
        2.0, "Re-detection window of a track started by hand in its first failed frame, box "
        "sizes on every side of the start box (replaces multi_kernel.recovery_margin)",
        minimum=0.1, maximum=100.0)
    recovery_growth: float = parameter(
        0.0, "Re-detection window growth of a track started by hand (replaces "
        "multi_kernel.recovery_growth): box sizes added on every side of the scan per "
        "earlier frame of the same failure", minimum=0.0, maximum=100.0)

    background_weighting: str = parameter(
        "cbwh", "Background weighting of the kernel models of a track started by hand "
        "(replaces multi_kernel.background_weighting): cbwh, Ning et al.'s corrected "
        "background-weighted histogram (colours frequent in a ring around the box count "
        "less in the model, mk_tracker.tracking.background_weighting; chosen by the "
        "leave-one-clip-out protocol of bench_single_target.py over none, the plain "
        "models: a look-alike passer-by no longer takes the track), or none",
        choices=BACKGROUND_WEIGHTINGS)

    border_person_aspect: float = parameter(
        0.41, "The image border as an occluder (mk_tracker.tracking.image_border; not in the "
        "paper): a first box of a track started by hand that touches the left or right "
        "image border (within border_margin_px) with width / height below this is the "
        "visible part of a person partly outside the image; the kernels are laid out on "
        "the whole person (the box extended past the border to this aspect), each kernel's "
        "model is completed as it comes into view, the reported box of every track started "
        "by hand is clipped to the image and it ends when its box leaves the image.  0.41 "
        "= the standard pedestrian box aspect of the Caltech pedestrian benchmark (Dollar "
        "et al. 2012); 0 = off (the kernels are laid "
        "out on the part inside the image)", minimum=0.0, maximum=2.0)
    border_margin_px: float = parameter(
        2.0, "A box within this many pixels of the left or right image border touches it "
        "(border_person_aspect)", minimum=0.0, maximum=100.0)


def manual_track_kalman(config: "MultiObjectTrackerConfig") -> KalmanConfig:
    """The Kalman settings of a track started by hand."""
    m = config.manual_track
    return replace(config.kalman, initial_velocity_var=m.initial_velocity_var)


def manual_track_lifecycle(config: "MultiObjectTrackerConfig") -> LifecycleConfig:
    """The lifecycle settings of a track started by hand."""
    m = config.manual_track
    return replace(config.lifecycle, occlusion_similarity=m.occlusion_similarity,
                   visibility_statistic=m.visibility_statistic)


def manual_track_multi_kernel(config: "MultiObjectTrackerConfig") -> MultiKernelConfig:
    """The multiple-kernel settings of a track started by hand."""
    m = config.manual_track
    return replace(config.multi_kernel, num_kernels=m.num_kernels,
                   scale_gate_statistic=m.scale_gate_statistic,
                   scale_similarity_gate=m.scale_similarity_gate,
                   multi_start_radius=m.multi_start_radius,
                   # the grid is tried when the search from the prediction leaves the
                   # track unseen (the occlusion test of the lifecycle)
                   multi_start_similarity=(m.occlusion_similarity if m.multi_start_radius > 0
                                           else config.multi_kernel.multi_start_similarity),
                   recovery_similarity=m.recovery_similarity,
                   recovery_growth=m.recovery_growth,
                   recovery_margin=m.recovery_margin,
                   similarity_reference_rate=m.similarity_reference_rate,
                   failure_sigmas=m.failure_sigmas,
                   learnt_measure=m.learnt_measure,
                   similarity_spread_prior=m.similarity_spread_prior,
                   background_weighting=m.background_weighting)


def columns_cover(res: Any, floor: float) -> bool:
    """Both kernel columns of a refinement result see the target: :func:`column_coverage` of
    its kernel similarities >= ``floor`` (``manual_track.min_column_similarity``; always true
    for ``floor <= 0``, layouts without columns and results without kernel similarities)."""
    sims = getattr(res, "kernel_similarities", None)
    if floor <= 0.0 or sims is None:
        return True
    s = np.asarray(sims, dtype=np.float64).reshape(-1)
    return s.size not in SUPPORTED_KERNEL_COUNTS or column_coverage(s, s.size) >= floor


def recentre_shift(res: Any, box: np.ndarray) -> float:
    """x shift that puts the seeing kernel column of a one-column result where the
    other column was: a box whose left column lies on the person's right half (whose
    colours look alike) and whose right column lies on background is
    :data:`~mk_tracker.tracking.kernel_layouts.COLUMN_SPACING` ``w`` (0.45 w, the distance
    between the column centres) right of the person; 0 for layouts without columns."""
    n = np.asarray(res.kernel_similarities).size
    if not has_columns(n):
        return 0.0
    left, right = column_best(res.kernel_similarities, n)
    step = COLUMN_SPACING * float(box[2])
    return -step if right < left else step
