"""People who stand still from the start: warm, person-sized regions that stay in place
(issue #19).  Not in Schizas et al. (2018).

The kernel covariance detector finds what *changes* between frames, so a person who stands
still in the same place for the whole clip (BU-TIV-lab: the man with crossed arms at the
back left, frames 0-561) is never detected, and no tracker can keep a track that was never
started.  Such a person is still *warm*: on the newest frame their pixels are dissimilar to
the scene background in the kernel's own sense, ``k(x, b) < 1/2`` with (3.6), i.e. warmer
than the background by the similarity radius ``r = sigma sqrt(2 ln 2)``, the test the
footprints already use.  The rule (``detector.still_people``, :class:`StillPeopleConfig`):

* at each full-frame pass, the connected regions of the newest frame's pixels warmer than
  the scene background (median of the frame) by ``r`` are candidates when they are clear
  of the image border (a cut-off region's shape is unknown), have an upright person's
  shape (:func:`~mk_tracker.detection.person_size.is_person_shaped` with the detector's
  ``person_aspect``), a height of ``min_height_ratio`` .. ``max_height_ratio`` times the
  mean height of the whole people this detector has detected (not one height per row:
  :class:`~mk_tracker.detection.person_size.PersonHeightModel` was tried first, but on
  BU-TIV-lab only about 10 detections in 560 frames are person-shaped and clear of the
  top and bottom, and its line read a negative height at the still man's row), a mean
  level above the background of at least ``min_warmth`` times that of the detected people,
  and no detection of this frame overlapping them at ``max_iou`` or more (else they are
  that detection's person);
* a candidate found again at the next full passes in the same place (IoU >=
  ``match_iou``) for ``min_time`` seconds is a still person, reported in every frame (also
  in tracking passes) except those in which a detection overlaps it at ``max_iou`` or more.
  At a full pass that does not find it alone (its warm pixels touch a neighbour's: one
  region) it is kept while its box is still warm at ``keep_fill`` of the share of pixels
  it held; otherwise it ends.
* ``persistent_passes`` (2; 0 = off): the candidates are also the connected regions of the
  pixels warm at this full pass *and* at the ``persistent_passes`` full passes before it
  (those not already found, at ``match_iou``, among this pass's regions, and only when the
  region of this pass's warm pixels that holds them is not itself of one person's shape
  and size: else they are the still core of that one person, e.g. a detected person who
  stands and talks).  A still person's pixels are warm at every pass, a
  person walking past is warm at other pixels from pass to pass, so the bridge of warm
  pixels that joins the two in one frame (one region, not person-shaped) is dropped, and
  the still one is found alone.  It is the "static foreground" of dual-background
  detection of abandoned objects (Porikli, Ivanov & Haga, EURASIP J. Adv. Signal Process.
  2008: a pixel that is foreground for a long time but not for a short one is static),
  with the kernel's warm test of (3.6) as the foreground and the full passes as the
  samples.  Its ``min_time`` clock starts at this pass, as any region's (starting it at the
  oldest pass of the window reported the persistent cores of people who stand and talk:
  commit 5d611ea, docs/benchmark_real_thermal.md).  The regions of this pass's warm pixels
  stay candidates as before, so a person who stops alone is not delayed by the window.
  Two neighbours who both stand still stay joined.

Without learnt people (no person-shaped detection yet) nothing is reported: size and warmth
are relative to the people this detector has seen move, not constants of one camera.  Warm
static objects of a person's shape and size (a heater, a coat on a stand) are reported too;
the ignore regions are there for known ones.  Measured in docs/benchmark_real_thermal.md,
"People who stand still from the start".
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np

from mk_tracker.boxes import iou
from mk_tracker.detection.person_size import is_person_shaped
from mk_tracker.parameters import parameter

__all__ = ["StillPeople", "StillPeopleConfig"]


@dataclass(frozen=True)
class StillPeopleConfig:
    """The constants of the rule (``detector.still_people.*``)."""

    enabled: bool = parameter(
        True, "report warm person-sized regions that stay in place for min_time, so that "
        "people who never move are detected (mk_tracker.detection.still_people; not in the "
        "paper)")
    min_time: float = parameter(
        2.0, "still_people: seconds a warm region must be found in the same place at the "
        "full-frame passes before it is reported", minimum=0.0, maximum=1e4)
    match_iou: float = parameter(
        0.5, "still_people: a region of a full pass is the same as one of the previous pass "
        "at this IoU or more", minimum=0.01, maximum=1.0)
    min_height_ratio: float = parameter(
        0.3, "still_people: a region at least this fraction of the learnt mean height of "
        "the detected whole people (far people are smaller)", minimum=0.0, maximum=10.0)
    max_height_ratio: float = parameter(
        1.5, "still_people: ... and at most this many times it", minimum=0.0, maximum=10.0)
    min_warmth: float = parameter(
        0.5, "still_people: the region's mean level above the background is at least this "
        "fraction of that of the detected people", minimum=0.0, maximum=10.0)
    max_iou: float = parameter(
        0.3, "still_people: a region that a detection of this frame overlaps at this IoU or "
        "more is that detection's and is not reported", minimum=0.0, maximum=1.0)
    keep_fill: float = parameter(
        0.7, "still_people: a reported region not found alone at a full pass (it touches a "
        "neighbour's warm pixels) is kept while its box is warm at this share of the "
        "pixels it held", minimum=0.0, maximum=10.0)
    persistent_passes: int = parameter(
        2, "still_people: candidates are also regions of the pixels warm at this full pass and "
        "at this many full passes before it, when this pass's region holding them is not one "
        "person (static foreground: drops a passer-by's warm pixels that join a still "
        "person's; chosen on the still-people and group choice seeds); 0: off",
        minimum=0, maximum=100)
    memory: float = parameter(
        300.0, "still_people: person samples (height, warmth) remembered, with "
        "exponential forgetting", minimum=1.0, maximum=1e6)


@dataclass
class _Region:
    box: tuple[float, float, float, float]
    since: float          # stamp of the first full pass that found it
    warmth: float         # mean level above the background
    pixels: int
    fill: float = 0.0     # share of the box's pixels in the region when it was found


def _overlapped(box, boxes, max_iou: float) -> bool:
    """Whether one of ``boxes`` overlaps ``box`` at ``max_iou`` or more."""
    return any(iou(box, other) >= max_iou for other in boxes)


class StillPeople:
    """The rule of the module docstring; the detector calls :meth:`step` once per frame
    with its detections of that frame."""

    def __init__(self, config: StillPeopleConfig, person_aspect: float) -> None:
        self.config = config
        self.person_aspect = float(person_aspect)
        self.decay = 1.0 - 1.0 / max(float(config.memory), 1.0)
        self._warmth = np.zeros(2)             # forgetting sums of (1, warmth) of people
        self._height = np.zeros(2)             # ... and of (1, height) of whole people
        self._regions: list[_Region] = []
        self._warm_masks: deque = deque(maxlen=max(int(config.persistent_passes), 0))

    @property
    def people_warmth(self) -> float | None:
        """Learnt mean level above the background of the detected people; None unlearnt."""
        n, s = self._warmth
        return float(s / n) if n >= 1.0 else None

    @property
    def people_height(self) -> float | None:
        """Learnt mean height of the detected whole people; None unlearnt."""
        n, s = self._height
        return float(s / n) if n >= 1.0 else None

    def step(self, frame: np.ndarray, radius: float, detections: list, stamp: float,
             full_pass: bool, make) -> list:
        """``detections`` plus the still people of this frame; ``make(box, score,
        pixels)`` builds a detection of the caller's type.  ``frame`` is the newest frame
        (raw levels, hot = high), ``radius`` the similarity radius of (3.6) in those units."""
        if not self.config.enabled:
            return detections
        boxes = [tuple(float(v) for v in d.box) for d in detections]
        background = float(np.median(frame[::4, ::4]))
        self._learn(frame, background, radius, boxes)
        if full_pass:
            self._find(frame, background, radius, boxes, stamp)
        c = self.config
        people = self.people_warmth
        out = list(detections)
        for reg in self._regions:
            if stamp - reg.since < c.min_time or people is None:
                continue
            if _overlapped(reg.box, boxes, c.max_iou):
                continue
            out.append(make(reg.box, float(min(1.0, reg.warmth / people)), reg.pixels))
        return out

    def _learn(self, frame: np.ndarray, background: float, radius: float, boxes) -> None:
        """Warmth from every detection (the mean level of its pixels warmer than the
        background by ``radius``, over the background); height from the person-shaped
        detections clear of the image's top and bottom (a cut-off person's height is not
        known)."""
        height = frame.shape[0]
        for x, y, w, h in boxes:
            x0, y0 = max(int(x), 0), max(int(y), 0)
            patch = frame[y0:int(y + h), x0:int(x + w)]
            warm = patch[patch > background + radius]
            if warm.size:
                self._warmth *= self.decay
                self._warmth += (1.0, float(warm.mean()) - background)
            if y >= 1.0 and y + h <= height - 1.0 and is_person_shaped(w, h,
                                                                      self.person_aspect):
                self._height *= self.decay
                self._height += (1.0, h)

    def _find(self, frame: np.ndarray, background: float, radius: float, boxes,
              stamp: float) -> None:
        c = self.config
        found: list[_Region] = []
        warm = frame > background + radius
        persistent = self._persistent(warm)
        if self.people_warmth is not None and self.people_height is not None:
            plain = cv2.connectedComponentsWithStats(warm.astype(np.uint8), connectivity=8)
            found = self._candidates(plain, frame, background, boxes, stamp)
            if persistent is not None:
                found += [reg for reg in self._candidates(
                              cv2.connectedComponentsWithStats(persistent.astype(np.uint8),
                                                               connectivity=8),
                              frame, background, boxes, stamp)
                          if not any(iou(reg.box, other.box) >= c.match_iou
                                     for other in found)
                          and not self._in_one_person(reg, plain)]
        kept = []
        for old in self._regions:
            best = max(found, key=lambda reg: iou(old.box, reg.box), default=None)
            if best is not None and iou(best.box, old.box) >= c.match_iou:
                best.since = min(best.since, old.since)
            elif stamp - old.since >= c.min_time and self._still_warm(frame, background,
                                                                      radius, old):
                kept.append(old)    # confirmed, now touching a neighbour's warm pixels
        self._regions = found + kept

    def _person_sized(self, w: float, h: float) -> bool:
        """An upright person's shape and a height of ``min_height_ratio`` ..
        ``max_height_ratio`` times the learnt one."""
        c = self.config
        return is_person_shaped(w, h, self.person_aspect) and (
            c.min_height_ratio * self.people_height <= h
            <= c.max_height_ratio * self.people_height)

    def _in_one_person(self, reg: _Region, plain) -> bool:
        """Whether the region of this pass's warm pixels that holds most of ``reg``'s box is
        itself of one person's shape and size: then the persistent region is the still core
        of that person (reported or not by the plain rule), not a person cut free from a
        neighbour's warm pixels."""
        _, labels, stats, _ = plain
        x, y, w, h = (int(v) for v in reg.box)
        inside = labels[y:y + h, x:x + w]
        ks, counts = np.unique(inside[inside > 0], return_counts=True)
        if not len(ks):
            return False
        _, _, pw, ph, _ = (int(v) for v in stats[int(ks[np.argmax(counts)])])
        return self._person_sized(pw, ph)

    def _candidates(self, components, frame: np.ndarray, background: float, boxes,
                    stamp: float) -> list[_Region]:
        """The connected regions (``cv2.connectedComponentsWithStats`` of a mask) that pass
        the tests of the module docstring."""
        c = self.config
        people = self.people_warmth
        out = []
        n, labels, stats, _ = components
        rows, cols = frame.shape
        for k in range(1, n):
            x, y, w, h, area = (int(v) for v in stats[k])
            if x <= 0 or y <= 0 or x + w >= cols or y + h >= rows:
                continue
            if not self._person_sized(w, h):
                continue
            box = (float(x), float(y), float(w), float(h))
            if _overlapped(box, boxes, c.max_iou):
                continue
            level = float(frame[y:y + h, x:x + w][labels[y:y + h, x:x + w] == k].mean())
            if level - background < c.min_warmth * people:
                continue
            out.append(_Region(box, stamp, level - background, area, area / (w * h)))
        return out

    def _persistent(self, warm: np.ndarray) -> np.ndarray | None:
        """``persistent_passes``: ``warm`` and the warm masks of that many previous full
        passes (fewer while they are not there yet); None when 0 or when there is no
        earlier pass."""
        if self._warm_masks.maxlen == 0:
            return None
        if any(m.shape != warm.shape for m in self._warm_masks):
            self._warm_masks.clear()
        out = warm.copy() if self._warm_masks else None
        for mask in self._warm_masks:
            out &= mask
        self._warm_masks.append(warm)
        return out

    def _still_warm(self, frame: np.ndarray, background: float, radius: float,
                    reg: _Region) -> bool:
        """``keep_fill``: whether a confirmed region's box is still warm (by the test that
        made the region) at that share of the pixels it held when found."""
        x, y, w, h = (int(v) for v in reg.box)
        patch = frame[y:y + h, x:x + w]
        return bool(patch.size) and float(np.mean(patch > background + radius)) >= (
            self.config.keep_fill * reg.fill)
