"""Readers for MOTChallenge and OTB sequence folders.

Both readers return a :class:`Sequence`: image paths (images are loaded lazily with
``cv2.imread`` by :meth:`Sequence.image`), the frame rate, per-frame ground truth
(``{identity: box}``) and, for MOTChallenge, per-frame public detections.

Coordinates are kept exactly as stored in the files.  Both formats were annotated in
Matlab and nominally count pixels from 1, whereas :mod:`mk_tracker.boxes` counts from 0; the
readers deliberately do *not* shift boxes by one pixel, so that ground truth, public
detections, imported bags and :mod:`mk_tracker.evaluation.metrics` (which reads the same files
verbatim) all agree.  The possible 1-pixel offset against the image grid is below the
annotation accuracy.  Frames are 0-based indices into ``image_paths`` (file frame number
minus 1; line ``k`` of an OTB file is frame ``k - 1``).

MOTChallenge (``read_mot_sequence``)::

    img1/000001.jpg ...             images (imDir/imExt from seqinfo.ini when present)
    gt/gt.txt                       frame,id,x,y,w,h,conf[,class,visibility|,x3d,y3d,z3d]
    det/det.txt  (optional)         frame,-1,x,y,w,h,score,...   (score not in [0, 1])
    seqinfo.ini  (optional)         [Sequence] frameRate, seqLength, imWidth, imHeight ...

  Ground-truth rows with ``conf == 0`` are "ignore" rows (MOT16+) and are dropped; when the
  8th column is a class (MOT16+ files with 9 columns), only class 1 (pedestrian) is kept.
  MOT15 files (conf -1, 3-D columns) keep every row.

OTB (``read_otb_sequence``)::

    img/0001.jpg ...
    groundtruth_rect.txt            one "x y w h" line per frame, comma- or
                                    whitespace-separated

  A line with a NaN or a non-positive size marks a frame without a visible target (empty
  ground truth for that frame).  The target's identity is 1.

Malformed files raise :class:`DatasetError` naming the file, the line and the problem.  The
files are parsed by :mod:`mk_tracker.evaluation.metrics` (:func:`~mk_tracker.evaluation.metrics.parse_mot_lines`,
:func:`~mk_tracker.evaluation.metrics.parse_box_lines`), so scoring reads them identically; this
module adds the checks against the folder (frame numbers within the images, one box per
identity and frame, one OTB line per image).
"""

from __future__ import annotations

import configparser
import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from mk_tracker.messages.detection_messages import Detection
from mk_tracker.evaluation.metrics import (EvaluationError, parse_box_lines, parse_mot_lines,
                                   read_text_lines)

Box = tuple[float, float, float, float]

DEFAULT_FRAME_RATE = 25.0
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")


class DatasetError(ValueError):
    """A dataset folder or file is missing, malformed or unreadable."""


@dataclass(frozen=True)
class Sequence:
    """One video sequence with its annotations.  ``ground_truth[k]`` and
    ``detections[k]`` belong to ``image_paths[k]``; ``detections`` is None when the
    sequence has no public detections."""

    name: str
    layout: str  # "mot" or "otb"
    folder: Path
    image_paths: tuple[Path, ...]
    frame_rate: float
    ground_truth: tuple[dict[int, Box], ...]
    detections: tuple[tuple[Detection, ...], ...] | None = None
    image_size: tuple[int, int] | None = None  # (width, height) when declared
    info: dict[str, str] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.image_paths)

    def image(self, index: int) -> np.ndarray:
        """BGR uint8 image of frame ``index`` (0-based), read from disk now."""
        if not 0 <= index < len(self.image_paths):
            raise DatasetError(f"{self.name}: frame {index} outside 0..{len(self) - 1}")
        path = self.image_paths[index]
        if not path.is_file():
            raise DatasetError(f"{path}: image file is missing")
        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if image is None:
            raise DatasetError(f"{path}: cannot decode image (corrupt or not an image)")
        return image

    def images(self) -> Iterator[np.ndarray]:
        """All images in order, one at a time."""
        for k in range(len(self)):
            yield self.image(k)

    @property
    def identities(self) -> list[int]:
        """Sorted ground-truth identities."""
        return sorted({i for frame in self.ground_truth for i in frame})

    @property
    def ground_truth_count(self) -> int:
        """Number of ground-truth boxes over all frames."""
        return sum(len(frame) for frame in self.ground_truth)

    def track(self, identity: int) -> dict[int, Box]:
        """``{frame index: box}`` of one identity (single-target benchmarks)."""
        return {k: frame[identity] for k, frame in enumerate(self.ground_truth)
                if identity in frame}

    def timestamp_ns(self, index: int, start_ns: int = 0) -> int:
        """Time stamp of frame ``index`` at the sequence's frame rate."""
        return int(start_ns) + round(index * 1e9 / self.frame_rate)


