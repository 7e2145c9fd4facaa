"""Where does a group of people become one half-frame object of the thermal detector, and
how long do the tracking passes carry it (issues #19 and #15)?

    nice -n 10 .venv/bin/python benchmarks/diagnose_group_objects.py --gains 0.93 1.0

Runs the configured detector (``--params`` files, counter masked as in
benchmarks/bench_real_thermal.py) on BU-TIV-lab at constant gains and, at every full-frame
pass, records the steps of :meth:`ThermalDetector._full_pass` by wrapping its methods (no
second implementation): the support pixels of the sparse factors (5.1), the K-means clusters
(3.12)-(3.13) and their boxes, the groups after the link rule (``link_gap``), after the
footprint merge (``merge_by_footprint``), the candidates before and after
``drop_background_footprints``; then, frame by frame, the life of every object whose box
is larger than half the frame (``w h > W H / 2``).  Not a test: nothing is asserted.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_real_thermal import COUNTER_REGION, DEFAULT_CLIP  # noqa: E402

from mk_tracker.bags.recording_import import open_recording  # noqa: E402
from mk_tracker.bags.video_source import to_thermal  # noqa: E402
from mk_tracker.detection import thermal_detector as td  # noqa: E402
from mk_tracker.frame_processing import build_detector  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402


def _box(rows: np.ndarray, cols: np.ndarray) -> tuple[int, int, int, int]:
    return (int(cols.min()), int(rows.min()), int(cols.max() - cols.min() + 1),
            int(rows.max() - rows.min() + 1))


def _big(box, area: float) -> bool:
    return box[2] * box[3] > 0.5 * area


class Recorder:
    """Wraps the module functions and detector methods one full pass calls."""

    def __init__(self, det: td.ThermalDetector) -> None:
        self.det = det
        self.log: dict = {}
        self._orig = {n: getattr(td, n) for n in ("cluster_support_pixels", "merge_linked")}
        rec = self

        def clusters(points, **kw):
            z, labels = rec._orig["cluster_support_pixels"](points, **kw)
            rec.log["kmeans"] = _groups(points, labels)
            return z, labels

        def linked(labels, links):
            out = rec._orig["merge_linked"](labels, links)
            rec.log["linked_labels"] = out
            return out

        td.cluster_support_pixels = clusters
        td.merge_linked = linked
        for name in ("_merge_by_footprint", "_without_background", "_reassociate"):
            setattr(det, name, self._wrap(name, getattr(det, name)))

    def _wrap(self, name, method):
        def call(*args, **kw):
            if name == "_without_background":
                self.log["candidates"] = [c.box for c in args[2]]
            if name == "_merge_by_footprint":
                rows, cols, groups = args[2], args[3], args[4]
                self.log["groups_in"] = [_box(rows[g], cols[g]) for g in groups]
            out = method(*args, **kw)
            if name == "_merge_by_footprint":
                rows, cols = args[2], args[3]
                self.log["groups_out"] = [_box(rows[g], cols[g]) for g in out[0]]
            if name == "_without_background":
                self.log["kept"] = [c.box for c in out]
            if name == "_reassociate" and "candidates" not in self.log:
                self.log["candidates"] = [c.box for c in args[0]]
            return out
        return call


def _groups(points: np.ndarray, labels: np.ndarray) -> list:
    out = []
    for k in np.unique(labels):
        p = points[labels == k]
        out.append(_box(p[:, 1], p[:, 0]))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--gains", type=float, nargs="+", default=[0.93, 1.0])
    parser.add_argument("--params", type=Path, nargs="*", default=[])
    parser.add_argument("--frames", type=int, default=0, help="only the first N frames")
    args = parser.parse_args(argv)
    cfg = load_pipeline_config(list(args.params))
    source = open_recording(args.clip, None)
    frames = []
    for i, item in enumerate(source.frames()):
        frames.append((i / source.fps, to_thermal(item)[0]))
        if args.frames and i + 1 >= args.frames:
            break
    print(f"{len(frames)} frames", file=sys.stderr)
    for g in args.gains:
        wrapper = build_detector(cfg.method, cfg.detector, cfg.threshold, COUNTER_REGION)
        det = getattr(wrapper, "detector", wrapper)
        rec = Recorder(det)
        print(f"\n== gain {g:.2f}")
        life: dict = {}
        for k, (stamp, frame) in enumerate(frames):
            scaled = np.clip(np.rint(g * frame.astype(np.float64)), 0, 255).astype(np.uint8)
            rec.log = {}
            found = wrapper.process(scaled, stamp)
            area = float(scaled.shape[0] * scaled.shape[1])
            if det.last_mode in ("startup", "reconfiguration"):
                res = rec.log
                big_k = [b for b in res.get("kmeans", []) if _big(b, area)]
                linked = res.get("linked_labels")
                nlink = len(np.unique(linked)) if linked is not None else None
                big_in = [b for b in res.get("groups_in", []) if _big(b, area)]
                big_out = [b for b in res.get("groups_out", []) if _big(b, area)]
                big_c = [b for b in res.get("candidates", []) if _big(b, area)]
                print(f"frame {k} full pass: kmeans {len(res.get('kmeans', []))} "
                      f"(>half {len(big_k)}), linked {nlink}, "
                      f"groups {len(res.get('groups_in', []))}->{len(res.get('groups_out', []))} "
                      f"(>half {len(big_in)}->{len(big_out)}), candidates "
                      f"{len(res.get('candidates', []))} (>half {len(big_c)} {big_c}), "
                      f"published {len(found)}")
            for d in found:
                if _big(d.box, area):
                    life.setdefault(d.object_id, []).append((k, det.last_mode[0],
                                                            tuple(int(v) for v in d.box)))
        for oid, seen in life.items():
            modes = "".join(m for _, m, _ in seen)
            print(f"object {oid}: > half the frame in {len(seen)} frames "
                  f"{seen[0][0]}..{seen[-1][0]} modes {modes[:60]} first {seen[0][2]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
