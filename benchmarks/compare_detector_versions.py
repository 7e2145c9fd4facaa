"""Detections and CPU time of the default thermal detector, this checkout against an older
version of ``mk_tracker``, on the same frames: the real BU-TIV-lab clip (counter masked, as
``bench_real_thermal.py`` runs it) and generated crowds.  Says whether every box is equal
(to ``--tol``) and the median thread time per frame of both, measured in turns.

The older version is a directory holding its ``mk_tracker`` package, e.g.::

    mkdir -p /tmp/base && git archive <commit> mk_tracker | tar -x -C /tmp/base
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 nice -n 10 \\
        .venv/bin/python benchmarks/compare_detector_versions.py --baseline /tmp/base

Each version runs in its own process (``PYTHONPATH`` picks the package), one process per
round and version, the versions alternating, so both see the same machine load; the
figures are medians over frames of each frame's fastest round.  Exit status 1 if any box
differs.  Not a test, but the equality check is the one of issue #19's speed work.
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CLIP = ROOT.parent / "shared" / "data" / "thermal" / "BU-TIV-lab" / "BU-TIV-lab.mp4"
COUNTER_REGION = (0.0, 0.0, 110.0, 50.0)
SCENES = [(people, size, seed) for people in (3, 8, 15) for size in ((320, 240), (640, 480))
          for seed in (0, 1)]


def clip_frames(cache: Path) -> None:
    """Decode the clip once (as ``mk_tracker import --thermal`` does) into ``cache``."""
    from mk_tracker.bags.bag_io import open_bag
    from mk_tracker.bags.recording_import import import_recording, open_recording
    from mk_tracker.messages.image_conversion import image_to_numpy
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bag"
        import_recording(open_recording(CLIP, None), bag, thermal=True)
        frames, stamps, encodings = [], [], set()
        with open_bag(bag) as reader:
            for m in reader.messages(["/thermal/image_raw"]):
                msg = reader.deserialize(m)
                frames.append(np.array(image_to_numpy(msg)))
                stamps.append(m.timestamp_ns)
                encodings.add(msg.encoding)
    np.savez(cache, frames=np.stack(frames), stamps=np.array(stamps),
             encoding=sorted(encodings)[0])


def worker(cache: Path, frames: int, out: Path) -> None:
    """Run the importable ``mk_tracker``'s default detector on every input; pickle the
    boxes and thread times per frame to ``out``."""
    from mk_tracker.frame_processing import build_detector
    from mk_tracker.synthetic.presets import crowd_scene
    from mk_tracker.tools.pipeline_config import load_pipeline_config
    cfg = load_pipeline_config()

    def run(name, images, stamps, encoding, regions):
        det = build_detector(cfg.method, cfg.detector, cfg.threshold, regions)
        boxes, times, modes = [], [], []
        for image, stamp in zip(images, stamps):
            t0 = time.thread_time()
            dets = det.process(image, stamp, encoding=encoding)
            times.append(time.thread_time() - t0)
            boxes.append(np.array([[*d.box, d.score] for d in dets], dtype=float).reshape(-1, 5))
            modes.append(det.last_mode)
        return name, {"boxes": boxes, "ms": np.array(times) * 1e3, "modes": modes}

    data = np.load(cache)
    results = dict([run("BU-TIV-lab", data["frames"], data["stamps"] * 1e-9,
                        str(data["encoding"]), COUNTER_REGION)])
    for people, (w, h), seed in SCENES:
        scene = crowd_scene(people, seed=seed, width=w, height=h, frames=frames)
        fr = [scene.frame(i) for i in range(len(scene))]
        name, res = run(f"crowd {people} {w}x{h} seed {seed}", [f.thermal for f in fr],
                        [f.stamp for f in fr], None, ())
        results[name] = res
    results["package"] = str(Path(sys.modules["mk_tracker"].__file__).parent)
    out.write_bytes(pickle.dumps(results))


def spawn(path: str | None, cache: Path, frames: int, out: Path) -> dict:
    env = dict(os.environ)
    if path:
        env["PYTHONPATH"] = path
    subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker", str(out),
                    "--cache", str(cache), "--frames", str(frames)],
                   env=env, cwd=path or str(ROOT), check=True)
    return pickle.loads(out.read_bytes())


def same_boxes(a: list, b: list, tol: float) -> tuple[bool, str]:
    for i, (x, y) in enumerate(zip(a, b)):
        if x.shape != y.shape:
            return False, f"frame {i}: {len(x)} vs {len(y)} detections"
        if x.size and float(np.max(np.abs(x - y))) > tol:
            return False, f"frame {i}: boxes differ by {float(np.max(np.abs(x - y))):.3g}"
    return len(a) == len(b), "" if len(a) == len(b) else "frame counts differ"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", required=False, help="directory holding the old mk_tracker")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--frames", type=int, default=100, help="frames per generated scene")
    parser.add_argument("--tol", type=float, default=1e-9)
    parser.add_argument("--cache", type=Path, default=Path(tempfile.gettempdir())
                        / "mk_tracker_butiv_frames.npz")
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        worker(args.cache, args.frames, args.worker)
        return 0
    if not args.baseline:
        parser.error("--baseline is required")
    if not args.cache.exists():
        clip_frames(args.cache)
    runs: dict[str, list] = {"current": [], "baseline": []}
    with tempfile.TemporaryDirectory() as tmp:
        spawn(None, args.cache, 5, Path(tmp) / "warm.pkl")      # numba caches compiled
        spawn(args.baseline, args.cache, 5, Path(tmp) / "warm.pkl")
        for r in range(args.rounds):
            for label, path in (("current", None), ("baseline", args.baseline)):
                runs[label].append(spawn(path, args.cache, args.frames, Path(tmp) / "r.pkl"))
    cur, base = runs["current"], runs["baseline"]
    ok_all = True
    print(f"current {cur[0]['package']} vs baseline {base[0]['package']}, {args.rounds} "
          f"rounds, load {os.getloadavg()[0]:.1f}")
    print(f"| input | frames | boxes equal ({args.tol:g}) | current ms / frame, median (p90) | "
          "baseline ms / frame, median (p90) | current / baseline |")
    print("|---|---|---|---|---|---|")
    for name in cur[0]:
        if name == "package":
            continue
        ok, why = same_boxes(cur[0][name]["boxes"], base[0][name]["boxes"], args.tol)
        ok_all &= ok and cur[0][name]["modes"] == base[0][name]["modes"]
        fig = []
        for rs in (cur, base):
            best = np.min([r[name]["ms"] for r in rs], axis=0)
            fig.append((float(np.median(best)), float(np.percentile(best, 90))))
        print(f"| {name} | {len(cur[0][name]['boxes'])} | {'yes' if ok else 'NO ' + why} | "
              f"{fig[0][0]:.2f} ({fig[0][1]:.2f}) | {fig[1][0]:.2f} ({fig[1][1]:.2f}) | "
              f"{fig[0][0] / fig[1][0]:.2f} |")
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
