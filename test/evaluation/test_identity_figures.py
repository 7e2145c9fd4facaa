"""Ground-truth-free figures of a multi-object run (mk_tracker.evaluation.identity_figures),
and the real thermal gate of issues #15/#19 on BU-TIV-lab (runs only where ../shared/data
is present)."""

from __future__ import annotations

import pytest

from mk_tracker.boxes import iou
from mk_tracker.evaluation.identity_figures import duplicate_pairs, identity_figures


def test_duplicate_pairs_count_each_overlapping_pair_once():
    a = (0, 0, 10, 20)
    assert duplicate_pairs([]) == 0
    assert duplicate_pairs([a, (1, 0, 10, 20)]) == 1               # IoU 0.82
    assert duplicate_pairs([a, (6, 0, 10, 20)]) == 0               # IoU 0.25
    assert duplicate_pairs([a, (1, 0, 10, 20), (0, 1, 10, 20)]) == 3


def test_identity_figures_per_frame_and_over_the_clip():
    tracks = [[(1, (0, 0, 10, 20)), (2, (1, 0, 10, 20))],
              [(1, (0, 0, 10, 20))],
              [(3, (50, 0, 10, 20)), (1, (0, 0, 10, 20))]]
    f = identity_figures(tracks, [[0, 1, 2], [0], []])
    assert f == {"detections": pytest.approx(4 / 3), "tracks": pytest.approx(5 / 3),
                 "ids": 3, "duplicates": pytest.approx(1 / 3)}
    assert identity_figures([])["ids"] == 0


def test_real_thermal_clip_keeps_ids_and_duplicates_down(shared_data, tmp_path):
    """BU-TIV-lab (~7 people, 4-6 visible, no ground truth), counter masked, defaults:
    measured 8 ids, 0.00 duplicate pairs and 4.73 tracks per frame, no reported box
    taller than the 512 px frame, and the man with crossed arms at the back left, who
    stands still for the whole clip, covered by a reported box (IoU >= 0.3) in 452 frames
    (110-561; docs/benchmark_real_thermal.md); before the persistent warm pixels of the
    still-people rule (detector.still_people.persistent_passes 0) 8 / 0.00 / 4.06 and the
    man covered in 194 frames (368-561: his warm pixels joined a neighbour's at the full
    passes; the tracks per frame rose with the frames he is reported in); before still
    people were detected
    (detector.still_people) 7 / 0.00 / 3.72 and the man covered in no frame; before observation-
    centric recovery of drifted tracks (tracker.recovery.*) 9 / 0.00 / 4.33 with 325
    boxes taller than the frame (runaway kernels that stopped births; nearby recovery
    settings give 6-11 ids, 0.00-0.01 duplicate pairs, 3.6-4.0 tracks per frame, no box
    taller than the frame); before a stacked pair was published as one track
    (duplicates.report_one) 9 / 0.15 / 4.49, before re-acquisition from the last detection
    18 / 0.18 / 4.33, before the duplicate and still-person rules of #19 21 / 0.59 / 4.58,
    before group measurements 34 / 1.53 / 5.80.  The bounds keep a margin over the newest
    figures (nearby settings of the last-detection gate give 9-17 ids: one re-acquisition
    changes what follows, with 0.00-0.01 duplicate pairs and 3.9-4.7 tracks per frame; the
    duplicates bound is #19's goal), so every gain so far is guarded without pinning the
    figure."""
    from mk_tracker.bags.bag_io import open_bag
    from mk_tracker.tools.cli import main as cli_main
    from mk_tracker.tools.pipeline import PipelineOptions, process_bag
    from mk_tracker.tools.pipeline_config import load_pipeline_config

    clip = shared_data / "thermal" / "BU-TIV-lab" / "BU-TIV-lab.mp4"
    if not clip.is_file():
        pytest.skip("BU-TIV-lab is not in the shared data")
    bag = tmp_path / "lab"
    assert cli_main(["import", str(clip), "--thermal", "--out", str(bag), "--quiet"]) == 0
    params = tmp_path / "mask.yaml"
    params.write_text("detector_node:\n  ros__parameters:\n"
                      "    ignore_regions: [0.0, 0.0, 110.0, 50.0]\n")
    result = process_bag(bag, tmp_path / "out", config=load_pipeline_config([params]),
                         options=PipelineOptions(progress=False, write_video=False,
                                                 write_plots=False, write_bag=False))
    assert result.frames == 562
    stamps = sorted(result.frame_stamps)
    frames = [list(result.tracks.get(ns, [])) for ns in stamps]
    f = identity_figures(frames)
    assert f["ids"] <= 11 and f["duplicates"] <= 0.02 and f["tracks"] <= 5.2, f
    tallest = max(float(box[3]) for frame in frames for _, box in frame)
    assert tallest <= 512.0, tallest          # no runaway box (the frame is 512 px high)
    assert f["tracks"] >= 3.0, f              # people are followed (4-6 visible)
    # the man at the back left, still from the first frame to the last (detector.still_people)
    man = (85.0, 38.0, 55.0, 178.0)
    covered = sum(any(iou(box, man) >= 0.3 for _, box in frame) for frame in frames)
    assert covered >= 400, covered
    with open_bag(bag) as reader:             # the imported bag is the clip, thermal only
        assert "/thermal/image_raw" in reader.topics
