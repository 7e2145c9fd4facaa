"""Where a thermal detector frame spends its time, and how it compares with an older version.

Feeds synthetic crowds (:func:`mk_tracker.synthetic.presets.crowd_scene`, built as the benchmark
builds them) to :class:`mk_tracker.detection.thermal_detector.ThermalDetector` and reports

* per mode (tracking frame, full-frame pass) the median CPU time (``time.process_time``),
  both the plain median over all runs and the median over frames of each frame's fastest
  run ("median of min", less sensitive to other jobs on a shared machine: the detector is
  deterministic, so every run does the same work);
* with ``--compare DIR`` the same figures for the ``mk_tracker`` package found in ``DIR``
  (e.g. ``git archive <commit> mk_tracker | tar -x -C DIR``), measured in the same run,
  alternating with the current one, each in its own process;
* a cProfile of the current version (top functions by own time) per mode.

The report goes to ``docs/profile_thermal_detector.md`` with the command and the machine
load (its hand-written sections, from ``## Real LWIR frames`` on, are kept).  Not a
test: nothing is asserted.  Run it with one thread::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 \\
        .venv/bin/python benchmarks/profile_thermal_detector.py --compare /tmp/base
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: first heading of the report's hand-written sections, kept when the report is rewritten
HAND_WRITTEN = "## Real LWIR frames"


def measure(people: int, width: int, height: int, frames: int, seed: int,
            repeats: int) -> dict:
    """Per-mode CPU medians (ms) of the ``mk_tracker`` importable in this process."""
    import mk_tracker
    from mk_tracker.synthetic.presets import crowd_scene, paper_scene
    from mk_tracker.detection.thermal_detector import ThermalDetector

    warm = ThermalDetector()
    ps = paper_scene(99)
    for i in range(10):
        warm.process(ps.frame(i).thermal, ps.frame(i).stamp)
    scene = crowd_scene(people, seed=seed, width=width, height=height, frames=frames)
    data = [scene.frame(i) for i in range(len(scene))]
    times = np.full((repeats, len(data)), np.nan)
    modes: list[str] = []
    for r in range(repeats):
        det = ThermalDetector()
        modes = []
        for i, fr in enumerate(data):
            c0 = time.process_time()
            det.process(fr.thermal, fr.stamp)
            times[r, i] = (time.process_time() - c0) * 1e3
            modes.append(det.last_mode)
    out = {"package": str(Path(mk_tracker.__file__).parent)}
    for label, keep in (("tracking", ("tracking",)), ("full", ("startup", "reconfiguration"))):
        idx = [i for i, m in enumerate(modes) if m in keep]
        if idx:
            out[label] = {"median": float(np.median(times[:, idx])),
                          "median_of_min": float(np.median(times[:, idx].min(axis=0))),
                          "frames": len(idx)}
    return out


def run_worker(path: str | None, args: argparse.Namespace, people: int) -> dict:
    """:func:`measure` in a fresh process, importing ``mk_tracker`` from ``path`` (None:
    this checkout)."""
    env = dict(os.environ)
    if path:
        env["PYTHONPATH"] = path
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", "--people", str(people),
           "--width", str(args.width), "--height", str(args.height), "--frames",
           str(args.frames), "--seed", str(args.seed), "--repeats", str(args.repeats)]
    res = subprocess.run(cmd, env=env, cwd="/" if path else str(ROOT), check=True,
                         capture_output=True, text=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def profile(people: int, args: argparse.Namespace, top: int) -> dict[str, str]:
    """cProfile text (own time) per mode of the current version."""
    from mk_tracker.synthetic.presets import crowd_scene
    from mk_tracker.detection.thermal_detector import ThermalDetector

    from mk_tracker.synthetic.presets import paper_scene
    warm = ThermalDetector()                    # numba caches loaded before profiling
    ps = paper_scene(99)
    for i in range(10):
        warm.process(ps.frame(i).thermal, ps.frame(i).stamp)
    scene = crowd_scene(people, seed=args.seed, width=args.width, height=args.height,
                        frames=args.frames)
    stats: dict[str, pstats.Stats] = {}
    det = ThermalDetector()
    for i in range(len(scene)):
        fr = scene.frame(i)
        prof = cProfile.Profile()
        prof.enable()
        det.process(fr.thermal, fr.stamp)
        prof.disable()
        mode = "full" if det.last_mode in ("startup", "reconfiguration") else det.last_mode
        if mode not in ("tracking", "full"):
            continue
        if mode in stats:
            stats[mode].add(prof)
        else:
            stats[mode] = pstats.Stats(prof)
    out = {}
    for mode, st in stats.items():
        buf = io.StringIO()
        st.stream = buf
        st.strip_dirs().sort_stats("tottime").print_stats(top)
        out[mode] = buf.getvalue().strip()
    return out


def fmt(entries: list) -> str:
    """``median of min / median`` of one round, or their ranges over several rounds."""
    entries = [e for e in entries if e]
    if not entries:
        return "-"

    def span(key: str) -> str:
        lo, hi = min(e[key] for e in entries), max(e[key] for e in entries)
        return f"{lo:.2f}" if len(entries) == 1 else f"{lo:.2f}-{hi:.2f}"

    return f"{span('median_of_min')} / {span('median')}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--people", type=int, nargs="+", default=[1, 5, 15])
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="runs per scene")
    parser.add_argument("--compare", default=None,
                        help="directory holding an older mk_tracker package to measure too")
    parser.add_argument("--label", default="compared",
                        help="name of the --compare version in the report (e.g. its commit)")
    parser.add_argument("--rounds", type=int, default=1,
                        help="measure every version this many times, alternating (the table "
                             "gives the range over the rounds)")
    parser.add_argument("--top", type=int, default=15, help="functions listed per mode")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", default=str(ROOT / "docs" / "profile_thermal_detector.md"))
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(measure(args.people[0], args.width, args.height, args.frames,
                                 args.seed, args.repeats)))
        return 0

    load_before = os.getloadavg()[0]
    rows = []
    header = ("| people | version | tracking frame ms CPU, median of min / median | "
              "full-frame pass ms CPU, median of min / median | load |")
    versions = [("current", None)] + ([(args.label, args.compare)] if args.compare else [])
    for people in args.people:
        results: dict[str, list] = {label: [] for label, _ in versions}
        loads = []
        for _ in range(max(1, args.rounds)):
            for label, path in versions:
                results[label].append(run_worker(path, args, people))
                loads.append(os.getloadavg()[0])
        for label, _ in versions:
            res = results[label]
            row = (f"| {people} | {label} (`{res[0]['package']}`) | "
                   f"{fmt([r.get('tracking') for r in res])} | "
                   f"{fmt([r.get('full') for r in res])} | "
                   f"{min(loads):.1f}-{max(loads):.1f} |")
            print(row, flush=True)
            rows.append(row)
    profiles = profile(args.people[len(args.people) // 2], args, args.top)
    for mode, text in profiles.items():
        print(f"\n== {mode} ==\n{text}")
    command = ("OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 .venv/bin/python "
               "benchmarks/profile_thermal_detector.py " + shlex.join(argv or sys.argv[1:]))
    text = [
        "# Thermal detector profile",
        "",
        "Produced by:",
        "",
        "```",
        command.strip(),
        "```",
        "",
        f"Crowd scenes {args.width}x{args.height}, {args.frames} frames, seed {args.seed}, "
        f"{args.repeats} runs each, every version in its own process (the compared one "
        f"measured right after the current one; {max(1, args.rounds)} round(s) of both, "
        "alternating, ranges over the rounds).  CPU time per `process()` call "
        "(`time.process_time`, one thread); *median of min* takes each frame's fastest run, "
        "then the median over frames (the detector is deterministic, so slower runs are "
        "other jobs' interference).  The compared package is a plain copy of `mk_tracker/` at "
        "an older commit (`git archive <commit> mk_tracker | tar -x -C DIR`).  Machine load "
        "(1-min average, 2 cores): "
        f"{load_before:.1f} before, {os.getloadavg()[0]:.1f} after; the last column is "
        "the range sampled after each measurement of that scene.",
        "",
        header,
        "|---|---|---|---|---|",
        *rows,
        "",
    ]
    for mode, body in profiles.items():
        text += [f"## cProfile, {mode}, {args.people[len(args.people) // 2]} people "
                 "(own time; numba functions count as one call)", "", "```", body, "```", ""]
    out = Path(args.out)
    kept = ""            # the hand-written sections after the generated part stay
    if out.exists():
        previous = out.read_text()
        start = previous.find("\n" + HAND_WRITTEN)
        kept = previous[start:] if start >= 0 else ""
    out.write_text("\n".join(text) + kept)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
