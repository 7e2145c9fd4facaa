"""The RGB-only system (background-subtraction detector -> multi-object tracker) on the TUD
sequences, at the shipped defaults and with tracker parameters changed.

The tracker's defaults are chosen on public / generated detections
(benchmarks/bench_multi_object.py); this checks a candidate default on the project's own RGB
detection source before it is shipped (issue #16).  Each ``--variant`` is a comma-separated
list of ``NAME=VALUE`` tracker parameters (dotted names, YAML values), run besides the
defaults; MOTA / IDF1 as ``mk_tracker process`` scores them (motmetrics, IoU >= 0.5).

    .venv/bin/python benchmarks/background_tracker_ablation.py \\
        --variant min_detection_score=0.2 lifecycle.min_hits=2 \\
        min_detection_score=0.2,lifecycle.min_hits=2
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from mk_tracker.bags.dataset_import import import_sequence  # noqa: E402
from mk_tracker.bags.datasets import read_sequence  # noqa: E402
from bench_background_detector import tracking_scores  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "mot"


def nested(variant: str) -> dict:
    """``"a.b=2,c=0.2"`` -> ``{"a": {"b": 2}, "c": 0.2}``."""
    out: dict = {}
    for item in filter(None, variant.split(",")):
        name, _, value = item.partition("=")
        node = out
        *parents, leaf = name.strip().split(".")
        for key in parents:
            node = node.setdefault(key, {})
        node[leaf] = yaml.safe_load(value)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", nargs="*", default=[],
                        help="comma-separated NAME=VALUE tracker parameters")
    args = parser.parse_args(argv)
    variants = [("defaults", "")] + [(v, v) for v in args.variant]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name in ("TUD-Campus", "TUD-Stadtmitte"):
            if not (DATA / name).is_dir():
                print(f"{DATA / name} is absent: skipped", file=sys.stderr)
                continue
            import_sequence(read_sequence(DATA / name), tmp / name)
            for k, (label, variant) in enumerate(variants):
                m = tracking_scores(tmp / name, tmp / f"{name}-{k}", "background",
                                    tracker=nested(variant))
                rows.append(f"| {name} | {label} | {m['mota']:.3f} | {m['idf1']:.3f} |")
    print("\n".join(["| sequence | tracker parameters | MOTA | IDF1 |", "|---|---|---|---|"]
                    + rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
