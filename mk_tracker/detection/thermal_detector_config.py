"""Every constant of the thermal detector (:mod:`mk_tracker.detection.thermal_detector`).

One frozen dataclass, :class:`ThermalDetectorConfig`, whose fields are ROS parameters of
``detector_node`` (``detector.*``, through :mod:`mk_tracker.ros.parameter_bridge`) with a
description and a range; the paper's symbol, where there is one, is in brackets (Schizas,
Maroulas & Ren 2018).  The settings that are not in the paper say so; why each default was
chosen is in docs/benchmark_thermal_detector.md and docs/benchmark_groups.md.
"""

from __future__ import annotations

from dataclasses import dataclass

from mk_tracker.detection.body_extent import BodyExtentConfig
from mk_tracker.detection.gain_compensation import GainConfig
from mk_tracker.detection.keep_apart import KeepApartConfig
from mk_tracker.detection.object_extent import ObjectExtentConfig
from mk_tracker.detection.person_cover import PersonCoverConfig
from mk_tracker.detection.still_people import StillPeopleConfig
from mk_tracker.kalman import KalmanConfig
from mk_tracker.parameters import parameter

__all__ = ["ThermalDetectorConfig"]


@dataclass(frozen=True)
class ThermalDetectorConfig:
    """Every constant of the detector (paper symbol in brackets)."""

    sigma2: float = parameter(0.01, "[sigma^2] RBF kernel variance (3.6) on the unit "
                              "intensity scale (Sec. 6: 0.01); noise_bandwidth widens it on "
                              "a noisy stream", minimum=1e-6, maximum=10.0)
    noise_bandwidth: float = parameter(
        3.0, "the kernel's bandwidth sigma of (3.6) is at least this many times the "
        "stream's temporal noise std, measured at each full-frame pass "
        "(mk_tracker.detection.stream_noise): a noisy stream is not one frame-sized object; "
        "sigma2 stays the bandwidth of quiet streams; 0 = sigma2 always",
        minimum=0.0, maximum=100.0)
    lam: float = parameter(0.15, "[lambda] sparsity weight of (3.7); a pixel whose kernel "
                           "variance is below 3/2 (lambda/2)^(2/3) can never start a support",
                           minimum=0.0, maximum=10.0)
    max_cycles: int = parameter(10, "[kappa] maximum coordinate-descent cycles (Alg. 1)",
                                minimum=1, maximum=1000)
    tol: float = parameter(1e-2, "[epsilon] stop when ||M^k - M^(k-1)|| <= epsilon (Alg. 1)",
                           minimum=0.0, maximum=1.0)
    columns: int = parameter(1, "number of columns of M per block (Sec. 3.3)", minimum=1,
                             maximum=8)
    block_size: int = parameter(4, "[rho] side of the divide-and-conquer blocks (5.1), px",
                                minimum=2, maximum=32)
    window_frames: int = parameter(4, "[F] frames of the sliding window in tracking mode",
                                   minimum=2, maximum=64)
    startup_frames: int = parameter(6, "[F_s] frames of a start-up/reconfiguration pass",
                                    minimum=2, maximum=64)
    reconfigure_period: int = parameter(25, "[T_c] frames between full-frame passes",
                                        minimum=1, maximum=100000)
    counts_fps: float = parameter(
        25.0, "frame rate at which window_frames, startup_frames, reconfigure_period and "
        "group_recheck_frames are counted: on a slower stream (rate measured from the "
        "stamps) they are converted to the same durations, windows at least 2 frames "
        "(a 9 Hz thermal camera); faster streams keep the counts; 0 = frames at any rate",
        minimum=0.0, maximum=1000.0)
    rate_window: int = parameter(25, "stamp differences whose median is the measured frame "
                                 "rate (counts_fps)", minimum=1, maximum=10000)
    merge_distance_sq: float = parameter(150.0, "[epsilon_d] K-means clusters whose centroids "
                                         "are closer than this (px^2) are merged (3.13)",
                                         minimum=0.0, maximum=1e8)
    link_gap: int = parameter(4, "support pixels closer than this (px) always belong to one "
                              "object (added to the merge rule (3.13); 0 = paper rule only)",
                              minimum=0, maximum=1000)
    max_objects: int = parameter(20, "[M_up] upper limit on the number of objects",
                                 minimum=1, maximum=1000)
    min_object_pixels: int = parameter(6, "objects with fewer support pixels are dropped",
                                       minimum=1, maximum=100000)
    window_margin: int = parameter(8, "extra pixels on each side of the (5.2) window",
                                   minimum=0, maximum=1000)
    max_missed: int = parameter(3, "tracking frames without support before an object is "
                                "dropped", minimum=0, maximum=10000)
    current_frame_refinement: bool = parameter(True, "report the object's footprint in the "
                                               "newest frame instead of the swept support")
    normalization: str = parameter("auto", "auto: mono8 / 255, other encodings by the robust "
                                   "range of each full-frame pass; fixed: range_min..range_max",
                                   choices=("auto", "fixed"))
    range_min: float = parameter(0.0, "raw value mapped to 0 (normalization=fixed)")
    range_max: float = parameter(255.0, "raw value mapped to 1 (normalization=fixed)")
    merge_by_footprint: bool = parameter(True, "merge clusters whose newest-frame footprints "
                                         "touch (needs current_frame_refinement)")
    drop_background_footprints: bool = parameter(
        True, "full-frame passes: drop an object whose newest-frame footprint is, by its "
        "mean, similar (kernel (3.6) >= 1/2) to the scene background (median of the "
        "non-support pixels) while the local background it was found against is not: "
        "plain background that only stands out against a large warm neighbour, e.g. the "
        "band a near person swept; not in the paper; needs current_frame_refinement")
    split_by_valleys: bool = parameter(False, "split a footprint where people touch, along "
                                       "the intensity valleys between peaks that each stand "
                                       "out of the valley by the kernel's similarity radius "
                                       "(3.6); in full-frame passes, and in tracking passes "
                                       "when an object's box grows (valley_grow_ratio); not "
                                       "in the paper; needs current_frame_refinement")
    valley_min_peak_fraction: float = parameter(0.4, "split_by_valleys: a peak whose core "
                                                "(pixels within half the similarity radius "
                                                "of its top) is smaller than this fraction "
                                                "of the footprint's largest core is part of "
                                                "a bigger object (a warm hand beside a "
                                                "head); a piece of the footprint with one "
                                                "peak needs this fraction of the pieces' "
                                                "area per peak", minimum=0.0, maximum=1.0)
    valley_columns: bool = parameter(
        False, "split_by_valleys: cut only between the columns of upright people: valley "
        "parts stacked in one column range (valley_column_overlap) are one person, "
        "neighbours are cut at the emptiest column of the footprint between them, and each "
        "keeps the footprint's whole rows in its columns, so a split never makes a head or "
        "a leg box (mk_tracker.detection.person_size.valley_columns; not in the paper; "
        "docs/benchmark_groups.md)")
    valley_column_overlap: float = parameter(
        0.5, "valley_columns: two valley parts whose column ranges share at least this "
        "fraction of the narrower range are stacked parts of one person", minimum=0.0,
        maximum=1.0)
    valley_grow_ratio: float = parameter(1.3, "split_by_valleys in tracking passes: an "
                                         "object whose box is wider or taller than this "
                                         "times its last box, or its box at the last "
                                         "full-frame pass, is split and keeps the part "
                                         "nearest its prediction", minimum=1.0, maximum=100.0)
    split_by_person_size: bool = parameter(
        False, "split a footprint wider than split_ratio expected person widths at its row "
        "into round(width / expected width) people, cut at the emptiest columns (the person "
        "height per row is learnt online from isolated detections, "
        "mk_tracker.detection.person_size); in full-frame passes; not in the paper; needs "
        "current_frame_refinement")
    person_aspect: float = parameter(0.27, "width / height of one upright person's "
                                     "footprint (split_by_person_size)", minimum=0.1,
                                     maximum=2.0)
    split_ratio: float = parameter(1.5, "split_by_person_size: a footprint wider than this "
                                   "many expected person widths is a group", minimum=1.0,
                                   maximum=10.0)
    min_part_fraction: float = parameter(
        0.6, "split_by_person_size: a part narrower than this fraction of the expected "
        "person width is not a person (a limb): the footprint is cut into one person fewer",
        minimum=0.0, maximum=1.0)
    min_part_height_fraction: float = parameter(
        0.0, "split_by_person_size: the split is kept only when every part is at least this "
        "fraction of the expected person height at its own bottom row, else the footprint "
        "stays whole (0: no check; not in the paper; docs/benchmark_groups.md)",
        minimum=0.0, maximum=1.0)
    group_recheck_frames: int = parameter(
        5, "split_by_person_size: when a tracking pass finds a footprint as wide as several "
        "people, the next full-frame pass (which splits it) runs this many frames after the "
        "last one instead of reconfigure_period", minimum=1, maximum=100000)
    split_clusters: bool = parameter(
        False, "full-frame passes: instead of link_gap and merge_by_footprint, group the "
        "K-means clusters (3.12)-(3.13) of touching people into persons by the learnt "
        "person size: trailing bands dropped, pieces of one band joined, the footprint "
        "shared by Voronoi cells, slivers joined to a neighbour "
        "(mk_tracker.detection.crowd_split); not in the paper; needs "
        "current_frame_refinement")
    trail_fraction: float = parameter(
        0.5, "split_clusters: a cluster with fewer than this fraction of its support "
        "pixels in its newest-frame footprint is where an object was (a trailing band), "
        "not a person", minimum=0.0, maximum=1.0)
    seed_width_ratio: float = parameter(
        1.6, "split_clusters: clusters are one person's pieces while the union of their "
        "support boxes is at most this many expected person widths wide", minimum=0.0,
        maximum=10.0)
    seed_height_ratio: float = parameter(
        1.2, "split_clusters: ... and at most this many expected person heights tall",
        minimum=0.0, maximum=10.0)
    sliver_fraction: float = parameter(
        0.5, "split_clusters: a part narrower than this fraction of the expected person "
        "width is a sliver, joined to a neighbour",
        minimum=0.0, maximum=1.0)
    sliver_height_fraction: float = parameter(
        0.5, "split_clusters: ... or lower than this fraction of the expected person "
        "height", minimum=0.0, maximum=1.0)
    sliver_overlap: float = parameter(
        0.5, "split_clusters: a part with more than this fraction of its box inside "
        "another part's box is joined to it as a sliver is (1: never)", minimum=0.0,
        maximum=1.0)
    motion_slack: bool = parameter(
        False, "split_clusters: the pieces' size limits grow by the distance the fastest "
        "known object inside them (Kalman velocity) moved during the full pass's window")
    cut_blobs_whole: bool = parameter(
        False, "split_clusters: a blob whose footprint search patches reach the image's "
        "bottom row (its people's feet may be cut off, so no size applies) stays one object")
    learn_aspect: bool = parameter(
        False, "split_clusters: the expected person width is the learnt height times the "
        "mean width / height of the same samples (forgotten as the heights are) instead "
        "of person_aspect")
    keep_objects_apart: bool = parameter(
        True, "split_clusters: at a reconfiguration, two clusters that each hold the "
        "Kalman prediction of a different object of the last pass are never one person")
    size_memory: float = parameter(500.0, "split_by_person_size: person-size samples "
                                   "remembered (exponential forgetting)", minimum=1.0,
                                   maximum=1e6)
    size_max_residual: float = parameter(
        100.0, "the learnt person size (and split_clusters) is used only while the height "
        "fit's residual std / mean height is at most this (person_size; not in the paper; "
        "100: no check, docs/benchmark_groups.md)", minimum=0.0, maximum=100.0)
    size_min_samples: float = parameter(2.5, "... and its samples weigh at least this",
                                        minimum=2.5, maximum=1e6)
    min_valid_fraction: float = parameter(0.5, "frames with fewer finite pixels are skipped",
                                          minimum=0.0, maximum=1.0)
    kalman: KalmanConfig = parameter(KalmanConfig(), "per-object Kalman filter (Sec. 4)")
    body_extent: BodyExtentConfig = parameter(
        BodyExtentConfig(), "whole-body boxes (mk_tracker.detection.body_extent)")
    gain: GainConfig = parameter(
        GainConfig(), "compensation of the camera's automatic gain control "
        "(mk_tracker.detection.gain_compensation)")
    extent: ObjectExtentConfig = parameter(
        ObjectExtentConfig(), "bound on an object's width: groups re-split or not carried "
        "(mk_tracker.detection.object_extent)")
    keep_apart: KeepApartConfig = parameter(
        KeepApartConfig(), "objects followed apart before they met are kept apart at "
        "full-frame passes (mk_tracker.detection.keep_apart)")
    person_cover: PersonCoverConfig = parameter(
        PersonCoverConfig(), "a detection as large as several people replaced by "
        "whole-person boxes (mk_tracker.detection.person_cover)")
    still_people: StillPeopleConfig = parameter(
        StillPeopleConfig(), "warm person-sized regions that stay in place are detected "
        "(mk_tracker.detection.still_people)")
