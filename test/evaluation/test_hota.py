"""HOTA (Luiten et al. 2021) on cases small enough to compute by hand from the paper's
definitions: DetA = TP / (TP + FN + FP), AssA = mean over TPs of the Jaccard index of the
matched trajectories, HOTA_alpha = sqrt(DetA * AssA), averaged over alpha = 0.05..0.95."""

from __future__ import annotations

import math

import pytest

from mk_tracker.evaluation.hota import ALPHAS, hota
from mk_tracker.evaluation.metrics import MotRow

BOX = (0.0, 0.0, 10.0, 10.0)


def test_alphas_are_the_papers_19_thresholds():
    assert len(ALPHAS) == 19
    assert ALPHAS[0] == pytest.approx(0.05) and ALPHAS[-1] == pytest.approx(0.95)


def test_perfect_tracking_scores_one_and_nothing_scores_zero():
    gt = [MotRow(f, 1, BOX) for f in range(1, 5)]
    assert hota(gt, gt) == pytest.approx({"hota": 1.0, "deta": 1.0, "assa": 1.0})
    assert hota(gt, []) == {"hota": 0.0, "deta": 0.0, "assa": 0.0}
    assert hota([], []) == {"hota": 0.0, "deta": 0.0, "assa": 0.0}


def test_an_id_switch_halves_association_not_detection():
    # one person in frames 1-4, followed by id 10 in frames 1-2 and id 20 in frames 3-4:
    # every box is a TP at every alpha (DetA 1); each TP's pair (1, 10) or (1, 20) has
    # 2 matches over 4 + 2 frames: A = 2 / (4 + 2 - 2) = 0.5, so AssA = 0.5 and
    # HOTA = sqrt(1 * 0.5)
    gt = [MotRow(f, 1, BOX) for f in range(1, 5)]
    hyp = [MotRow(f, 10 if f <= 2 else 20, BOX) for f in range(1, 5)]
    scores = hota(gt, hyp)
    assert scores["deta"] == pytest.approx(1.0)
    assert scores["assa"] == pytest.approx(0.5)
    assert scores["hota"] == pytest.approx(math.sqrt(0.5))


def test_localisation_counts_only_below_the_iou_of_the_match():
    # two frames; the tracker has one box in frame 1 at IoU 0.62 (10 x 6.2 inside 10 x 10)
    # and none in frame 2.  For alpha <= 0.60 (12 of the 19 thresholds): TP 1, FN 1,
    # FP 0 -> DetA 1/2; A = 1 / (2 + 1 - 1) = 1/2 -> HOTA_alpha = 1/2.  Above: TP 0,
    # FN 2, FP 1 -> 0.  Means: HOTA = DetA = AssA = 12 * 0.5 / 19.
    gt = [MotRow(1, 1, BOX), MotRow(2, 1, BOX)]
    hyp = [MotRow(1, 7, (0.0, 0.0, 10.0, 6.2))]
    scores = hota(gt, hyp)
    assert scores["hota"] == pytest.approx(6.0 / 19.0)
    assert scores["deta"] == pytest.approx(6.0 / 19.0)
    assert scores["assa"] == pytest.approx(6.0 / 19.0)


def test_matching_prefers_the_track_that_follows_the_person_all_along():
    # person 1 in frames 1-3, tracked by id 5 all along; in frame 2 a second tracker box,
    # id 6, lies exactly on the person as well.  Id 5's trajectory overlaps the person's
    # far more (global alignment), so frame 2 matches id 5 (AssA 1) and id 6 is a FP:
    # DetA = 3 / (3 + 0 + 1) = 0.75, HOTA = sqrt(0.75)
    gt = [MotRow(f, 1, BOX) for f in (1, 2, 3)]
    # (id 6 comes first in frame 2: an IoU tie alone would pick it)
    hyp = [MotRow(2, 6, BOX)] + [MotRow(f, 5, BOX) for f in (1, 2, 3)]
    scores = hota(gt, hyp)
    assert scores["assa"] == pytest.approx(1.0)
    assert scores["deta"] == pytest.approx(0.75)
    assert scores["hota"] == pytest.approx(math.sqrt(0.75))
