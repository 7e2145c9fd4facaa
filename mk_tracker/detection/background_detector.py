"""People in a static RGB (or grey) camera by background subtraction: the automatic front end
of Chu et al. (2013), Sec. IV-D and Fig. 8 ("from the background subtraction to the end of
tracking, everything is fully automatic"), for users with no thermal camera (issue #13).

The per-pixel background model is OpenCV's (a maintained implementation): MOG2, the
adaptive Gaussian mixture of Zivkovic (2004, 2006), or KNN (Zivkovic & van der Heijden
2006), chosen by ``model``.  Shadows and highlights (``shadow_method``): the model's own test (it
marks shadows 127, dropped), or the brightness/chromaticity ratio test of
:mod:`mk_tracker.detection.shadows` against the model's background image.
This module turns the foreground mask into one box per person:

0. **Start-up without a clean background** (``bootstrap_frames``).  The first frames after
   a (re)start are buffered; their per-pixel temporal median is the first background (a
   standard background initialisation: a person who moves covers a pixel in fewer than
   half of the frames), handed to the model with learning rate 1, and the model then learns
   the background's spread from the buffered frames with their foreground (pixels far from
   the median, ``bootstrap_tolerance``) replaced by the median.  Online: no future frame.
1. **Working scale.**  Frames wider than ``max_width`` are reduced first (area averaging):
   the mask of a person needs no more pixels than that, and the cost falls with the square.
2. **Global change.**  When more than ``max_foreground_fraction`` of the frame is foreground
   (lights switched on, the camera moved), the model is restarted from this frame, the event
   counted (:attr:`global_changes`) and no box is reported for the frame, instead of one
   frame-sized detection flooding the tracker.
3. **Morphology sized to a person.**  An opening of ``open_fraction`` of the smallest
   person's width (at least ``min_open`` px) removes speckle; fragments of one person (cut
   by a thin occluder, or clothes like the background) are grouped by a dilation of half
   the smallest person's size, each group's box being that of its own foreground pixels.
4. **Person size per image row, learnt online.**  A component whose aspect ratio is that of
   one upright person gives a sample (bottom row, height); a line ``h = a + b * y_bottom``
   is fitted to them by least squares with exponential forgetting (``size_memory``): under a
   ground-plane camera a person's image height is close to linear in the row of the feet.
   A box shorter than ``min_height_ratio`` of the height learnt at its row is a fragment
   or speckle: it is dropped and not learnt (most false boxes on the TUD clips were such).
5. **Joining.**  Two boxes that overlap horizontally and are separated vertically by less
   than ``join_gap`` of the expected height are one person broken apart.
6. **Splitting groups.**  A component wider than ``split_ratio`` expected person widths is
   cut into ``round(width / expected width)`` people at the minima of the mask's vertical
   projection (column sums) near the evenly spaced cut positions; each part's box is then
   tightened to its own foreground rows.
7. **Trimming.**  Columns at a box's sides holding less than ``column_trim`` of its fullest
   column's foreground (a stride's leg, a swinging arm) are cut off the box.
8. **Start-up in seconds** (``counts_fps``).  ``bootstrap_frames`` and ``startup_frames``
   are counted at ``counts_fps`` frames per second and converted to the same durations at
   the frame rate measured from the stamps (the median of the last ``rate_window`` stamp
   differences, at most ``max_frame_rate``): at 6.25 fps the start-up lasts 3 frames
   (0.4 s), not 10 (1.6 s, most of a short clip).  ``history`` and ``learning_rate`` stay
   per frame: converting them too lost on the generated 7-fps scene (walkers who stop
   became background sooner) and did not help the real 6.25-fps checks
   (docs/benchmark_background_detector.md).

People who stand still become background and are no longer detected: with OpenCV's
background ratio (0.9) a still colour joins the background after about ``0.1 * history``
frames at the automatic learning rate; the tracker keeps their tracks by coasting (its lifecycle), as for any missed
detection.  Bad input: a frame of another size restarts the model (:attr:`last_event` says
why); a stamp going backwards restarts it too; a repeated stamp is skipped
(``last_mode == "out_of_order"``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from scipy import ndimage

from mk_tracker.detection.person_size import (PersonHeightModel, is_person_shaped,
                                              people_in_width, split_columns)
from mk_tracker.detection.shadows import shadow_or_highlight
from mk_tracker.detection.thermal_image import ThermalInputError
from mk_tracker.parameters import parameter, validate_config
from mk_tracker.stamps import FrameRate, checked_stamp

MODELS = ("mog2", "knn")
SHADOW_METHODS = ("model", "ratio", "none")
SHADOW_VALUE = 127


@dataclass(frozen=True)
class BackgroundDetectorConfig:
    """Constants of the background-subtraction detector (``background.*`` parameters)."""

    model: str = parameter("mog2", "Per-pixel background model: OpenCV MOG2 (Gaussian "
                           "mixture) or KNN", choices=MODELS)
    history: int = parameter(500, "Frames the background model remembers (a person standing "
                             "still for about a tenth of this becomes background)", minimum=2,
                             maximum=100_000)
    var_threshold: float = parameter(
        16.0, "Foreground threshold: squared Mahalanobis distance (MOG2) or squared distance "
        "(KNN uses 25x this value, its own default scale)", minimum=1.0, maximum=10_000.0)
    shadow_method: str = parameter(
        "model", "Shadow and highlight test: the model's own (MOG2/KNN detectShadows with "
        "shadow_threshold), the brightness/chromaticity ratio test of Horprasert et al. 1999 "
        "against the background image (shadow_min_ratio .. shadow_max_ratio, "
        "highlight_ratio, shadow_max_chroma), or none", choices=SHADOW_METHODS)
    shadow_threshold: float = parameter(
        0.7, "Shadow test of the model: a darker pixel whose brightness ratio to the "
        "background is at least this is a shadow and dropped (higher: fewer shadows, so dark "
        "clothes are not taken for shadows)", minimum=0.0, maximum=1.0)
    shadow_min_ratio: float = parameter(
        0.5, "Ratio test: smallest brightness ratio to the background of a shadow pixel",
        minimum=0.0, maximum=1.0)
    shadow_max_ratio: float = parameter(
        0.95, "Ratio test: largest brightness ratio to the background of a shadow pixel",
        minimum=0.0, maximum=1.0)
    highlight_ratio: float = parameter(
        1.0, "Ratio test: a pixel brighter than the background by at most this ratio, with "
        "its colour, is a highlight and dropped (1 = no highlight test)", minimum=1.0,
        maximum=10.0)
    shadow_max_chroma: float = parameter(
        0.1, "Ratio test: largest chromaticity distortion |I - aB| / (a|B|) of a shadow or "
        "highlight pixel (colour unchanged)", minimum=0.0, maximum=10.0)
    learning_rate: float = parameter(
        -1.0, "Model learning rate per frame; -1 = 1/min(2 n, history) after n frames "
        "(OpenCV's automatic rate)", minimum=-1.0, maximum=1.0)
    bootstrap_frames: int = parameter(
        10, "Frames buffered after a (re)start whose per-pixel temporal median becomes the "
        "first background (people who move are not in the median); the model learns its "
        "spread from those frames with their foreground replaced by the median.  0 = learn "
        "from the frames as they come", minimum=0, maximum=1000)
    bootstrap_tolerance: float = parameter(
        25.0, "Bootstrap: a buffered pixel differing from the median by more than this "
        "(grey levels, any channel) is foreground and replaced by the median", minimum=1.0,
        maximum=255.0)
    startup_frames: int = parameter(10, "Frames after a (re)start before boxes are reported "
                                    "(the model learns the background first; counts the "
                                    "bootstrap frames)", minimum=0, maximum=10_000)
    max_width: int = parameter(320, "Frames wider than this are reduced before the model "
                               "(px; speed)", minimum=32, maximum=10_000)
    max_foreground_fraction: float = parameter(
        0.5, "Foreground share of the frame above which the scene changed globally (lights, "
        "camera moved): the model restarts, no box", minimum=0.01, maximum=1.0)
    min_person_height: float = parameter(
        24.0, "Smallest person height in the full image, px (sizes the morphology and the "
        "smallest box)", minimum=2.0, maximum=10_000.0)
    person_aspect: float = parameter(0.4, "Width / height of one upright person",
                                     minimum=0.1, maximum=2.0)
    open_fraction: float = parameter(
        0.1, "Side of the square opening that removes speckle, as a share of the smallest "
        "person's width (min_person_height x person_aspect)", minimum=0.0, maximum=1.0)
    min_open: int = parameter(
        1, "Smallest side of that opening, px at the working scale (3 removes the one- and "
        "two-row streaks of interlaced video; 1 = none)", minimum=1, maximum=31)
    min_height_ratio: float = parameter(
        0.8, "A box shorter than this share of the person height learnt at its row is "
        "dropped (and not learnt); 0 = only min_person_height applies", minimum=0.0,
        maximum=1.0)
    column_trim: float = parameter(
        0.2, "Columns at the sides of a box holding less than this share of its fullest "
        "column's foreground are trimmed (a stride's leg, a swinging arm); 0 = off",
        minimum=0.0, maximum=1.0)
    min_fill: float = parameter(0.1, "Smallest share of foreground pixels in a box",
                                minimum=0.0, maximum=1.0)
    join_gap: float = parameter(0.1, "Largest vertical gap, in expected person heights, "
                                "between two parts joined into one person", minimum=0.0,
                                maximum=2.0)
    split_ratio: float = parameter(1.6, "A blob wider than this many expected person widths "
                                   "is split into several people", minimum=1.0, maximum=10.0)
    size_memory: float = parameter(
        500.0, "Person-size samples remembered by the per-row height model (exponential "
        "forgetting)", minimum=1.0, maximum=1e6)
    counts_fps: float = parameter(
        25.0, "Frame rate at which bootstrap_frames and startup_frames are counted: at "
        "another frame rate (measured from the stamps) they are converted to the same "
        "durations in seconds (0 = frames at any rate)", minimum=0.0, maximum=1000.0)
    rate_window: int = parameter(25, "Stamp differences whose median is the measured frame "
                                 "rate (counts_fps)", minimum=1, maximum=10_000)
    max_frame_rate: float = parameter(
        1000.0, "Highest frame rate taken from the stamps for counts_fps (stamps closer than "
        "this are broken, not a faster camera: the start-up stays bounded)", minimum=1.0,
        maximum=1e6)


@dataclass(frozen=True)
class ForegroundDetection:
    """One person: ``box`` ``(x, y, w, h)`` in full-image pixels, ``score`` = share of
    foreground pixels in the box, ``pixel_count`` foreground pixels (working scale)."""

    box: tuple[float, float, float, float]
    score: float
    pixel_count: int


class BackgroundDetector:
    """Background subtraction + person-shaped boxes; same ``process`` interface as the
    thermal detectors."""

    def __init__(self, config: BackgroundDetectorConfig | None = None) -> None:
        self.config = config if config is not None else BackgroundDetectorConfig()
        validate_config(self.config)
        self.heights = PersonHeightModel(self.config.size_memory)
        self.global_changes = 0
        self.restarts = 0
        self.last_mode = "startup"
        self.last_event: str | None = None
        self._shape: tuple[int, ...] | None = None
        self._last_stamp: float | None = None
        self._model: Any = None
        self._since_restart = 0
        self._mono16_map: tuple[float, float] | None = None
        self._buffer: list[np.ndarray] = []
        self._seeded = False
        #: the frame rate from the last ``rate_window`` stamp differences
        self._rate = FrameRate(self.config.rate_window, self.config.max_frame_rate)

    # -- frame rate ----------------------------------------------------------------------
    def frames_for(self, count: int) -> int:
        """``count`` frames counted at ``counts_fps``, in frames at the measured frame rate
        (the same duration in seconds); ``count`` itself with ``counts_fps`` 0 or before two
        stamps gave a rate.  A positive count stays at least 1 frame."""
        return self._rate.frames(count, self.config.counts_fps)

    # -- model ---------------------------------------------------------------------------
    def _new_model(self) -> Any:
        c = self.config
        own_shadows = c.shadow_method == "model"
        if c.model == "knn":
            model = cv2.createBackgroundSubtractorKNN(history=c.history,
                                                      dist2Threshold=25.0 * c.var_threshold,
                                                      detectShadows=own_shadows)
        else:
            model = cv2.createBackgroundSubtractorMOG2(history=c.history,
                                                       varThreshold=c.var_threshold,
                                                       detectShadows=own_shadows)
        model.setShadowThreshold(float(c.shadow_threshold))
        return model

    def reset(self) -> None:
        """Forget the background (the person-size model is kept: the camera is the same)."""
        self._model = self._new_model()
        self._since_restart = 0
        self._mono16_map = None
        self._buffer = []
        self._seeded = self.config.bootstrap_frames == 0
        self.restarts += 1

    def _seed(self) -> None:
        """Start the model from the temporal median of the buffered frames, then let it learn
        the background's spread from those frames with their foreground (pixels far from the
        median) replaced by the median, so that people present from the first frame are not
        learnt as background."""
        stack = np.stack(self._buffer)
        median = np.median(stack, axis=0).astype(np.uint8)
        self._model.apply(median, learningRate=1.0)        # OpenCV: rate 1 re-initialises
        tol = self.config.bootstrap_tolerance
        for frame in self._buffer:
            diff = cv2.absdiff(frame, median)
            far = (diff.max(axis=2) if diff.ndim == 3 else diff) > tol
            clean = frame.copy()
            clean[far] = median[far]
            self._model.apply(clean, learningRate=-1.0)        # OpenCV: 1 / (2 n)
        self._buffer = []
        self._seeded = True

    def _update(self, small: np.ndarray) -> np.ndarray | None:
        """Feed one working-scale frame; the model's raw mask, or None while the bootstrap
        buffers frames (the frame that completes the buffer is already measured)."""
        self._since_restart += 1
        if not self._seeded:
            self._buffer.append(small)
            if len(self._buffer) < self.frames_for(self.config.bootstrap_frames):
                return None
            self._seed()
        return self._model.apply(small, learningRate=self.config.learning_rate)

    def _foreground(self, small: np.ndarray, raw: np.ndarray) -> np.ndarray:
        """Foreground mask (0/1) without shadows and highlights."""
        mask = (raw == 255).astype(np.uint8)
        if self.config.shadow_method == "ratio" and mask.any():
            c = self.config
            drop = shadow_or_highlight(small, self._model.getBackgroundImage(), mask,
                                       c.shadow_min_ratio, c.shadow_max_ratio,
                                       c.highlight_ratio, c.shadow_max_chroma)
            mask[drop] = 0
        return mask

    # -- input ---------------------------------------------------------------------------
    def _as_uint8(self, frame: np.ndarray, encoding: str | None) -> np.ndarray:
        arr = np.asarray(frame)
        if arr.ndim == 3 and arr.shape[2] == 4:
            arr = arr[:, :, :3]
        if encoding in ("rgb8", "rgba8"):
            arr = arr[:, :, ::-1]
        if arr.dtype == np.uint8:
            return np.ascontiguousarray(arr)
        if arr.dtype == np.uint16 or arr.dtype.kind == "f":
            if self._mono16_map is None:       # fixed after a restart: no flicker
                finite = arr[np.isfinite(arr)] if arr.dtype.kind == "f" else arr
                if finite.size == 0:
                    raise ThermalInputError("frame has no finite pixel")
                lo, hi = np.percentile(finite, (0.5, 99.5))
                self._mono16_map = (float(lo), 255.0 / max(float(hi - lo), 1e-6))
            lo, scale = self._mono16_map
            out = np.nan_to_num((arr.astype(np.float32) - lo) * scale, nan=0.0)
            return np.clip(out, 0, 255).astype(np.uint8)
        raise ThermalInputError(f"unsupported pixel type {arr.dtype}")

    # -- per frame -----------------------------------------------------------------------
    def process(self, frame: Any, stamp: float, encoding: str | None = None
                ) -> list[ForegroundDetection]:
        """People in ``frame`` (BGR/RGB/grey, 8 or 16 bit) taken at ``stamp`` seconds."""
        t = checked_stamp(stamp, ThermalInputError)
        self.last_event = None
        if self._last_stamp is not None and t == self._last_stamp:
            self.last_mode = "out_of_order"
            return []
        image = self._as_uint8(frame, encoding)
        if self._model is None:
            self.reset()
        elif image.shape != self._shape:
            self.last_event = (f"frame {image.shape[1]}x{image.shape[0]} differs from the "
                               f"previous {self._shape[1]}x{self._shape[0]}: background "
                               "model restarted")
            self.reset()
        elif self._last_stamp is not None and t < self._last_stamp:
            self.last_event = "time went backwards: background model restarted"
            self.reset()
        elif self._last_stamp is not None and self.config.counts_fps > 0.0:
            self._rate.add(t - self._last_stamp)
        self._shape = image.shape
        self._last_stamp = t
        height, width = image.shape[:2]
        scale = min(1.0, self.config.max_width / float(width))
        small = image if scale >= 1.0 else cv2.resize(
            image, (max(1, round(width * scale)), max(1, round(height * scale))),
            interpolation=cv2.INTER_AREA)
        raw = self._update(small)
        if raw is None:
            self.last_mode = "startup"
            return []
        moving = float(np.count_nonzero(raw == 255)) / raw.size
        startup = self.frames_for(self.config.startup_frames)
        if self._since_restart > startup and \
                moving > self.config.max_foreground_fraction:
            self.global_changes += 1
            self.last_event = (f"{100 * moving:.0f} % of the frame changed at once: "
                               "background model restarted")
            self.reset()
            if self.config.bootstrap_frames > 0:
                self._update(small)                       # the first bootstrap frame
            else:
                self._model.apply(small, learningRate=1.0)
                self._since_restart = 1
            self.last_mode = "global_change"
            return []
        if self._since_restart <= startup:
            self.last_mode = "startup"
            return []
        mask = self._foreground(small, raw)
        self.last_mode = "tracking"
        boxes = self._person_boxes(mask, scale)
        inv = 1.0 / scale
        return [ForegroundDetection((x * inv, y * inv, w * inv, h * inv), fill, count)
                for (x, y, w, h), fill, count in boxes]

    # -- mask -> people --------------------------------------------------------------------
    def _person_boxes(self, mask: np.ndarray, scale: float
                      ) -> list[tuple[tuple[float, float, float, float], float, int]]:
        c = self.config
        min_h = c.min_person_height * scale
        min_w = max(1.0, c.person_aspect * min_h)
        # speckle and thin streaks (interlacing, a flickering edge) go by an opening sized to
        # the smallest person (sizing it by the learnt size fed wrong sizes back: worse)
        k_open = max(c.min_open, int(round(c.open_fraction * min_w)))
        if k_open > 1:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((k_open, k_open), np.uint8))
        # fragments of one person (clothes like the background, a thin occluder) are grouped
        # by a person-sized dilation; each group's box is that of its own foreground pixels
        k_group = (max(3, int(round(min_w / 2.0)) | 1), max(3, int(round(min_h / 2.0)) | 1))
        grouping = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_RECT, k_group))
        n, labels = cv2.connectedComponents(grouping, connectivity=8)
        labels = np.where(mask > 0, labels, 0)
        min_area = 0.3 * min_w * min_h
        # each group's pixel count and the bounds of its own foreground pixels, in one pass
        # over the image each (a pass per group cost 60 % of a crowded TUD frame)
        counts = np.bincount(labels.ravel(), minlength=n)
        parts = []
        for i, found in enumerate(ndimage.find_objects(labels, max_label=n - 1), start=1):
            if found is None or counts[i] < 0.15 * min_w * min_h:
                continue
            rows, cols = found
            parts.append((float(cols.start), float(rows.start), float(cols.stop - cols.start),
                          float(rows.stop - rows.start)))
        parts = self._join(parts, min_h / scale, scale)
        out = []
        for box in parts:
            for sub in self._split(mask, box, scale):
                if c.column_trim > 0.0:
                    sub = self._trim_columns(mask, sub)
                x, y, w, h = sub
                if h < 0.5 * min_h or w * h < min_area:
                    continue
                expected = self._expected_height(y + h, scale)
                if expected is not None and h < c.min_height_ratio * expected:
                    continue      # a fragment or speckle: neither a person nor a size sample
                x0, y0 = int(x), int(y)
                count = int(mask[y0:y0 + int(h), x0:x0 + int(w)].sum())
                fill = count / max(w * h, 1.0)
                if fill < c.min_fill:
                    continue
                self._learn(sub, scale)
                out.append((sub, min(1.0, fill), count))
        return out

    def _trim_columns(self, mask: np.ndarray, box: tuple) -> tuple:
        """The box narrowed to the columns holding at least ``column_trim`` of its fullest
        column's foreground: a stride's leg or a swinging arm widens the mask's extent well
        beyond the body."""
        x, y, w, h = box
        x0, y0 = int(x), int(y)
        cols = mask[y0:y0 + int(h), x0:x0 + int(w)].sum(axis=0)
        if cols.size == 0 or cols.max() == 0:
            return box
        keep = np.flatnonzero(cols >= self.config.column_trim * cols.max())
        return (float(x0 + keep[0]), y, float(keep[-1] + 1 - keep[0]), h)

    def _expected_height(self, y_bottom: float, scale: float) -> float | None:
        """Expected person height (working scale) with feet at ``y_bottom`` (working scale)."""
        h = self.heights.height_at(y_bottom / scale)
        if h is None:
            return None
        return max(h, self.config.min_person_height) * scale

    def _learn(self, box: tuple[float, float, float, float], scale: float) -> None:
        x, y, w, h = box
        if is_person_shaped(w, h, self.config.person_aspect) and \
                h / scale >= self.config.min_person_height:
            # one upright person (not a fragment): a size sample
            self.heights.add((y + h) / scale, h / scale)

    def _join(self, boxes: list, _min_h_full: float, scale: float) -> list:
        """Merge parts stacked vertically with a small gap (a person broken apart)."""
        boxes = sorted(boxes, key=lambda b: b[1])
        merged = True
        while merged:
            merged = False
            for i in range(len(boxes)):
                for j in range(i + 1, len(boxes)):
                    a, b = boxes[i], boxes[j]
                    overlap = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
                    if overlap < 0.5 * min(a[2], b[2]):
                        continue
                    top, bottom = (a, b) if a[1] <= b[1] else (b, a)
                    gap = bottom[1] - (top[1] + top[3])
                    bottom_y = max(a[1] + a[3], b[1] + b[3])
                    expected = self._expected_height(bottom_y, scale) or \
                        self.config.min_person_height * scale
                    union_h = bottom_y - min(a[1], b[1])
                    if gap > self.config.join_gap * expected or union_h > 1.3 * expected:
                        continue
                    x0, y0 = min(a[0], b[0]), min(a[1], b[1])
                    x1 = max(a[0] + a[2], b[0] + b[2])
                    boxes[i] = (x0, y0, x1 - x0, bottom_y - y0)
                    del boxes[j]
                    merged = True
                    break
                if merged:
                    break
        return boxes

    def _split(self, mask: np.ndarray, box: tuple, scale: float) -> list:
        """Cut a blob wider than ``split_ratio`` expected widths at projection minima
        (:mod:`mk_tracker.detection.person_size`); each part's box is tightened to its own
        foreground rows."""
        x, y, w, h = box
        expected_h = self._expected_height(y + h, scale)
        if expected_h is None:
            return [box]
        people = people_in_width(w, self.config.person_aspect * expected_h,
                                 self.config.split_ratio)
        if people == 1:
            return [box]
        x0, y0, x1, y1 = int(x), int(y), int(x + w), int(y + h)
        parts = []
        for left, right in split_columns(mask[y0:y1, x0:x1], people):
            rows = np.flatnonzero(mask[y0:y1, x0 + left:x0 + right].any(axis=1))
            top, bottom = y0 + int(rows[0]), y0 + int(rows[-1]) + 1
            parts.append((float(x0 + left), float(top), float(right - left),
                          float(bottom - top)))
        return parts or [box]
