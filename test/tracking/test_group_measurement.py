"""Group measurements (issue #15): a detection around several tracked people is assigned to
none of them; each member keeps its id and is held inside the group box; a box already
explained by live tracks starts no new track."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mk_tracker.parameters import updated
from mk_tracker.tracking.group_measurement import (GroupConfig, constrain_inside,
                                                   coverage_matrix, explained_fraction,
                                                   find_groups)
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0


def test_coverage_is_the_share_of_the_inner_box_inside_the_outer_one():
    cov = coverage_matrix([(0, 0, 10, 10), (5, 0, 10, 10), (50, 50, 4, 4)],
                          [(0, 0, 10, 20)])
    assert cov[:, 0] == pytest.approx([1.0, 0.5, 0.0])


def test_a_group_needs_two_members_inside_a_clearly_larger_box():
    cfg = GroupConfig()
    tracks = [(100, 100, 30, 60), (135, 100, 30, 60), (400, 100, 30, 60)]
    assert find_groups(tracks, [(98, 98, 70, 64)], cfg) == {0: [0, 1]}
    # one person's box over two tracks on that person: a duplicate, not a group
    assert find_groups([(100, 100, 30, 60), (102, 101, 30, 60)], [(99, 99, 34, 63)], cfg) == {}
    # two tracks on one person inside a larger box: overlapping members are no group
    assert find_groups([(100, 100, 30, 60), (106, 100, 30, 60)], [(95, 95, 60, 70)], cfg) == {}
    assert find_groups([(100, 100, 30, 60), (106, 100, 30, 60)], [(95, 95, 60, 70)],
                       dataclasses.replace(cfg, member_max_iou=0.9)) == {0: [0, 1]}
    # one member only
    assert find_groups(tracks, [(98, 98, 36, 64)], cfg) == {}
    # switched off
    assert find_groups(tracks, [(98, 98, 70, 64)], dataclasses.replace(cfg, enabled=False)) \
        == {}


def test_member_min_height_refuses_tracks_much_shorter_than_the_box():
    # two tracks stacked on one person (torso box over legs box) inside that person's
    # detection: each is less than 0.8 of the box's height, so with the bound on it is no
    # group and the detection is associated as usual
    tracks = [(100, 100, 30, 70), (102, 150, 30, 70)]
    det = [(95, 95, 45, 130)]
    assert find_groups(tracks, det, GroupConfig()) == {0: [0, 1]}
    on = GroupConfig(member_min_height=0.8)
    assert find_groups(tracks, det, on) == {}
    # two people side by side, as tall as the box (0.94 of it): still a group
    assert find_groups([(100, 100, 30, 60), (135, 100, 30, 60)], [(98, 98, 70, 64)], on) \
        == {0: [0, 1]}
    # the bound is inclusive: members exactly 0.8 of the box's height
    assert find_groups([(100, 100, 30, 80), (135, 100, 30, 80)], [(98, 98, 70, 100)], on) \
        == {0: [0, 1]}
    assert find_groups([(100, 100, 30, 79), (135, 100, 30, 79)], [(98, 98, 70, 100)], on) \
        == {}


def test_each_track_belongs_to_the_detection_that_covers_it_most():
    tracks = [(0, 0, 10, 10), (12, 0, 10, 10), (20, 0, 10, 10), (32, 0, 10, 10)]
    dets = [(-1, -1, 25, 12), (18, -1, 26, 12)]
    assert find_groups(tracks, dets, GroupConfig()) == {0: [0, 1], 1: [2, 3]}


def test_constrain_moves_the_least_distance_and_keeps_the_size():
    out = constrain_inside((90, 100, 20, 40), (100, 90, 60, 80))
    assert out == pytest.approx([100, 100, 20, 40])
    out = constrain_inside((150, 150, 20, 40), (100, 90, 60, 80))
    assert out == pytest.approx([140, 130, 20, 40])
    # larger than the group along x: centred on it
    out = constrain_inside((0, 100, 80, 40), (100, 90, 60, 80))
    assert out == pytest.approx([90, 100, 80, 40])


def test_explained_fraction_counts_the_union_once():
    box = (0, 0, 12, 12)
    assert explained_fraction(box, []) == 0.0
    assert explained_fraction(box, [(0, 0, 6, 12)]) == pytest.approx(0.5)
    assert explained_fraction(box, [(0, 0, 6, 12), (0, 0, 6, 12)]) == pytest.approx(0.5)
    assert explained_fraction(box, [(0, 0, 6, 12), (6, 0, 6, 12)]) == pytest.approx(1.0)


def _people_merging(trk, group: bool, frames_apart=20, frames_merged=25):
    """Two people walk side by side; after ``frames_apart`` frames the detector reports one
    box around both (a merged detection) for ``frames_merged`` frames, then two again."""
    out = []
    for i in range(frames_apart + frames_merged + 15):
        a = (100 + 2 * i, 100, 30, 60)
        b = (140 + 2 * i, 102, 30, 60)
        if frames_apart <= i < frames_apart + frames_merged:
            x0, y0 = a[0] - 2, 98
            dets = [FrameDetection((x0, y0, b[0] + b[2] + 2 - x0, 66), 0.9)]
        else:
            dets = [FrameDetection(a, 0.9), FrameDetection(b, 0.9)]
        out.append(trk.step(IMG, i * DT, dets))
    return out


@pytest.mark.parametrize("enabled", [True, False])
def test_tracks_of_a_merged_detection_keep_their_ids_and_places(enabled):
    # the premise run (no group measurements) is the plain association: without it the
    # recovery round (tracking/recovery.py) would give the merged box to one track at once
    cfg = updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False,
                                               "group.enabled": enabled,
                                               "recovery.enabled": enabled})
    results = _people_merging(MultiObjectTracker(cfg), enabled)
    first = {t.id for t in results[19].reported()}
    assert len(first) == 2
    merged = results[20:45]
    if enabled:
        ids_after = {t.id for t in results[-1].reported()}
        # both people stay reported, each in its own half of the group, no new id
        for r in merged:
            boxes = sorted((t.box for t in r.reported()), key=lambda b: b[0])
            assert {t.id for t in r.reported()} == first
            assert boxes[0][2] < 40 and boxes[1][2] < 40          # not grown to the group
            assert boxes[0][0] + boxes[0][2] / 2 < boxes[1][0] + boxes[1][2] / 2 - 20
        assert ids_after == first
        assert max(t.id for t in results[-1].tracks) == max(first)
    else:
        # the premise: without group measurements the merged box matches neither track
        # at first (both drop out of the report), then one track takes the group's box
        assert min(len(r.reported()) for r in merged) == 0
        assert max(t.box[2] for r in merged for t in r.reported()) > 50


@pytest.mark.parametrize("bound", [0.0, 0.8])
def test_a_person_detection_over_two_stacked_part_tracks_is_no_group_with_the_bound(bound):
    """Two confirmed tracks on the torso and the legs of one person (the detector gave part
    boxes), then the detector sees the whole person: without ``member_min_height`` that box
    is a group measurement over both part tracks, which then count as detected (neither
    coasts, so neither ends); with 0.8 (each is 0.48 of the box's height) it is no group and
    the part tracks go undetected."""
    cfg = updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False,
                                               "group.member_min_height": bound})
    trk = MultiObjectTracker(cfg)
    parts = [FrameDetection((300, 100, 30, 60), 0.9), FrameDetection((300, 160, 30, 60), 0.9)]
    for i in range(4):
        trk.step(IMG, i * DT, parts)
    assert len(trk.step(IMG, 4 * DT, parts).reported()) == 2
    before = trk.totals["group_measurements"]
    result = trk.step(IMG, 5 * DT, [FrameDetection((297, 98, 36, 124), 0.9)])
    grouped = trk.totals["group_measurements"] - before
    detected = [t for t in result.tracks if t.time_since_detection == 0.0]
    assert len(result.tracks) == 2                # the person's box starts no third track
    if bound == 0.0:
        assert grouped == 1 and len(detected) == 2
    else:
        assert grouped == 0 and not detected
