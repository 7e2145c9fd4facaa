"""Cost of moving images between numpy, ROS messages and bags.

Compares, in the same run:

* building an rclpy ``sensor_msgs/Image`` from a numpy frame: :func:`numpy_to_image`
  (``array.array`` + one memcpy) against the naive ``Image(data=ndarray)`` and
  ``Image(data=ndarray.tobytes())``;
* reading a frame back: :func:`image_to_numpy` (a view) against ``np.array(msg.data)``;
* writing and reading a bag of frames with :class:`BagWriter` / :func:`open_bag` in both
  storage formats, and reading the same bag with ``rosbags.rosbag2.Reader``.

Usage::

    .venv/bin/python benchmarks/bench_message_io.py [--frames 100] [--out docs/message_io.md]
"""

from __future__ import annotations

import argparse
import platform
import shlex
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.bag_typestore import make_typestore  # noqa: E402
from mk_tracker.bags.bag_writer import BagWriter  # noqa: E402
from mk_tracker.messages.image_conversion import image_to_numpy, numpy_to_image  # noqa: E402
from mk_tracker.messages.message_types import (bag_message_types, make_header,  # noqa: E402
                                      ros_message_types)


def timed(fn, repeat: int) -> float:
    """Median wall time of ``fn()`` in milliseconds."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) * 1e3


def image_rows(repeat: int) -> list[tuple[str, str, float]]:
    try:
        from sensor_msgs.msg import Image
    except ImportError:
        return [("rclpy Image", "sensor_msgs not installed", float("nan"))]
    types = ros_message_types()
    rows = []
    for h, w in ((480, 640), (1080, 1920)):
        frame = np.random.default_rng(0).integers(0, 255, (h, w, 3), dtype=np.uint8)
        size = f"{w}x{h} bgr8"
        msg = numpy_to_image(frame, "bgr8", types=types)
        rows.append((size, "numpy_to_image (array.array + memcpy)",
                     timed(lambda: numpy_to_image(frame, "bgr8", types=types), repeat)))
        rows.append((size, "Image(data=frame.tobytes())",
                     timed(lambda: Image(height=h, width=w, encoding="bgr8", step=3 * w,
                                         data=frame.tobytes()), repeat)))
        rows.append((size, "Image(data=ndarray) (naive)",
                     timed(lambda: Image(height=h, width=w, encoding="bgr8", step=3 * w,
                                         data=frame.reshape(-1)), max(1, repeat // 10))))
        rows.append((size, "image_to_numpy (view)", timed(lambda: image_to_numpy(msg), repeat)))
        rows.append((size, "np.array(msg.data).reshape (copy)",
                     timed(lambda: np.array(msg.data, np.uint8).reshape(h, w, 3), repeat)))
    return rows


def bag_rows(frames: int) -> list[tuple[str, str, float]]:
    store = make_typestore()
    types = bag_message_types(store)
    frame = np.random.default_rng(1).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for storage in ("mcap", "sqlite3"):
            path = Path(tmp) / storage
            t0 = time.perf_counter()
            with BagWriter(path, storage, typestore=store) as bag:
                for k in range(frames):
                    header = make_header(types, "camera", k * 40_000_000)
                    bag.write("/image_raw", k * 40_000_000,
                              numpy_to_image(frame, "bgr8", header, types=types))
            rows.append((storage, f"BagWriter: write {frames} 640x480 frames",
                         (time.perf_counter() - t0) * 1e3 / frames))
            t0 = time.perf_counter()
            with open_bag(path) as bag:
                n = 0
                for m in bag.messages():
                    image_to_numpy(bag.deserialize(m))
                    n += 1
            assert n == frames
            rows.append((storage, "open_bag: read + deserialize + image_to_numpy",
                         (time.perf_counter() - t0) * 1e3 / frames))
            from rosbags.rosbag2 import Reader
            t0 = time.perf_counter()
            with Reader(path) as reader:
                n = 0
                for conn, _, data in reader.messages():
                    image_to_numpy(store.deserialize_cdr(data, conn.msgtype))
                    n += 1
            rows.append((storage, f"rosbags Reader: same ({n} messages read)",
                         (time.perf_counter() - t0) * 1e3 / frames))
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--out", type=Path, default=Path("docs/message_io.md"))
    args = parser.parse_args()
    command = "benchmarks/bench_message_io.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    images = image_rows(args.repeat)
    bags = bag_rows(args.frames)
    lines = ["# Message and bag I/O cost", "",
             f"Command: `.venv/bin/python {command.strip()}`  ",
             f"Machine: {platform.machine()}, Python {platform.python_version()}, "
             f"numpy {np.__version__}", "",
             "## numpy <-> rclpy sensor_msgs/Image (median ms per call)", "",
             "| image | method | ms |", "|---|---|---:|"]
    lines += [f"| {a} | {b} | {c:.3f} |" for a, b, c in images]
    lines += ["", f"## Bags of {args.frames} 640x480 bgr8 frames (ms per frame)", "",
              "| storage | operation | ms/frame |", "|---|---|---:|"]
    lines += [f"| {a} | {b} | {c:.3f} |" for a, b, c in bags]
    text = "\n".join(lines) + "\n"
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
