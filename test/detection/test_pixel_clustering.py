"""K-means of support pixels with the merge rule (3.12)-(3.13) and the link rule."""

import numpy as np
import pytest

from mk_tracker.detection.pixel_clustering import (ClusteringError, cluster_support_pixels, describe_parts,
                                         describe_pixels, kmeans, link_groups, merge_linked,
                                         valley_split)


def blob(cx, cy, r=2):
    ys, xs = np.mgrid[cy - r:cy + r + 1, cx - r:cx + r + 1]
    return np.column_stack([xs.ravel(), ys.ravel()]).astype(float)


def test_kmeans_separates_two_blobs():
    pts = np.vstack([blob(0, 0), blob(30, 10)])
    centroids, labels = kmeans(pts, 2)
    got = sorted(map(tuple, np.round(centroids, 6)))
    assert got == [(0.0, 0.0), (30.0, 10.0)]
    assert len(set(labels[:25])) == 1 and len(set(labels[25:])) == 1


def test_merge_rule_reduces_clusters_to_the_number_of_objects():
    pts = np.vstack([blob(0, 0), blob(40, 0), blob(20, 30)])
    centroids, labels = cluster_support_pixels(pts, max_objects=10, merge_distance_sq=25.0)
    assert centroids.shape[0] == 3
    np.testing.assert_allclose(sorted(map(tuple, centroids)), [(0, 0), (20, 30), (40, 0)],
                               atol=1e-9)


def test_objects_closer_than_epsilon_d_merge():
    pts = np.vstack([blob(0, 0), blob(12, 0)])
    far, _ = cluster_support_pixels(pts, max_objects=5, merge_distance_sq=20.0)
    near, labels = cluster_support_pixels(pts, max_objects=5, merge_distance_sq=144.0)
    assert far.shape[0] == 2          # 12^2 = 144 > 20: kept apart
    assert near.shape[0] == 1         # 144 <= 144: merged (3.13)
    np.testing.assert_allclose(near[0], (6.0, 0.0))
    assert set(labels) == {0}


def test_upper_limit_m_up_caps_the_count():
    pts = np.vstack([blob(0, 0), blob(40, 0), blob(80, 0)])
    centroids, _ = cluster_support_pixels(pts, max_objects=2, merge_distance_sq=1.0)
    assert centroids.shape[0] == 2


def test_empty_support_and_bad_input():
    c, lab = cluster_support_pixels(np.zeros((0, 2)), max_objects=3, merge_distance_sq=10)
    assert c.shape == (0, 2) and lab.size == 0
    with pytest.raises(ClusteringError):
        cluster_support_pixels(np.zeros((4, 3)), max_objects=3, merge_distance_sq=10)
    with pytest.raises(ClusteringError):
        cluster_support_pixels(np.zeros((4, 2)), max_objects=0, merge_distance_sq=10)


def test_link_groups_gap():
    mask = np.zeros((5, 12), bool)
    mask[2, 0] = mask[2, 3] = mask[2, 10] = True      # gaps of 3 and 7 columns
    g2 = link_groups(mask, 2)
    g3 = link_groups(mask, 3)
    assert g2[2, 0] != g2[2, 3]
    assert g3[2, 0] == g3[2, 3] != g3[2, 10]
    assert g3[0, 0] == 0


def test_merge_linked_joins_clusters_sharing_a_group():
    labels = np.array([0, 0, 1, 1, 2, 2])
    groups = np.array([5, 5, 5, 7, 9, 9])
    np.testing.assert_array_equal(merge_linked(labels, groups), [0, 0, 0, 0, 1, 1])


def test_describe_pixels_uses_the_pixel_centre_convention():
    obj = describe_pixels(np.array([2, 3, 2, 3]), np.array([5, 5, 6, 6]))
    assert obj.centroid == (3.0, 6.0)
    assert obj.box == (2.0, 5.0, 2.0, 2.0)
    assert obj.pixel_count == 4
    with pytest.raises(ClusteringError):
        describe_pixels(np.array([]), np.array([]))


def test_merge_linked_chains_and_first_pixel_order():
    # cluster 2 and 0 share group 7, cluster 0 and 3 share group 9 -> one object; cluster 1
    # alone; numbering follows the first pixel of each object
    labels = np.array([1, 2, 0, 0, 3, 1, 4])
    groups = np.array([5, 7, 7, 9, 9, 5, 6])
    np.testing.assert_array_equal(merge_linked(labels, groups), [0, 1, 1, 1, 1, 0, 2])
    rng = np.random.default_rng(4)
    labels = rng.integers(0, 20, 500)
    groups = rng.integers(0, 200, 500)
    out = merge_linked(labels, groups)
    # pixels with the same cluster, or the same group, always share an object
    for values in (labels, groups):
        for v in np.unique(values):
            assert np.unique(out[values == v]).size == 1
    assert out[0] == 0 and set(np.unique(out)) == set(range(out.max() + 1))


def _two_people(gap_value: float) -> tuple[np.ndarray, np.ndarray]:
    """Two 'people' side by side that touch: bodies 100 and 110, heads 150 on top, a
    one-column bridge of ``gap_value`` between the bodies (all on the footprint)."""
    v = np.zeros((40, 41), dtype=np.float32)
    v[10:40, 0:20] = 100.0
    v[10:40, 21:41] = 110.0
    v[10:40, 20] = gap_value
    v[2:10, 6:14] = 150.0          # head of the left one
    v[2:10, 27:35] = 150.0         # head of the right one
    return v, v > 0


