"""Scoring: CLEAR-MOT/identity metrics on hand-built sequences, MOT files, OTB metrics, CLI."""

import argparse
import re

import numpy as np
import pytest

from mk_tracker.evaluation import metrics as ev
from mk_tracker.evaluation import eval_command as evaluation_cli


def rows(spec):
    """spec: list of (frame, id, x) with boxes (x, 0, 10, 10)."""
    return [ev.MotRow(f, i, (float(x), 0.0, 10.0, 10.0)) for f, i, x in spec]


GT = rows([(f, 1, 0) for f in range(1, 11)] + [(f, 2, 100) for f in range(1, 11)])


def test_perfect_result():
    m = ev.mot_metrics(GT, GT)
    assert m["mota"] == pytest.approx(1.0)
    assert m["idf1"] == pytest.approx(1.0)
    assert m["num_switches"] == 0
    assert m["mostly_tracked"] == 2 and m["mostly_lost"] == 0


def test_identity_swap_counts_one_switch_per_target():
    hyp = rows([(f, 1 if f <= 5 else 2, 0) for f in range(1, 11)]
               + [(f, 2 if f <= 5 else 1, 100) for f in range(1, 11)])
    m = ev.mot_metrics(GT, hyp)
    assert m["num_switches"] == 2
    assert m["mota"] == pytest.approx(1.0 - 2 / 20)
    assert m["idf1"] == pytest.approx(0.5)


def test_misses_false_positives_and_mostly_lost():
    hyp = rows([(f, 7, 0) for f in range(1, 11)] + [(3, 9, 300)])
    m = ev.mot_metrics(GT, hyp)
    assert m["num_misses"] == 10
    assert m["num_false_positives"] == 1
    assert m["mostly_lost"] == 1 and m["mostly_tracked"] == 1
    assert m["mota"] == pytest.approx(1.0 - 11 / 20)


def test_iou_threshold_decides_a_match():
    shifted = [ev.MotRow(r.frame, r.id, (r.box[0] + 5.0, 0.0, 10.0, 10.0)) for r in GT]
    # IoU of boxes shifted by half their width = 50 / 150 = 1/3
    assert ev.mot_metrics(GT, shifted)["num_misses"] == 20
    m = ev.mot_metrics(GT, shifted, iou_threshold=0.3)
    assert m["num_misses"] == 0
    assert m["motp"] == pytest.approx(2.0 / 3.0)


def test_duplicate_hypothesis_id_is_an_error():
    with pytest.raises(ev.EvaluationError):
        ev.mot_accumulator(GT, rows([(1, 1, 0), (1, 1, 100)]))


def test_mot_file_round_trip_and_gt_consider_flag(tmp_path):
    path = tmp_path / "res.txt"
    n = ev.write_mot_file(path, [ev.MotRow(2, 5, (1.5, 2.25, 10.0, 20.0), 0.75),
                                 ev.MotRow(1, 3, (0.0, 0.0, 4.0, 4.0))])
    assert n == 2
    back = ev.read_mot_file(path)
    assert [(r.frame, r.id) for r in back] == [(1, 3), (2, 5)]
    assert back[1].box == (1.5, 2.25, 10.0, 20.0) and back[1].score == pytest.approx(0.75)
    gt = ev.parse_mot_lines(["1,1,0,0,10,10,1,1,1.0", "1,2,0,0,10,10,0,1,1.0",
                             "1,3,0,0,10,10,1,3,1.0"], ground_truth=True)
    assert [r.id for r in gt] == [1]


@pytest.mark.parametrize("line", ["1,1,0,0,10", "1,1,a,0,10,10", "1,1,0,0,-3,10",
                                  "1.5,1,0,0,10,10", "1,1,nan,0,10,10"])
def test_bad_mot_lines_name_the_line(line):
    with pytest.raises(ev.EvaluationError, match=":1:"):
        ev.parse_mot_lines([line])


def test_single_target_metrics_hand_computed():
    gt = [(0, 0, 10, 10)] * 4 + [None]
    pred = [(0, 0, 10, 10), (3, 4, 10, 10), (30, 0, 10, 10), None, (0, 0, 10, 10)]
    err = ev.center_errors(pred, gt)
    assert err[:3] == pytest.approx([0.0, 5.0, 30.0]) and np.isinf(err[3])
    assert err.size == 4                                   # frame without gt left out
    assert ev.precision_at(err, 20.0) == pytest.approx(0.5)
    ov = ev.overlaps(pred, gt)
    assert ov == pytest.approx([1.0, 42.0 / 158.0, 0.0, 0.0])
    # success AUC: mean over t = 0, 0.05, ..., 1 of fraction(IoU > t)
    expected = np.mean([np.mean(np.array(ov) > t) for t in np.linspace(0, 1, 21)])
    assert ev.success_auc(ov) == pytest.approx(expected)
    # frame 0 succeeds at every t < 1 (20 of 21 thresholds), frame 1 for t < 0.266 (6)
    assert ev.success_auc(ov) == pytest.approx((20 + 6) / (21 * 4))


def test_box_list_reader_accepts_commas_and_spaces(tmp_path):
    p = tmp_path / "gt.txt"
    p.write_text("1,2,3,4\n5 6 7 8\n0\t0\t0\t0\n")
    assert ev.read_box_list(p) == [(1, 2, 3, 4), (5, 6, 7, 8), None]


def parse(argv):
    parser = argparse.ArgumentParser()
    evaluation_cli.configure_parser(parser)
    return parser.parse_args(argv)


def test_cli_scores_results_and_writes_markdown(tmp_path, capsys):
    gt = tmp_path / "gt.txt"
    res = tmp_path / "res.txt"
    ev.write_mot_file(gt, GT)
    ev.write_mot_file(res, [r for r in GT if r.id == 1])
    md = tmp_path / "out.md"
    assert evaluation_cli.run(parse(["--gt", str(gt), str(res), "--markdown", str(md)])) == 0
    out = capsys.readouterr().out
    assert "MOTA" in out and "50.0%" in out
    # HOTA of one of two people tracked perfectly: DetA 10 / (10 + 10) = 0.5, AssA 1,
    # HOTA sqrt(0.5)
    assert re.search(r"^res\s+70\.7%\s+50\.0%\s+100\.0%$", out, re.M), out
    table = md.read_text()
    assert "| res |" in table and "hota | deta | assa |" in table and "| 0.707 | 0.500 | 1.000 |" in table


def test_cli_reports_missing_file(tmp_path, capsys):
    assert evaluation_cli.run(parse(["--gt", str(tmp_path / "nope.txt"),
                                     str(tmp_path / "x.txt")])) == 1
    assert "no such file" in capsys.readouterr().err


def test_cli_single_target_with_plot(tmp_path, capsys):
    gt = tmp_path / "groundtruth_rect.txt"
    gt.write_text("0,0,10,10\n0,0,10,10\n")
    res = tmp_path / "res.txt"
    res.write_text("0 0 10 10\n100 100 10 10\n")
    png = tmp_path / "plot.png"
    assert evaluation_cli.run(parse(["--single-target", "--gt", str(tmp_path), str(res),
                                     "--plot", str(png)])) == 0
    assert "precision@20px 0.500" in capsys.readouterr().out
    assert png.stat().st_size > 1000


def test_tud_campus_ground_truth_scores_perfectly(shared_data):
    gt = ev.read_mot_file(shared_data / "mot" / "TUD-Campus" / "gt" / "gt.txt",
                          ground_truth=True)
    assert len(gt) == 359
    m = ev.mot_metrics(gt, gt)
    assert m["mota"] == pytest.approx(1.0) and m["num_unique_objects"] == 8
