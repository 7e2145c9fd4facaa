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

from mk_tracker.numba_support import import_numba


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


#: the K-means of the object-level splits (:mod:`~mk_tracker.detection.keep_apart`,
#: :mod:`~mk_tracker.detection.object_extent`) fit their centroids on about this many
#: footprint pixels
SPLIT_FIT_POINTS = 1000


def stride_sample(points: np.ndarray, max_points: int = SPLIT_FIT_POINTS) -> np.ndarray:
    """Every ``n // max_points``-th row of ``points`` (all of them when ``n <= 2 *
    max_points - 1``): a deterministic sample of between ``max_points`` and ``2 *
    max_points - 1`` rows to fit centroids on, before every pixel takes its nearest one."""
    return points[::max(1, points.shape[0] // max_points)]


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


def valley_split(values: np.ndarray, mask: np.ndarray, depth: float, *,
                 min_area: int = 1, min_peak_fraction: float = 0.0,
                 backend: str = "auto") -> tuple[int, np.ndarray]:
    """Split a footprint along the intensity valleys between its peaks.

    ``values``: ``(h, w)`` intensities, oriented so that the objects are the high side (warm
    objects as they are, cold ones negated); ``mask``: ``(h, w)`` bool, the footprint (one
    or more touching objects).

    *Peaks.*  Going down through the threshold sets ``{values >= L}`` of the footprint
    (8-connected components, every level a pixel has: exact, no level step), a component
    that holds no peak yet, has at least ``min_area`` pixels and whose maximum is at least
    ``depth`` above ``L`` gets a peak.  So a peak's height above the highest saddle joining
    it to a higher peak -- its dynamic -- is at least ``depth``.  The sets are one
    union-find over the pixels in descending order.  Each peak's *core* is its component at
    ``depth / 2`` below its top; peaks whose core is smaller than ``min_peak_fraction``
    times the largest core are parts of a bigger object (e.g. a person's warm hands beside
    its head: the head's core is many times a hand's, at any scale) and are dropped.  A
    piece of the mask (8-connected) that holds one peak is a part of its own only if its
    area is at least ``min_peak_fraction`` times the pieces' largest area per peak (a leg
    cut off from its body by background pixels is not).

    *Parts.*  With two or more peaks left, the footprint is flooded from them, the highest
    pixels first (a watershed): each peak's part ends at the valleys between it and the
    others; a plateau is shared by distance.  Pixels on the dome of a dropped peak go to
    the first part that reaches it, and the pixels of a piece of the mask no part reaches
    to the part of the nearest labelled pixel.

    With ``depth`` the similarity radius of the kernel (3.6), touching warm blobs are split
    only where each is dissimilar (k < 1/2) to the valley between them -- the test that
    made their pixels foreground against the background.

    ``backend``: ``"compiled"`` (numba), ``"python"`` (the same loops interpreted: the
    reference, slow) or ``"auto"`` (compiled when numba is available and
    ``MK_TRACKER_NO_NUMBA`` is not set).

    Returns ``(n, labels)``: ``labels`` ``(h, w)`` int32, 1..n on the footprint, 0 off it;
    ``n`` is 0 for an empty mask, 1 when the footprint does not split.
    """
    vals = np.ascontiguousarray(values, dtype=np.float32)
    m = np.ascontiguousarray(mask, dtype=bool)
    if vals.ndim != 2 or vals.shape != m.shape:
        raise ClusteringError(f"values {vals.shape} and mask {m.shape} must be one (h, w) shape")
    if not (np.isfinite(depth) and depth > 0):
        raise ClusteringError(f"depth must be a positive number, got {depth!r}")
    if not 0.0 <= min_peak_fraction <= 1.0:
        raise ClusteringError(f"min_peak_fraction must be in [0, 1], got {min_peak_fraction!r}")
    if backend not in ("auto", "compiled", "python"):
        raise ClusteringError(f"unknown backend {backend!r}")
    if not m.any():
        return 0, np.zeros(m.shape, dtype=np.int32)
    if not np.all(np.isfinite(vals[m])):
        raise ClusteringError("values contain NaN or infinite numbers on the mask")
    whole = m.astype(np.int32)
    kernels = _valley_kernels() if backend != "python" else None
    if backend == "compiled" and kernels is None:
        raise ClusteringError("the compiled valley split needs numba")
    peaks_loops, flood_loops = kernels[:2] if kernels is not None else (_valley_peaks_loops,
                                                                        _valley_flood_loops)
    # the mask's pixels (flat indices) in descending order of value, ties row-major (16-bit
    # keys sort by radix: integer levels, as mono8/mono16 frames have, take that path)
    where = np.flatnonzero(m)
    inside = vals.ravel()[where]
    hi = float(inside.max())
    drop = hi - inside
    if float(drop.max()) < 65536.0 and np.array_equal(drop, np.round(drop)):
        drop = drop.astype(np.uint16)
    ranked = np.ascontiguousarray(where[np.argsort(drop, kind="stable")])
    n_pix = ranked.size
    h, w = m.shape
    step = w + 2                                      # the mask padded by one pixel
    cell = np.ascontiguousarray((ranked // w + 1) * step + ranked % w + 1)
    pos = np.full((h + 2) * step, -1, dtype=np.int32)
    pos[cell] = np.arange(n_pix, dtype=np.int32)
    peaks = np.empty(n_pix, dtype=np.int64)
    areas = np.empty(n_pix, dtype=np.int64)
    pieces = np.empty(n_pix, dtype=np.int64)
    piece_areas = np.empty(n_pix, dtype=np.int64)
    n_peaks = peaks_loops(vals, ranked, cell, pos, step, np.float32(depth),
                          max(int(min_area), 1), peaks, areas, pieces, piece_areas)
    if n_peaks <= 1:
        return 1, whole
    areas = areas[:n_peaks]
    keep = areas >= min_peak_fraction * areas.max()
    if np.count_nonzero(keep) <= 1:
        return 1, whole
    kept = np.flatnonzero(keep).tolist()
    # a piece of the mask (8-connected) with one peak is a part of its own only if it is
    # not much smaller than the pieces' area per peak (a leg cut off from its body by
    # background pixels is not); peaks that share a piece are split by their valley
    piece = [int(pieces[k]) for k in kept]
    count = [piece.count(q) for q in piece]
    share = [float(piece_areas[k]) / cnt for k, cnt in zip(kept, count)]
    seeds = np.array([peaks[k] for k, cnt, sh in zip(kept, count, share)
                      if cnt >= 2 or sh >= min_peak_fraction * max(share)], dtype=np.int64)
    if seeds.size <= 1:
        return 1, whole
    out = np.zeros(m.shape, dtype=np.int32)
    flood_loops(vals, ranked, cell, pos, step, w, seeds, out)
    left = m & (out == 0)
    if left.any():
        # pieces of the mask no part reaches: each pixel to the part of the nearest labelled
        # pixel (Euclidean)
        labelled = out > 0
        _, nearest = cv2.distanceTransformWithLabels(
            (~labelled).astype(np.uint8), cv2.DIST_L2, 3, labelType=cv2.DIST_LABEL_PIXEL)
        lut = np.concatenate([[0], out[labelled]])     # zero pixels are numbered row-major
        out[left] = lut[nearest[left]]
    return int(seeds.size), out


def _valley_peaks_loops(vals, ranked, cell, pos, step, depth, min_area, peaks, areas, pieces,
                        piece_areas):
    """Peaks of :func:`valley_split`: union-find over the mask's pixels ``ranked`` (flat
    indices, descending value).  ``cell``: each ranked pixel's flat index in the frame
    padded by one pixel (rows of ``step``), ``pos``: the rank of each padded pixel, -1 off
    the mask (so neighbours need no bounds test).  Writes the rank of each peak's highest
    pixel, its area at half the depth below it, the piece of the mask (8-connected) it is
    in and that piece's area into ``peaks``, ``areas``, ``pieces``, ``piece_areas``;
    returns how many peaks."""
    fv = vals.ravel()
    n = ranked.shape[0]
    offsets = np.array([-step - 1, -step, -step + 1, -1, 1, step - 1, step, step + 1])
    # per rank; the entries of a root describe its component
    parent = np.empty(n, dtype=np.int32)
    top = np.empty(n, dtype=np.int32)       # the component's highest pixel (lowest rank)
    area = np.empty(n, dtype=np.int32)
    core = np.zeros(n, dtype=np.int32)      # its area at half the depth below the top
    cored = np.zeros(n, dtype=np.bool_)
    held = np.zeros(n, dtype=np.bool_)      # it holds a peak
    half = depth / np.float32(2.0)
    roots = np.empty(8, dtype=np.int32)
    n_peaks = 0
    for o in range(n):
        v = fv[ranked[o]]
        c = cell[o]
        n_roots = 0
        for t in range(8):
            q = pos[c + offsets[t]]
            if q < 0 or q >= o:                       # off the mask, or not added yet
                continue
            while parent[q] != q:                     # find, with path halving
                parent[q] = parent[parent[q]]
                q = parent[q]
            seen = False
            for j in range(n_roots):
                if roots[j] == q:
                    seen = True
                    break
            if not seen:
                roots[n_roots] = q
                n_roots += 1
        # the components of {values > v} this pixel joins: each gets its peak now if it
        # stands out by depth (its area is the one it had at that level)
        for j in range(n_roots):
            r = roots[j]
            height = fv[ranked[top[r]]] - v
            if not cored[r] and height >= half:
                core[r] = area[r]
                cored[r] = True
            if not held[r] and area[r] >= min_area and height >= depth:
                peaks[n_peaks] = top[r]
                areas[n_peaks] = core[r]
                n_peaks += 1
                held[r] = True
        parent[o] = o
        top[o] = o
        area[o] = 1
        root = o
        for j in range(n_roots):
            r = roots[j]
            big, small = (r, root) if area[r] >= area[root] else (root, r)
            parent[small] = big
            area[big] += area[small]
            held[big] = held[big] or held[small]
            if top[small] < top[big]:
                # the merged component's top and core are the higher one's
                top[big] = top[small]
                core[big] = core[small]
                cored[big] = cored[small]
            root = big
    # a piece of the mask that never joins another one gets no peak of its own here (no
    # valley separates it: it stands out of the background only)
    for j in range(n_peaks):
        q = peaks[j]
        while parent[q] != q:
            q = parent[q]
        pieces[j] = q
        piece_areas[j] = area[q]
    return n_peaks


def _valley_flood_loops(vals, ranked, cell, pos, step, width, seeds, labels):
    """Parts of :func:`valley_split`, a watershed: the levels of the mask's pixels in
    descending order (``ranked``, ``cell``, ``pos``, ``step`` as in
    :func:`_valley_peaks_loops`), the ``seeds`` (ranks) starting parts 1..n.  At each level,
    a pixel next to a labelled higher one takes the part of the highest such neighbour, and
    the part spreads breadth-first across the level (a plateau is shared by distance).  A
    pixel of the level left unlabelled (on the dome of a dropped peak) waits, grouped with
    its waiting neighbours (union-find); the first part that touches a group takes all of
    it.  Pixels of pieces of the mask no part reaches are left 0.  ``labels`` ``(h, w)``
    int32 zeros (``w`` = ``width``), written."""
    fv = vals.ravel()
    w = width
    n = ranked.shape[0]
    offsets = np.array([-step - 1, -step, -step + 1, -1, 1, step - 1, step, step + 1])
    lab = np.zeros(n, dtype=np.int32)       # a waiting pixel: 0, its group decides
    group = np.arange(n).astype(np.int32)   # union-find of the waiting pixels
    glab = np.zeros(n, dtype=np.int32)      # per group root: the part that took it
    for k in range(seeds.shape[0]):
        lab[seeds[k]] = k + 1
    queue = np.empty(n, dtype=np.int32)
    o = 0
    while o < n:
        level = fv[ranked[o]]
        e = o + 1
        while e < n and fv[ranked[e]] == level:
            e += 1
        head = 0
        tail = 0
        for a in range(o, e):
            if lab[a] > 0:                      # a seed
                queue[tail] = a
                tail += 1
                continue
            c = cell[a]
            best = a
            best_label = 0
            for t in range(8):
                q = pos[c + offsets[t]]
                if q < 0 or q >= o:
                    continue
                label = lab[q]
                if label == 0:
                    r = q
                    while group[r] != r:
                        group[r] = group[group[r]]
                        r = group[r]
                    label = glab[r]
                if label > 0 and q < best:
                    best = q
                    best_label = label
            if best_label > 0:
                lab[a] = best_label
                queue[tail] = a
                tail += 1
        while head < tail:
            a = queue[head]
            head += 1
            c = cell[a]
            for t in range(8):
                q = pos[c + offsets[t]]
                if q < 0 or q >= e or lab[q] > 0:
                    continue
                if q >= o:                      # the same level: spread
                    lab[q] = lab[a]
                    queue[tail] = q
                    tail += 1
                else:                           # a waiting dome: this part takes it
                    r = q
                    while group[r] != r:
                        group[r] = group[group[r]]
                        r = group[r]
                    if glab[r] == 0:
                        glab[r] = lab[a]
        for a in range(o, e):
            if lab[a] > 0:
                continue
            c = cell[a]
            for t in range(8):
                q = pos[c + offsets[t]]
                if q < 0 or q >= e or lab[q] > 0:
                    continue
                r = q
                while group[r] != r:
                    group[r] = group[group[r]]
                    r = group[r]
                ra = a
                while group[ra] != ra:
                    ra = group[ra]
                if r != ra:
                    group[r] = ra
        o = e
    # the waiting groups a part took; pieces of the mask no part reaches stay 0
    for o in range(n):
        if lab[o] == 0:
            r = o
            while group[r] != r:
                group[r] = group[group[r]]
                r = group[r]
            lab[o] = glab[r]
    out = labels.ravel()
    for o in range(n):
        out[ranked[o]] = lab[o]


def describe_parts(labels: np.ndarray, n: int) -> np.ndarray:
    """:func:`describe_pixels` sums of parts ``1..n`` of a label image, all in one scan:
    ``(n, 7)`` float64 rows ``(pixel count, sum of columns, sum of rows, min column, max
    column, min row, max row)`` (a part with no pixel has count 0)."""
    lab = np.ascontiguousarray(labels, dtype=np.int32)
    if lab.ndim != 2:
        raise ClusteringError(f"labels must be (h, w), got shape {lab.shape}")
    out = np.zeros((int(n), 7))
    kernels = _valley_kernels()
    (kernels[2] if kernels is not None else _describe_parts_loops)(lab, out)
    return out


def _describe_parts_loops(labels, out):
    """Loop of :func:`describe_parts`."""
    h, w = labels.shape
    n = out.shape[0]
    for k in range(n):
        out[k, 3] = w
        out[k, 5] = h
        out[k, 4] = -1.0
        out[k, 6] = -1.0
    for y in range(h):
        for x in range(w):
            k = labels[y, x] - 1
            if k < 0 or k >= n:
                continue
            out[k, 0] += 1.0
            out[k, 1] += x
            out[k, 2] += y
            out[k, 3] = min(out[k, 3], x)
            out[k, 4] = max(out[k, 4], x)
            out[k, 5] = min(out[k, 5], y)
            out[k, 6] = max(out[k, 6], y)


_VALLEY: list = []


def _valley_kernels():
    """``(peaks, flood, describe)`` loops of :func:`valley_split` and
    :func:`describe_parts` compiled with numba, or ``None`` (no numba, or
    ``MK_TRACKER_NO_NUMBA`` set)."""
    if not _VALLEY:
        try:
            numba = import_numba()
            _VALLEY.append((numba.njit(cache=True, nogil=True)(_valley_peaks_loops),
                            numba.njit(cache=True, nogil=True)(_valley_flood_loops),
                            numba.njit(cache=True, nogil=True)(_describe_parts_loops)))
        except ImportError:
            _VALLEY.append(None)
    return _VALLEY[0]


def load_valley_split() -> int:
    """Compile (or load from numba's cache) the loops of :func:`valley_split` and
    :func:`describe_parts` by splitting a constructed pair of touching blobs; returns the
    number of parts found (2).  Scenes without people who touch never reach them, so a warm-up
    that only runs a detector would leave the compile to the first crowd."""
    pair = np.zeros((20, 30), dtype=np.float32)
    pair[5:15, 2:12] = pair[5:15, 18:28] = 100.0
    pair[5:15, 12:18] = 40.0
    n, labels = valley_split(pair, pair > 0, 30.0)
    describe_parts(labels, n)
    return n
