"""K-means of support pixels with the merge rule (3.12)-(3.13) and the link rule."""

import numpy as np
import pytest

from mk_tracker.pixel_clustering import (ClusteringError, cluster_support_pixels,
                                         describe_pixels, kmeans, link_groups, merge_linked)


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
