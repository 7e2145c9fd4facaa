"""How the thermal detector splits one footprint into people: along its intensity valleys
(``split_by_valleys``) or by the expected person width at its row (``split_by_person_size``,
:mod:`mk_tracker.detection.person_size`).  Neither is in Schizas et al. (2018); both are
switchable, and the module docstring of :mod:`mk_tracker.detection.thermal_detector` says
where they act in Algorithm 2.

:class:`FootprintSplitting` is a mixin of
:class:`~mk_tracker.detection.thermal_detector.ThermalDetector`: its methods use the
detector's configuration, its normalisation map and its footprint search.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mk_tracker.detection.block_support import SupportResult
from mk_tracker.detection.footprint import (_UNSET, _VoronoiCell, _median, _owned_support,
                                            _similarity_radius)
from mk_tracker.detection.person_size import (is_person_shaped, parts_are_people,
                                              people_in_width, split_columns, valley_columns)
from mk_tracker.detection.pixel_clustering import describe_parts, describe_pixels, valley_split

__all__ = ["FootprintSplitting"]


@dataclass
class _Candidate:
    """One object found in a pass.  ``level``: the mean newest-frame value (as stored) of
    its footprint pixels; ``local``: the local background its footprint was found against
    (median of the non-support pixels of the footprint's search patch); both NaN when not
    computed (tracking passes, swept support)."""

    centroid: tuple[float, float]
    box: tuple[float, float, float, float]
    score: float
    pixel_count: int
    level: float = math.nan
    local: float = math.nan


def _footprint_levels(frame: np.ndarray, support: np.ndarray,
                      footprint: tuple[tuple[int, int], np.ndarray]) -> tuple[float, float]:
    """``(level, local)`` of :class:`_Candidate` for the footprint ``((y0, x0), mask)``,
    ``mask`` covering the footprint's search patch."""
    (y0, x0), mask = footprint
    patch = (slice(y0, y0 + mask.shape[0]), slice(x0, x0 + mask.shape[1]))
    values = frame[patch]
    rest = values[~support[patch]]
    local = float(_median(rest)) if rest.size else math.nan
    return float(values[mask].mean()), local


class FootprintSplitting:
    """Footprint splitting and the person-size model's samples (mixin)."""

    def _learn_sizes(self, detections: list[Any]) -> list[Any]:
        """split_by_person_size, split_clusters or person_cover: person-size samples from
        the person-shaped detections;
        after a tracking pass, whether a detection is as wide as several people (two people
        met: the next full-frame pass, which splits it, comes ``group_recheck_frames``
        after the last one instead of ``reconfigure_period``).  A box that touches the top
        or bottom of the image is neither: its person is cut off, so neither its height
        nor the row of its feet is known."""
        c = self.config
        if not (c.split_by_person_size or (c.split_clusters and c.current_frame_refinement)
                or c.person_cover.enabled):
            return detections
        group = False
        for d in detections:
            x, y, w, h = d.box
            if not self._whole_height(y, h):
                continue
            if is_person_shaped(w, h, c.person_aspect):
                self.heights.add(y + h, h)
                self._add_aspect(w, h)
                self._note_size_object(d.object_id)
            elif not group:
                expected = self.heights.height_at(y + h)
                group = expected is not None and people_in_width(
                    w, c.person_aspect * expected, c.split_ratio) > 1
        # (the person cover needs no early full-frame pass: it covers groups every frame)
        self._group_seen = group and self.last_mode == "tracking" and (
            c.split_by_person_size or c.split_clusters)
        return detections

    def _note_size_object(self, object_id: int) -> None:
        """Record that the newest size sample came from detector object ``object_id`` (-1:
        none); objects whose latest sample is a whole ``size_memory`` of samples old are
        dropped, as the size model has mostly forgotten them (weight below 1/e)."""
        self._size_samples += 1
        if object_id >= 0:
            self.size_objects[object_id] = self._size_samples
        horizon = self._size_samples - self.config.size_memory
        for oid in [o for o, n in self.size_objects.items() if n <= horizon]:
            del self.size_objects[oid]

    def sampled_objects(self) -> int:
        """How many detector objects the size model's remembered samples came from: those
        with a sample in the last ``size_memory`` samples (the others were dropped when the
        newest sample came)."""
        return len(self.size_objects)

    def _whole_height(self, y: float, h: float) -> bool:
        """Whether a box ``y .. y + h`` is clear of the image's top and bottom rows."""
        return y >= 1.0 and y + h <= self._shape[0] - 1.0

    def _group_footprint(self, frame: np.ndarray, result: SupportResult, rows: np.ndarray,
                         cols: np.ndarray, bounds: tuple[int, int, int, int],
                         footprint: Any) -> Any:
        """The group's newest-frame footprint: ``footprint`` when the caller has it, else
        searched now; None when it has none."""
        if footprint is _UNSET:
            return self._footprint(frame, result.support, rows, cols, bounds)
        return footprint

    def _valley_candidates(self, frame: np.ndarray, result: SupportResult, rows: np.ndarray,
                           cols: np.ndarray, bounds: tuple[int, int, int, int],
                           footprint: Any) -> list[_Candidate]:
        """Detections of one group's footprint split along its intensity valleys
        (:meth:`_valley_parts`): touching people whose footprints fused are one part each; a
        footprint with one peak is one detection, as :meth:`_candidate` gives it."""
        c = self.config
        fp = self._group_footprint(frame, result, rows, cols, bounds, footprint)
        if fp is None:
            return []
        score = float(min(1.0, result.variance[rows, cols].mean() / 0.5))
        parts = self._valley_parts(frame, fp)
        if parts is None:
            (y0, x0), mask = fp
            fr, fc = np.nonzero(mask)
            if fr.size < c.min_object_pixels:
                return []
            now = describe_pixels(fc + x0, fr + y0)
            parts = [(now.centroid, now.box, now.pixel_count)]
        levels = _footprint_levels(frame, result.support, fp)
        return [_Candidate(centroid, box, score, n, *levels) for centroid, box, n in parts]

    def _size_candidates(self, frame: np.ndarray, result: SupportResult, rows: np.ndarray,
                         cols: np.ndarray, bounds: tuple[int, int, int, int],
                         footprint: Any) -> list[_Candidate]:
        """Detections of one group's footprint split by the expected person width at its
        bottom row (:mod:`mk_tracker.detection.person_size`): one per person side by side,
        cut at the emptiest columns; one detection, as :meth:`_candidate` gives it, while
        the footprint is no wider than ``split_ratio`` persons or no size is known (not yet
        learnt, or refused by the size check: ``size_max_residual``), and while a part is
        shorter than ``min_part_height_fraction`` expected heights at its own row
        (:func:`~mk_tracker.detection.person_size.parts_are_people`)."""
        c = self.config
        fp = self._group_footprint(frame, result, rows, cols, bounds, footprint)
        if fp is None:
            return []
        (y0, x0), mask = fp
        fr, fc = np.nonzero(mask)
        if fr.size < c.min_object_pixels:
            return []
        score = float(min(1.0, result.variance[rows, cols].mean() / 0.5))
        now = describe_pixels(fc + x0, fr + y0)
        levels = _footprint_levels(frame, result.support, fp)
        x, y, w, h = now.box
        expected = self.heights.height_at(y + h) if self._whole_height(y, h) else None
        people = 1 if expected is None else people_in_width(w, c.person_aspect * expected,
                                                            c.split_ratio)
        if people == 1:
            return [_Candidate(now.centroid, now.box, score, now.pixel_count, *levels)]
        first, end = int(fc.min()), int(fc.max()) + 1
        out = []
        expected_width = c.person_aspect * expected
        for a, b in split_columns(mask[:, first:end], people,
                                  c.min_part_fraction * expected_width):
            pr, pc = np.nonzero(mask[:, first + a:first + b])
            if pr.size < c.min_object_pixels:
                continue
            part = describe_pixels(pc + x0 + first + a, pr + y0)
            out.append(_Candidate(part.centroid, part.box, score, part.pixel_count, *levels))
        if len(out) > 1 and not parts_are_people([p.box for p in out], self.heights.height_at,
                                                 c.min_part_height_fraction):
            return [_Candidate(now.centroid, now.box, score, now.pixel_count, *levels)]
        return out

    def _valley_parts(self, frame: np.ndarray, footprint: tuple[tuple[int, int], np.ndarray]
                      ) -> list[tuple[tuple[float, float], tuple[float, float, float, float],
                                      int]] | None:
        """``(centroid, box, pixel_count)`` of each part of a footprint split along its
        intensity valleys (:func:`mk_tracker.detection.pixel_clustering.valley_split` with depth = the
        kernel's similarity radius, so each part is dissimilar, k < 1/2, to the valley that
        separates it); parts smaller than ``min_object_pixels`` are left out.  ``None``
        when the footprint has one peak (it does not split).  With ``valley_columns`` the
        parts are upright people's column ranges
        (:func:`~mk_tracker.detection.person_size.valley_columns`), ``None`` when all its
        parts are stacked in one."""
        c = self.config
        (y0, x0), mask = footprint
        h, w = mask.shape
        patch = frame[y0:y0 + h, x0:x0 + w]
        # the side of the background the footprint is on (all of it is on one side): its
        # mean against the median of the patch's border pixels off the footprint
        ring = np.concatenate([patch[0], patch[-1], patch[1:-1, 0], patch[1:-1, -1]])
        off = ring[~np.concatenate([mask[0], mask[-1], mask[1:-1, 0], mask[1:-1, -1]])]
        polarity = 1.0
        if off.size:
            polarity = 1.0 if float(patch[mask].mean()) >= float(_median(off)) else -1.0
        depth = _similarity_radius(self._bandwidth.sigma2) / self._map[1]          # window units
        n, labels = valley_split(patch * np.float32(polarity), mask, depth,
                                 min_area=c.min_object_pixels,
                                 min_peak_fraction=c.valley_min_peak_fraction)
        if n <= 1:
            return None
        out = []
        if c.valley_columns:
            ranges = valley_columns(labels, n, c.valley_column_overlap,
                                    patch * np.float32(polarity), depth)
            if len(ranges) < 2:
                return None
            for a, b in ranges:
                pr, pc = np.nonzero(mask[:, a:b])
                if pr.size < c.min_object_pixels:
                    continue
                part = describe_pixels(pc + x0 + a, pr + y0)
                out.append((part.centroid, part.box, part.pixel_count))
            return out
        for cnt, sx, sy, xmin, xmax, ymin, ymax in describe_parts(labels, n).tolist():
            if cnt < c.min_object_pixels:
                continue
            out.append(((sx / cnt + 0.5 + x0, sy / cnt + 0.5 + y0),
                        (float(xmin + x0), float(ymin + y0), float(xmax + 1 - xmin),
                         float(ymax + 1 - ymin)), int(cnt)))
        return out

    def _split_grown(self, frame: np.ndarray, result: SupportResult, regions: list,
                     centres: np.ndarray, k: int, cand: _Candidate,
                     owned: tuple[int, np.ndarray, np.ndarray] | None = None) -> _Candidate:
        """Tracking pass: object ``k``'s footprint grew past ``valley_grow_ratio`` times its
        last box or its box at the last full-frame pass (it fused with someone it touches):
        the part of the footprint, split along its valleys, nearest its prediction
        (``cand`` when it does not split).  ``owned``: object ``k``'s entry of
        :func:`_owned_support` when the caller has it (the numpy path); the compiled path
        does not keep the owned pixels, so they are found again here."""
        if owned is None:
            only = [r if j == k else None for j, r in enumerate(regions)]
            owned = _owned_support(result.support, only, centres)[k]
        _, rows, cols = owned
        if rows.size < self.config.min_object_pixels:
            return cand
        cell = _VoronoiCell(centres, k) if len(centres) > 1 else None
        fp = self._footprint(frame, result.support, rows, cols, regions[k], cell)
        if fp is None:
            return cand
        parts = self._valley_parts(frame, fp)
        if not parts:
            return cand
        px, py = centres[k]
        centroid, box, n = min(parts, key=lambda q: math.dist(q[0], (px, py)))
        return _Candidate(centroid, box, cand.score, n)
