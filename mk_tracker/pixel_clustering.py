"""Splitting support pixels into objects, Schizas et al. Sec. 3.3, (3.12)-(3.13).

The support of the sparse factors (the pixels with a nonzero entry) may hold several
objects.  Their coordinates are clustered by K-means (3.12); while two cluster centroids are
closer than the merge distance, ``||xi_j - xi_j'||^2 <= epsilon_d`` (3.13), the number of
clusters is decreased by one and K-means re-run, starting from ``Z = M_up`` (the upper limit
on the number of objects).  Each re-run starts from the previous centroids with the closest
pair replaced by its pixel-weighted mean, so the reductions are cheap.

K-means is OpenCV's ``cv2.kmeans`` with k-means++ seeding from a fixed seed, so a frame
always gives the same objects.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


class ClusteringError(ValueError):
    """Inputs the clustering cannot use."""


def _sq_dists(points: np.ndarray, centroids: np.ndarray) -> np.ndarray:
    """``(n, k)`` squared distances (expanded form, clipped at 0 against rounding)."""
    d = (points * points).sum(axis=1)[:, None] - 2.0 * points @ centroids.T
    d += (centroids * centroids).sum(axis=1)[None, :]
    return np.maximum(d, 0.0)


def kmeans(points: np.ndarray, k: int | None = None, *, init: np.ndarray | None = None,
           max_iter: int = 50, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """K-means minimising (3.12), by OpenCV's ``cv2.kmeans``.

    Either ``k`` (k-means++ seeding; OpenCV's generator is seeded with ``seed`` first, so a
    frame always gives the same clusters) or ``init`` centroids (each point starts in the
    cluster of its nearest initial centroid).  Stops after ``max_iter`` Lloyd iterations or
    when no centroid moves by more than 1e-3 px.  Returns ``(centroids (Z, d), labels
    (n,))``; clusters left empty are dropped, so fewer than ``k`` centroids may come back.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[0] == 0:
        raise ClusteringError(f"points must be a non-empty (n, d) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ClusteringError("points contain NaN or infinite coordinates")
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, int(max_iter), 1e-3)
    data = pts.astype(np.float32)
    if init is None:
        if k is None or k < 1:
            raise ClusteringError("give k >= 1 or initial centroids")
        k = min(int(k), pts.shape[0])
        cv2.setRNGSeed(int(seed))
        _, labels, _ = cv2.kmeans(data, k, None, criteria, 1, cv2.KMEANS_PP_CENTERS)
    else:
        start = np.asarray(init, dtype=np.float64)
        if start.ndim != 2 or start.shape[1] != pts.shape[1] or start.shape[0] == 0:
            raise ClusteringError(f"initial centroids must be (k, {pts.shape[1]}), "
                                  f"got shape {start.shape}")
        k = min(start.shape[0], pts.shape[0])
        first = np.argmin(_sq_dists(pts, start[:k]), axis=1).astype(np.int32).reshape(-1, 1)
        _, labels, _ = cv2.kmeans(data, k, first, criteria, 1, cv2.KMEANS_USE_INITIAL_LABELS)
    labels = labels.reshape(-1).astype(np.int64)
    # centroids in float64 from the final labels; empty clusters are dropped
    counts = np.bincount(labels, minlength=k)
    keep = counts > 0
    remap = np.cumsum(keep) - 1
    labels = remap[labels]
    counts = counts[keep]
    sums = np.stack([np.bincount(labels, weights=pts[:, a], minlength=counts.size)
                     for a in range(pts.shape[1])], axis=1)
    return sums / counts[:, None], labels


def closest_pair(centroids: np.ndarray) -> tuple[int, int, float]:
    """Indices and squared distance of the two closest centroids."""
    d = _sq_dists(centroids, centroids)
    np.fill_diagonal(d, np.inf)
    flat = int(np.argmin(d))
    i, j = divmod(flat, d.shape[1])
    return i, j, float(d[i, j])