# --------------------------------------------------------------------------------------

def _folder(folder: str | Path) -> Path:
    path = Path(folder)
    if not path.is_dir():
        raise DatasetError(f"{path}: not a directory")
    return path


def _images(directory: Path, suffix: str | None = None) -> tuple[Path, ...]:
    if not directory.is_dir():
        raise DatasetError(f"{directory}: image folder is missing")
    suffixes = (suffix.lower(),) if suffix else IMAGE_SUFFIXES
    paths = [p for p in directory.iterdir() if p.suffix.lower() in suffixes]
    if not paths:
        raise DatasetError(f"{directory}: no images ({', '.join(suffixes)})")
    numbered = []
    for p in paths:
        if not p.stem.isdigit():
            raise DatasetError(f"{p}: image name is not a frame number")
        numbered.append((int(p.stem), p))
    numbered.sort()
    numbers = [n for n, _ in numbered]
    expected = list(range(numbers[0], numbers[0] + len(numbers)))
    if numbers != expected or numbers[0] != 1:
        missing = sorted(set(range(1, numbers[-1] + 1)) - set(numbers))
        raise DatasetError(f"{directory}: images must be numbered 1..N without gaps "
                           f"(missing frame numbers {missing[:10]})")
    return tuple(p for _, p in numbered)


@contextmanager
def _as_dataset_error() -> Iterator[None]:
    """The parsers' :class:`EvaluationError` (naming file and line) as :class:`DatasetError`."""
    try:
        yield
    except EvaluationError as exc:
        raise DatasetError(str(exc)) from None


def _frame_index(path: Path, line_no: int, frame: int, n_frames: int) -> int:
    if not 1 <= frame <= n_frames:
        raise DatasetError(f"{path}:{line_no}: frame {frame} outside 1..{n_frames}")
    return frame - 1


def _seqinfo(folder: Path) -> dict[str, str]:
    path = folder / "seqinfo.ini"
    if not path.is_file():
        return {}
    parser = configparser.ConfigParser()
    try:
        parser.read(path)
    except configparser.Error as exc:
        raise DatasetError(f"{path}: malformed ({exc})") from None
    if not parser.has_section("Sequence"):
        raise DatasetError(f"{path}: no [Sequence] section")
    return {k: v for k, v in parser.items("Sequence")}


def read_mot_sequence(folder: str | Path, frame_rate: float | None = None) -> Sequence:
    """Read a MOTChallenge sequence folder (see the module docstring).

    ``frame_rate`` overrides ``seqinfo.ini``'s ``frameRate``; without either it is
    :data:`DEFAULT_FRAME_RATE`.
    """
    root = _folder(folder)
    info = _seqinfo(root)
    images = _images(root / info.get("imdir", "img1"), info.get("imext"))
    n = len(images)
    if "seqlength" in info and int(info["seqlength"]) != n:
        raise DatasetError(f"{root / 'seqinfo.ini'}: seqLength {info['seqlength']} but "
                           f"{n} images in {images[0].parent}")
    rate = _frame_rate(root, frame_rate, info.get("framerate"))
    gt_path = root / "gt" / "gt.txt"
    if not gt_path.is_file():
        raise DatasetError(f"{gt_path}: ground truth file is missing")
    ground_truth: list[dict[int, Box]] = [{} for _ in range(n)]
    with _as_dataset_error():
        rows = parse_mot_lines(read_text_lines(gt_path), ground_truth=True, source=str(gt_path))
    for row in rows:
        k = _frame_index(gt_path, row.line, row.frame, n)
        if row.id in ground_truth[k]:
            raise DatasetError(f"{gt_path}:{row.line}: identity {row.id} appears twice "
                               f"in frame {row.frame}")
        ground_truth[k][row.id] = row.box
    detections = None
    det_path = root / "det" / "det.txt"
    if det_path.is_file():
        per_frame: list[list[Detection]] = [[] for _ in range(n)]
        with _as_dataset_error():
            rows = parse_mot_lines(read_text_lines(det_path), source=str(det_path),
                                   require_score=True)
        for row in rows:
            k = _frame_index(det_path, row.line, row.frame, n)
            per_frame[k].append(Detection(row.box, row.score))
        detections = tuple(tuple(d) for d in per_frame)
    size = None
    if "imwidth" in info and "imheight" in info:
        size = (int(info["imwidth"]), int(info["imheight"]))
    return Sequence(info.get("name", root.name), "mot", root, images, rate,
                    tuple(ground_truth), detections, size, info)


