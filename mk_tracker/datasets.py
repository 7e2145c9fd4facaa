"""Readers for MOTChallenge and OTB sequence folders.

Both readers return a :class:`Sequence`: image paths (images are loaded lazily with
``cv2.imread`` by :meth:`Sequence.image`), the frame rate, per-frame ground truth
(``{identity: box}``) and, for MOTChallenge, per-frame public detections.

Coordinates are kept exactly as stored in the files.  Both formats were annotated in
Matlab and nominally count pixels from 1, whereas :mod:`mk_tracker.boxes` counts from 0; the
readers deliberately do *not* shift boxes by one pixel, so that ground truth, public
detections, imported bags and :mod:`mk_tracker.evaluation` (which reads the same files
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

Malformed files raise :class:`DatasetError` naming the file, the line and the problem.
"""

from __future__ import annotations

import configparser
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from mk_tracker.detection_messages import Detection

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


_SEPARATORS = re.compile(r"[,\s]+")


def _numbers(path: Path, line_no: int, line: str, minimum: int) -> list[float]:
    parts = [p for p in _SEPARATORS.split(line.strip()) if p]
    if len(parts) < minimum:
        raise DatasetError(f"{path}:{line_no}: expected at least {minimum} values, "
                           f"got {len(parts)}: {line.strip()!r}")
    try:
        return [float(p) for p in parts]
    except ValueError as exc:
        raise DatasetError(f"{path}:{line_no}: not a number ({exc}): {line.strip()!r}") from None


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    try:
        text = path.read_text()
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path}: not a text file ({exc})") from None
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read ({exc.strerror})") from None
    for line_no, line in enumerate(text.splitlines(), start=1):
        if line.strip() and not line.lstrip().startswith("#"):
            yield line_no, line


def _frame_index(path: Path, line_no: int, value: float, n_frames: int) -> int:
    if not math.isfinite(value) or value != int(value) or not 1 <= value <= n_frames:
        raise DatasetError(f"{path}:{line_no}: frame {value:g} outside 1..{n_frames}")
    return int(value) - 1


def _box(path: Path, line_no: int, x: float, y: float, w: float, h: float) -> Box:
    if not all(math.isfinite(v) for v in (x, y, w, h)) or w <= 0 or h <= 0:
        raise DatasetError(f"{path}:{line_no}: invalid box {(x, y, w, h)} "
                           "(needs finite values and positive size)")
    return (x, y, w, h)


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
    for line_no, line in _lines(gt_path):
        v = _numbers(gt_path, line_no, line, 6)
        k = _frame_index(gt_path, line_no, v[0], n)
        if not math.isfinite(v[1]) or v[1] != int(v[1]):
            raise DatasetError(f"{gt_path}:{line_no}: identity {v[1]} is not an integer")
        identity = int(v[1])
        if len(v) >= 7 and v[6] == 0:
            continue  # MOT16+ "ignore" row
        if len(v) == 9 and int(v[7]) != 1:
            continue  # MOT16+ non-pedestrian class
        if identity in ground_truth[k]:
            raise DatasetError(f"{gt_path}:{line_no}: identity {identity} appears twice "
                               f"in frame {int(v[0])}")
        ground_truth[k][identity] = _box(gt_path, line_no, *v[2:6])
    detections = None
    det_path = root / "det" / "det.txt"
    if det_path.is_file():
        per_frame: list[list[Detection]] = [[] for _ in range(n)]
        for line_no, line in _lines(det_path):
            v = _numbers(det_path, line_no, line, 7)
            k = _frame_index(det_path, line_no, v[0], n)
            if not math.isfinite(v[6]):
                raise DatasetError(f"{det_path}:{line_no}: score {v[6]} is not finite")
            per_frame[k].append(Detection(_box(det_path, line_no, *v[2:6]), v[6]))
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
    rows = [(line_no, _numbers(gt_path, line_no, line, 4)) for line_no, line in _lines(gt_path)]
    for line_no, v in rows:
        if len(v) != 4:
            raise DatasetError(f"{gt_path}:{line_no}: expected 4 values x y w h, got {len(v)}")
    if len(rows) != len(images):
        raise DatasetError(f"{gt_path}: {len(rows)} boxes for {len(images)} images")
    ground_truth = []
    for line_no, (x, y, w, h) in rows:
        visible = all(math.isfinite(t) for t in (x, y, w, h)) and w > 0 and h > 0
        ground_truth.append({1: _box(gt_path, line_no, x, y, w, h)} if visible else {})
    return Sequence(root.name, "otb", root, images, _frame_rate(root, frame_rate, None),
                    tuple(ground_truth))


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
