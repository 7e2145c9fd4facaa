"""Figures and a picture of every preset of :mod:`mk_tracker.synthetic.presets`.

For each preset it prints and tabulates the frame count, image sizes and thermal encoding,
the number of targets, the range of box heights (scale change), the smallest visible
fraction and the number of (target, frame) pairs with a target fully hidden (< 1% visible)
but inside the image, and the thermal value range; it writes ``docs/synthetic_scenes.md``
and ``docs/images/synthetic_scenes.jpg`` (RGB beside thermal, middle frame of each preset).
Run from the repository::

    .venv/bin/python benchmarks/scene_gallery.py
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from mk_tracker.synthetic.presets import PRESETS  # noqa: E402
from mk_tracker.synthetic.scene_config import SceneFrame  # noqa: E402
from mk_tracker.messages.image_conversion import to_bgr  # noqa: E402

PANE = (256, 192)
RGB_CONDITIONS = """\
RGB conditions for static-camera tests (`SceneConfig`): `rgb_shadow_strength` and
`rgb_shadow_length` (a cast shadow on the ground beside each person's feet, not part of
its box), `rgb_illumination_drift` (the image gain moving linearly over the clip);
`far_view_scene(stop_fraction=...)` stops some walkers for good on their way across. The
`static_camera` preset (issue #13's test scene) combines them over a ground plane (sizes
proportional to the row of the feet, adults 72-88 px at 80% of the image height):
`mk_tracker generate --preset static_camera --fps 7 --seed S --out scene`. Walking speeds
are set in px/s, so another `--fps` changes the motion per frame, not the pace."""


def pane(frame: SceneFrame, encoding: str, title: str) -> np.ndarray:
    rgb = cv2.resize(frame.rgb, PANE, interpolation=cv2.INTER_AREA)
    thermal = cv2.resize(to_bgr(np.nan_to_num(frame.thermal), encoding), PANE,
                         interpolation=cv2.INTER_AREA)
    out = np.hstack([rgb, thermal])
    (tw, th), _ = cv2.getTextSize(title, cv2.FONT_HERSHEY_SIMPLEX, 0.5, 1)
    cv2.rectangle(out, (0, 0), (tw + 10, th + 10), (0, 0, 0), -1)
    cv2.putText(out, title, (5, th + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1,
                cv2.LINE_AA)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=str(REPO / "docs" / "synthetic_scenes.md"))
    args = parser.parse_args(argv)
    command = " ".join([".venv/bin/python benchmarks/scene_gallery.py"] +
                       (argv if argv is not None else sys.argv[1:]))
    out = Path(args.out)
    image_path = out.parent / "images" / "synthetic_scenes.jpg"
    lines = ["# Synthetic scene presets", "", "Produced by:", "", "```", command, "```", "",
             "Presets of `mk_tracker.synthetic.presets` with their default arguments and seed "
             f"{args.seed} (`crowd`: 15 people).  Heights are box heights in thermal px; "
             "'hidden' counts (target, frame) pairs with visible_fraction < 0.01 while the "
             "box is inside the thermal image.", "",
             "| preset | frames | RGB | thermal | targets | box height min-max | "
             "min visible | hidden | thermal min-max |", "|---|---|---|---|---|---|---|---|---|"]
    panes = []
    for name, factory in PRESETS.items():
        scene = factory(n_people=15, seed=args.seed) if name == "crowd" else \
            factory(seed=args.seed)
        enc = scene.config.thermal_encoding
        heights, vis, hidden = [], [], 0
        tmin, tmax = np.inf, -np.inf
        for i in range(len(scene)):
            for obj in scene.ground_truth(i):
                heights.append(obj.box_thermal[3])
                vis.append(obj.visible_fraction)
                hidden += int(obj.in_frame and obj.visible_fraction < 0.01)
        for i in range(0, len(scene), max(1, len(scene) // 10)):
            t = scene.frame(i).thermal
            tmin, tmax = min(tmin, float(np.nanmin(t))), max(tmax, float(np.nanmax(t)))
        mid = scene.frame(len(scene) // 2)
        panes.append(pane(mid, enc, f"{name} #{mid.index}"))
        row = (f"| {name} | {len(scene)} | {scene.rgb_size[0]}x{scene.rgb_size[1]} | "
               f"{scene.thermal_size[0]}x{scene.thermal_size[1]} {enc} | "
               f"{len(scene.config.people)} | {min(heights):.0f}-{max(heights):.0f} | "
               f"{min(vis):.2f} | {hidden} | {tmin:g}-{tmax:g} |")
        print(row)
        lines.append(row)
    if len(panes) % 2:
        panes.append(np.zeros_like(panes[0]))
    grid = np.vstack([np.hstack(panes[i:i + 2]) for i in range(0, len(panes), 2)])
    image_path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(image_path), grid, [cv2.IMWRITE_JPEG_QUALITY, 80])
    lines += ["", "Middle frame of each preset, RGB (left) and thermal (right, display "
              "scaling of `mk_tracker.messages.image_conversion.to_bgr`):", "",
              f"![presets](images/{image_path.name})", "", RGB_CONDITIONS, ""]
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {out} and {image_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
