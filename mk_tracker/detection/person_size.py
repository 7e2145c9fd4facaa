"""Expected person size per image row, learnt online, and the split of a group's mask into
people by it (issues #13 and #15).

Both detectors report one box per connected foreground region; people who walk close
together make one region.  Under a camera looking at a ground plane, the image height of a
standing person is close to linear in the image row of their feet, so a region much wider
than one person at its row is a group:

* :class:`PersonHeightModel` fits ``h = a + b * y_bottom`` by least squares with
  exponential forgetting, from the boxes of *isolated* people (:func:`is_person_shaped`:
  an upright aspect ratio, so a fragment or a side-by-side group is not a sample);
* :func:`people_in_width` says how many people a region of a given width holds
  (``round(width / expected width)`` once it is ``split_ratio`` expected widths wide);
* :func:`projection_cuts` cuts the region at the emptiest columns of its mask (the vertical
  projection) near the evenly spaced positions; :func:`split_columns` takes one person
  fewer while a part would be narrower than a person.

The background-subtraction detector (:mod:`mk_tracker.detection.background_detector`) and the
thermal detector (:mod:`mk_tracker.detection.thermal_detector`, ``split_by_person_size``)
use them the same way.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PersonHeightModel", "is_person_shaped", "people_in_width", "projection_cuts",
           "split_columns"]


class PersonHeightModel:
    """``h = a + b * y_bottom`` fitted online by least squares with exponential forgetting
    (weights ``(1 - 1/memory)^age``); without enough spread in ``y`` it is the weighted mean
    height."""

    def __init__(self, memory: float) -> None:
        self.decay = 1.0 - 1.0 / max(float(memory), 1.0)
        self.sums = np.zeros(5)          # n, y, h, yy, yh

    @property
    def samples(self) -> float:
        return float(self.sums[0])

    def add(self, y_bottom: float, height: float) -> None:
        self.sums *= self.decay
        self.sums += (1.0, y_bottom, height, y_bottom * y_bottom, y_bottom * height)

    def height_at(self, y_bottom: float) -> float | None:
        """Expected height of a person whose feet are at row ``y_bottom``; None with fewer
        than about 3 samples."""
        n, sy, sh, syy, syh = self.sums
        if n < 2.5:
            return None
        var = syy / n - (sy / n) ** 2
        mean_h = sh / n
        if var < 1.0:                    # all samples on (nearly) one row
            return float(mean_h)
        b = (syh / n - (sy / n) * mean_h) / var
        return float(mean_h + b * (y_bottom - sy / n))


def is_person_shaped(width: float, height: float, aspect: float) -> bool:
    """Whether a ``width x height`` box is one upright person of width/height ``aspect``
    (between 0.6 and 1.5 times it): a size sample for :class:`PersonHeightModel`."""
    return 0.6 * aspect * height <= width <= 1.5 * aspect * height


def people_in_width(width: float, expected_width: float, split_ratio: float) -> int:
    """How many people side by side a region ``width`` wide holds: 1 up to ``split_ratio``
    expected widths, else ``round(width / expected_width)`` (at least 2)."""
    if not expected_width > 0 or width <= split_ratio * expected_width:
        return 1
    return max(2, int(round(width / expected_width)))


def projection_cuts(columns: np.ndarray, people: int) -> list[int]:
    """Cut positions (column indices, increasing) that split a region whose vertical
    projection is ``columns`` into ``people`` parts: near each evenly spaced position
    ``k * len / people`` (within a third of a part), the emptiest column; among equals the
    one nearest the even position."""
    n = len(columns)
    step = n / people
    window = max(1, int(step / 3))
    cuts: list[int] = []
    for k in range(1, people):
        centre = int(round(k * step))
        lo, hi = max(1, centre - window), min(n - 1, centre + window)
        if hi <= lo:
            continue
        candidates = np.arange(lo, hi)
        best = np.lexsort((np.abs(candidates - centre), columns[lo:hi]))[0]
        cut = int(candidates[best])
        if not cuts or cut > cuts[-1]:
            cuts.append(cut)
    return cuts


def split_columns(mask: np.ndarray, people: int, min_width: float = 0.0
                  ) -> list[tuple[int, int]]:
    """``(first, end)`` column ranges of a region's ``mask`` split into ``people`` parts at
    :func:`projection_cuts` of its column sums; ranges without a mask pixel are left out.

    ``min_width``: a part narrower than this is a limb or a shadow, not a person; the split
    is then tried with one person fewer, down to the whole region (one range).
    """
    columns = mask.sum(axis=0).astype(np.float64)
    for count in range(people, 1, -1):
        edges = [0] + projection_cuts(columns, count) + [mask.shape[1]]
        parts = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a and columns[a:b].any()]
        if len(parts) >= 2 and all(b - a >= min_width for a, b in parts):
            return parts
    filled = np.flatnonzero(columns)
    return [(int(filled[0]), int(filled[-1]) + 1)] if filled.size else []