def test_valley_split_separates_touching_blobs_at_their_valley():
    v, m = _two_people(60.0)
    n, labels = valley_split(v, m, depth=30.0)
    assert n == 2
    left, right = labels[20, 5], labels[20, 35]
    assert left != right and left > 0 and right > 0
    # every body pixel goes to its own head's part (the bridge, 40 below both, splits them)
    assert np.all(labels[10:40, 0:20] == left)
    assert np.all(labels[10:40, 21:41] == right)
    assert np.all(labels[2:10, 6:14] == left) and np.all(labels[2:10, 27:35] == right)
    assert np.all(labels[~m] == 0) and np.all(labels[m] > 0)


def test_valley_split_keeps_a_blob_whose_peaks_stand_out_by_less_than_depth():
    v, m = _two_people(100.0)
    # heads 150 over bodies 100/110 and a bridge of 100: the left head stands 50 above the
    # valley, less than a depth of 60 -> one object
    n, labels = valley_split(v, m, depth=60.0)
    assert n == 1
    assert np.array_equal(labels, m.astype(np.int32))


def test_valley_split_drops_small_peaks_by_fraction_and_area():
    v = np.zeros((40, 30), dtype=np.float32)
    v[10:40, 5:25] = 100.0          # body
    v[2:10, 11:19] = 150.0          # head, 64 px
    v[30:32, 3:5] = 150.0           # a 'hand', 4 px, on the body's edge
    m = v > 0
    # with no size rule the hand is a peak of its own
    assert valley_split(v, m, depth=30.0)[0] == 2
    # smaller than 0.4 of the head: part of the body
    assert valley_split(v, m, depth=30.0, min_peak_fraction=0.4)[0] == 1
    # fewer pixels than min_area: no peak either
    assert valley_split(v, m, depth=30.0, min_area=6)[0] == 1


def test_valley_split_single_blob_empty_mask_and_bad_input():
    v = np.full((5, 5), 7.0, dtype=np.float32)
    m = np.zeros((5, 5), dtype=bool)
    n, labels = valley_split(v, m, depth=1.0)
    assert n == 0 and not labels.any()
    m[1:4, 1:4] = True
    n, labels = valley_split(v, m, depth=1.0)
    assert n == 1 and np.array_equal(labels, m.astype(np.int32))
    with pytest.raises(ClusteringError):
        valley_split(v, m[:4], depth=1.0)
    with pytest.raises(ClusteringError):
        valley_split(v, m, depth=0.0)
    with pytest.raises(ClusteringError):
        valley_split(v, m, depth=1.0, min_peak_fraction=1.5)
    bad = v.copy()
    bad[2, 2] = np.nan
    with pytest.raises(ClusteringError):
        valley_split(bad, m, depth=1.0)


def test_valley_split_compiled_loops_equal_the_interpreted_reference():
    """The numba loops (the default backend when numba is there) and the same loops run
    by Python give the same parts, on noisy blobs with plateaus, ties and pieces cut off
    from the rest."""
    rng = np.random.default_rng(7)
    for trial in range(6):
        v, m = _two_people(60.0 + 10 * trial)
        v = v + rng.integers(0, 6, v.shape).astype(np.float32)
        m[30:34, 18:23] = False                  # a hole
        m[36:40, 0:3] = True                     # and a piece off to the side
        m[36:40, 3:6] = False
        for frac in (0.0, 0.4):
            fast = valley_split(v, m, 30.0, min_area=3, min_peak_fraction=frac,
                                backend="auto")
            slow = valley_split(v, m, 30.0, min_area=3, min_peak_fraction=frac,
                                backend="python")
            assert fast[0] == slow[0]
            assert np.array_equal(fast[1], slow[1])


def test_valley_split_a_cut_off_piece_with_one_peak_is_no_part():
    """A leg cut off from its body by background pixels stands out of its own foot by more
    than depth, but no valley separates it from a person: it joins the nearest part.  A
    piece as big as the other part per peak is a part of its own (a second person)."""
    v = np.zeros((60, 50), dtype=np.float32)
    v[10:40, 5:25] = 100.0          # body
    v[2:10, 11:19] = 150.0          # head
    v[42:58, 8:12] = 90.0           # a leg, cut off by the row of background at 40-41
    v[56:58, 8:12] = 50.0           # its cold foot: the leg stands 40 above it
    m = v > 0
    n, labels = valley_split(v, m, depth=30.0, min_peak_fraction=0.4)
    assert n == 1 and np.all(labels[m] == 1)
    # a second person as a piece of its own: two parts
    v[10:40, 30:48] = 100.0
    v[2:10, 35:43] = 150.0
    m = v > 0
    n, labels = valley_split(v, m, depth=30.0, min_peak_fraction=0.4)
    assert n == 2
    assert labels[20, 10] != labels[20, 40]
    assert labels[50, 10] == labels[20, 10]      # the leg goes to its own body's part


def test_describe_parts_equals_describe_pixels_of_each_part():
    labels = np.zeros((9, 12), dtype=np.int32)
    labels[1:4, 2:6] = 1
    labels[5:9, 7:12] = 2
    labels[0, 11] = 2
    stats = describe_parts(labels, 3)
    for k in (1, 2):
        r, c = np.nonzero(labels == k)
        ref = describe_pixels(c, r)
        cnt, sx, sy, xmin, xmax, ymin, ymax = stats[k - 1]
        assert cnt == ref.pixel_count
        assert (sx / cnt + 0.5, sy / cnt + 0.5) == pytest.approx(ref.centroid)
        assert (xmin, ymin, xmax + 1 - xmin, ymax + 1 - ymin) == pytest.approx(ref.box)
    assert stats[2, 0] == 0
