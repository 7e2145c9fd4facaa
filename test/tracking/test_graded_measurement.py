"""The graded measurement of a hand-started track (``manual_track.graded_measurement``,
mk_tracker.tracking.graded_measurement): a search result below ``occlusion_similarity`` and
at least ``graded_measurement_floor`` corrects the Kalman filter with an inflated std."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mk_tracker.parameters import updated
from mk_tracker.tracking.graded_measurement import graded_noise_scale, within_validation_gate
from mk_tracker.tracking.manual_track import ManualTrackConfig
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker, MultiObjectTrackerConfig

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0
STEP = 4.0          # px per frame


def test_noise_scale_is_the_likelihood_ratio_to_a_match_at_the_level():
    # (level / s) ** (lambda / 2): exp(-lambda J) with J = -ln s, as information
    assert graded_noise_scale(0.2, 0.4, 0.1, 5.0) == pytest.approx(2.0 ** 2.5)
    assert graded_noise_scale(0.3, 0.4, 0.1, 20.0) == pytest.approx((4.0 / 3.0) ** 10)
    assert graded_noise_scale(0.3, 0.4, 0.1, 0.0) == pytest.approx(1.0)
    scales = [graded_noise_scale(s, 0.4, 0.1, 5.0) for s in (0.39, 0.3, 0.2, 0.1)]
    assert scales == sorted(scales) and scales[0] > 1.0


@pytest.mark.parametrize("s", [0.4, 0.9, 0.099, 0.0, -0.1, math.nan, math.inf])
def test_no_graded_measurement_at_or_above_the_level_below_the_floor_or_not_finite(s):
    assert graded_noise_scale(s, 0.4, 0.1, 5.0) is None


def test_validation_gate_is_the_squared_mahalanobis_distance():
    cov = np.diag([4.0, 9.0])
    # d2 = 4^2 / 4 + 0 = 4; 6^2 / 9 = 4; (2, 3) gives 1 + 1 = 2
    assert within_validation_gate((4.0, 0.0), cov, 4.0)
    assert not within_validation_gate((4.0, 0.0), cov, 3.99)
    assert within_validation_gate((0.0, 6.0), cov, 4.0)
    assert within_validation_gate((2.0, 3.0), cov, 2.0)
    assert not within_validation_gate((2.0, 3.0), cov, 1.99)
    # 0 = no gate; a singular or non-finite covariance or innovation fails a gate
    assert within_validation_gate((1e6, 1e6), cov, 0.0)
    assert not within_validation_gate((1.0, 0.0), np.zeros((2, 2)), 9.21)
    assert not within_validation_gate((math.nan, 0.0), cov, 9.21)


class WalkerRefiner:
    """A 40x80 person walking right at STEP px per frame, found exactly by every search;
    kernel similarities 0.9 up to frame ``dim_from`` and ``dim`` after it."""

    def __init__(self, dim_from, dim):
        self.dim_from, self.dim, self.frame = dim_from, dim, 0

    def start(self, image, box):
        return "target"

    def refine(self, image, state, predicted_center=None):
        rho = np.full(2, 0.9 if self.frame < self.dim_from else self.dim)
        return type("R", (), {"box": (200.0 + STEP * self.frame, 100.0, 40.0, 80.0),
                              "similarity": float(rho.mean()), "kernel_similarities": rho,
                              "weights": np.ones(2), "lost": False})()

    def appearance_similarity(self, image, state, box):
        return 0.0


def _run(dim, frames=80, dim_from=5, **manual):
    base = updated(MultiObjectTrackerConfig(), {"lifecycle.min_hits": 1})
    cfg = dataclasses.replace(base, manual_track=ManualTrackConfig(
        occlusion_similarity=0.4, visibility_statistic="weighted", **manual))
    ref = WalkerRefiner(dim_from, dim)
    trk = MultiObjectTracker(cfg, refiner=ref)
    trk.start_track(IMG, 0.0, (200, 100, 40, 80))
    out = []
    for k in range(1, frames):
        ref.frame = k
        out.append(trk.step(IMG, k * DT).tracks[0])
    return out, trk


def test_off_by_default():
    assert ManualTrackConfig().graded_measurement is False


def test_a_walker_scored_below_the_level_is_followed_by_graded_measurements():
    # seen in frames 1-4 only (a velocity learnt in a few frames), then every search is on
    # her but scores 0.3: accept/reject coasts and holds the box; graded follows her
    truth_x = 200.0 + STEP * 79
    off, trk_off = _run(0.3)
    on, trk_on = _run(0.3, graded_measurement=True, graded_measurement_floor=0.2)
    assert all(t.state == "occluded" for t in off[5:] + on[5:])   # unseen either way
    assert abs(on[-1].box[0] - truth_x) < 10.0
    assert abs(off[-1].box[0] - truth_x) > 3.0 * abs(on[-1].box[0] - truth_x)
    assert trk_off.tracks[0].held and not trk_on.tracks[0].held


def test_below_the_floor_the_result_is_rejected_as_before():
    off, _ = _run(0.15, frames=40)
    on, _ = _run(0.15, frames=40, graded_measurement=True, graded_measurement_floor=0.2)
    assert [t.box for t in on] == [t.box for t in off]


def test_a_sharper_likelihood_trusts_a_poor_match_less():
    # seen for 20 frames, then scored 0.25 from frame 20 on: the graded measurements inform
    # the filter less with lambda 20 than with lambda 5 (a larger position variance), and
    # both more than coasting
    var = {}
    for lam in (5.0, 20.0, None):
        manual = {} if lam is None else dict(graded_measurement=True,
                                             graded_measurement_floor=0.2,
                                             graded_likelihood_sharpness=lam)
        _, trk = _run(0.25, frames=26, dim_from=20, max_coast_position_std=0.0, **manual)
        var[lam] = float(trk.tracks[0].kf.covariance[0, 0])
    assert var[5.0] < var[20.0] < var[None]


class LookAlikeRefiner(WalkerRefiner):
    """A 40x80 person standing at x 200, found exactly (0.9) up to frame ``dim_from``; after
    it every search scores ``dim`` and ends ``jump`` px to her right (towards a passer-by)."""

    def __init__(self, dim_from, dim, jump):
        super().__init__(dim_from, dim)
        self.jump = jump

    def refine(self, image, state, predicted_center=None):
        late = self.frame >= self.dim_from
        rho = np.full(2, self.dim if late else 0.9)
        return type("R", (), {"box": (200.0 + (self.jump if late else 0.0), 100.0, 40.0, 80.0),
                              "similarity": float(rho.mean()), "kernel_similarities": rho,
                              "weights": np.ones(2), "lost": False})()


def _stand(jump, frames=30, **manual):
    base = updated(MultiObjectTrackerConfig(), {"lifecycle.min_hits": 1})
    cfg = dataclasses.replace(base, manual_track=ManualTrackConfig(
        occlusion_similarity=0.4, visibility_statistic="weighted", graded_measurement=True,
        graded_measurement_floor=0.2, max_coast_position_std=0.0, **manual))
    ref = LookAlikeRefiner(20, 0.3, jump)
    trk = MultiObjectTracker(cfg, refiner=ref)
    trk.start_track(IMG, 0.0, (200, 100, 40, 80))
    for k in range(1, frames):
        ref.frame = k
        trk.step(IMG, k * DT)
    return float(trk.tracks[0].box[0])


def test_the_gate_rejects_a_poor_match_far_from_a_confident_prediction():
    # seen standing for 20 frames (a tight prediction), then every search scores 0.3 and
    # ends 60 px (1.5 box widths) to her right: ungated the graded measurements pull the box
    # onto the look-alike; gated at the 99% quantile they are rejected and the box stays
    assert _stand(60.0) > 200.0 + 30.0
    assert abs(_stand(60.0, graded_validation_gate=9.21) - 200.0) < 2.0


def test_the_gate_keeps_a_poor_match_near_the_prediction():
    # the same searches 1 px off: inside the gate, used exactly as without it
    assert _stand(1.0, graded_validation_gate=9.21) == pytest.approx(_stand(1.0))
    assert _stand(1.0) > 200.5


def test_a_gated_walker_scored_below_the_level_is_still_followed():
    on, _ = _run(0.3, graded_measurement=True, graded_measurement_floor=0.2,
                 graded_validation_gate=9.21)
    assert abs(on[-1].box[0] - (200.0 + STEP * 79)) < 10.0