def _frame_rate(root: Path, given: float | None, declared: str | None) -> float:
    if given is not None:
        rate = float(given)
    elif declared is not None:
        try:
            rate = float(declared)
        except ValueError:
            raise DatasetError(f"{root / 'seqinfo.ini'}: frameRate {declared!r} is not a "
                               "number") from None
    else:
        rate = DEFAULT_FRAME_RATE
    if not (math.isfinite(rate) and rate > 0):
        raise DatasetError(f"{root}: frame rate must be positive, got {rate}")
    return rate


def read_otb_sequence(folder: str | Path, frame_rate: float | None = None) -> Sequence:
    """Read an OTB sequence folder (see the module docstring); the frame rate defaults to
    :data:`DEFAULT_FRAME_RATE` (OTB does not record one)."""
    root = _folder(folder)
    images = _images(root / "img")
    gt_path = root / "groundtruth_rect.txt"
    if not gt_path.is_file():
        raise DatasetError(f"{gt_path}: ground truth file is missing")
    with _as_dataset_error():
        boxes = parse_box_lines(read_text_lines(gt_path), str(gt_path))
    if len(boxes) != len(images):
        raise DatasetError(f"{gt_path}: {len(boxes)} boxes for {len(images)} images")
    ground_truth = [{1: box} if box is not None else {} for box in boxes]
    return Sequence(root.name, "otb", root, images, _frame_rate(root, frame_rate, None),
                    tuple(ground_truth))


def subsampled(sequence: Sequence, step: int, offset: int = 0) -> Sequence:
    """A lower-frame-rate copy of ``sequence``: frames ``offset``, ``offset + step``, ...
    (0-based) with their ground truth and detections, at ``frame_rate / step``.

    The kept frames are renumbered 0, 1, ... (stamps ``k / (frame_rate / step)``): each one
    shows ``step`` times the motion per frame of the original, as a camera recording at the
    lower rate would.  ``step`` 1 and ``offset`` 0 return the sequence itself.  Raises
    :class:`DatasetError` for ``step`` < 1 or an ``offset`` outside ``0..step - 1``."""
    if isinstance(step, bool) or not isinstance(step, int) or step < 1:
        raise DatasetError(f"{sequence.name}: frame step must be an integer >= 1, got {step!r}")
    if isinstance(offset, bool) or not isinstance(offset, int) or not 0 <= offset < step:
        raise DatasetError(f"{sequence.name}: offset must be an integer in 0..{step - 1}, "
                           f"got {offset!r}")
    if step == 1:
        return sequence
    keep = range(offset, len(sequence), step)
    if not len(keep):
        raise DatasetError(f"{sequence.name}: no frame left at step {step}, offset {offset}")
    info = dict(sequence.info)
    info.update(framerate=f"{sequence.frame_rate / step:g}", seqlength=str(len(keep)))
    return Sequence(f"{sequence.name} step {step} offset {offset}", sequence.layout,
                    sequence.folder, tuple(sequence.image_paths[k] for k in keep),
                    sequence.frame_rate / step,
                    tuple(sequence.ground_truth[k] for k in keep),
                    None if sequence.detections is None
                    else tuple(sequence.detections[k] for k in keep),
                    sequence.image_size, info)


def detect_layout(folder: str | Path) -> str:
    """``"mot"`` or ``"otb"`` from the folder's contents."""
    root = _folder(folder)
    if (root / "gt" / "gt.txt").is_file() or (root / "img1").is_dir():
        return "mot"
    if (root / "groundtruth_rect.txt").is_file() or (root / "img").is_dir():
        return "otb"
    raise DatasetError(f"{root}: neither a MOTChallenge folder (img1/, gt/gt.txt) nor an "
                       "OTB folder (img/, groundtruth_rect.txt)")


def read_sequence(folder: str | Path, frame_rate: float | None = None) -> Sequence:
    """Read a MOTChallenge or OTB folder, whichever it is."""
    layout = detect_layout(folder)
    reader = read_mot_sequence if layout == "mot" else read_otb_sequence
    return reader(folder, frame_rate)