def cluster_support_pixels(coords: np.ndarray, *, max_objects: int, merge_distance_sq: float,
                           seed: int = 0, max_points: int = 1000
                           ) -> tuple[np.ndarray, np.ndarray]:
    """K-means of support pixel coordinates with the merge rule (3.13) and the limit M_up.

    ``coords``: ``(n, 2)`` pixel coordinates.  Starts with ``Z = min(M_up, n)`` clusters and
    decreases Z while the closest centroids satisfy ``||xi_j - xi_j'||^2 <= epsilon_d``.
    Centroids are fitted on at most ``max_points`` pixels (a deterministic stride sample),
    then every pixel takes its nearest centroid.  Returns ``(centroids, labels)``.
    """
    pts = np.asarray(coords, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ClusteringError(f"coords must be (n, 2), got shape {pts.shape}")
    if max_objects < 1:
        raise ClusteringError("max_objects (M_up) must be >= 1")
    n = pts.shape[0]
    if n == 0:
        return np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
    step = max(1, -(-n // max_points))
    sample = pts[::step]
    centroids, labels = kmeans(sample, min(max_objects, sample.shape[0]), seed=seed)
    while centroids.shape[0] > 1:
        i, j, d2 = closest_pair(centroids)
        if d2 > merge_distance_sq:
            break
        wi = np.count_nonzero(labels == i)
        wj = np.count_nonzero(labels == j)
        merged = (centroids[i] * wi + centroids[j] * wj) / max(wi + wj, 1)
        init = np.vstack([np.delete(centroids, [i, j], axis=0), merged[None]])
        centroids, labels = kmeans(sample, init=init)
    labels = np.argmin(_sq_dists(pts, centroids), axis=1)
    return centroids, labels


@dataclass(frozen=True)
class PixelObject:
    """One object's support pixels: centroid ``(cx, cy)``, box ``(x, y, w, h)`` (the paper's
    ``w_s^0 x h_s^0`` rectangle), and pixel count.  Pixel ``(c, r)`` covers
    ``[c, c+1) x [r, r+1)`` so its centre is ``(c + 0.5, r + 0.5)``."""

    centroid: tuple[float, float]
    box: tuple[float, float, float, float]
    pixel_count: int


def describe_pixels(cols: np.ndarray, rows: np.ndarray) -> PixelObject:
    """Centroid, bounding box and count of a non-empty set of pixels."""
    cols = np.asarray(cols)
    rows = np.asarray(rows)
    if cols.size == 0:
        raise ClusteringError("an object needs at least one pixel")
    x0, x1 = int(cols.min()), int(cols.max()) + 1
    y0, y1 = int(rows.min()), int(rows.max()) + 1
    return PixelObject(centroid=(float(cols.mean()) + 0.5, float(rows.mean()) + 0.5),
                       box=(float(x0), float(y0), float(x1 - x0), float(y1 - y0)),
                       pixel_count=int(cols.size))


def link_groups(support: np.ndarray, gap: int) -> np.ndarray:
    """Connected-component id of every support pixel, pixels within ``gap`` px linked.

    ``support``: ``(h, w)`` bool.  Returns an ``(h, w)`` int32 map (0 off the support).  Two
    support pixels share an id when a chain of support pixels joins them with steps of at
    most ``gap`` pixels (Chebyshev distance; ``gap = 1`` is 8-connectivity).
    """
    import cv2  # local: the rest of the module is pure numpy

    mask = np.asarray(support, dtype=np.uint8)
    size = max(int(gap), 1)        # a k x k dilation joins pixels up to k apart (Chebyshev)
    dil = cv2.dilate(mask, np.ones((size, size), np.uint8)) if size > 1 else mask
    _, labels = cv2.connectedComponents(dil, connectivity=8)
    labels = labels.astype(np.int32)
    labels[mask == 0] = 0
    return labels


def merge_linked(labels: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Merge clusters that share a link group: the final objects are the connected parts of
    the graph joining pixels of one K-means cluster or of one group.  Returns labels
    renumbered 0..n-1 (ordered by first pixel).

    The graph has one node per cluster and per group and an edge per distinct (cluster,
    group) pair of the pixels; its components come from a union-find over those few pairs.
    """
    labels = np.asarray(labels, dtype=np.int64)
    groups = np.asarray(groups, dtype=np.int64)
    if labels.size == 0:
        return labels
    _, lab = np.unique(labels, return_inverse=True)
    _, grp = np.unique(groups, return_inverse=True)
    n_lab, n_grp = int(lab.max()) + 1, int(grp.max()) + 1
    parent = list(range(n_lab + n_grp))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for pair in np.unique(lab * n_grp + grp).tolist():
        ra, rb = find(pair // n_grp), find(n_lab + pair % n_grp)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    root = np.array([find(k) for k in range(n_lab)], dtype=np.int64)
    merged = root[lab]
    _, first = np.unique(merged, return_index=True)
    order = np.argsort(np.argsort(first))
    _, dense = np.unique(merged, return_inverse=True)
    return order[dense]
