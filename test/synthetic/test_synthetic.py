"""Behaviour of the synthetic scene generator: determinism, ground truth against the pixels,
occlusion, the paper's synthetic test, homography, encodings and bad input."""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest

from mk_tracker.boxes import transform_box
from mk_tracker.synthetic.presets import (CROSS_MODAL_HOMOGRAPHY, PRESETS, approach_scene,
                                          cross_modal_scene, crossing_scene, crowd_scene,
                                          enter_leave_scene, occlusion_scene, paper_scene,
                                          static_warm_objects_scene)
from mk_tracker.synthetic.scene import make_scene
from mk_tracker.synthetic.scene_config import (OccluderSpec, PersonSpec, SceneConfig, SceneError,
                                               SceneIndexError)


def colour_match(img: np.ndarray, colour, cos_min: float = 0.985, min_norm: float = 40.0):
    """Pixels whose BGR direction is within a small angle of ``colour`` (stripes and noise
    change brightness, not hue) and that are not near-black."""
    px = img.reshape(-1, 3).astype(np.float64)
    c = np.asarray(colour, np.float64)
    norms = np.linalg.norm(px, axis=1)
    cos = (px @ c) / np.maximum(norms * np.linalg.norm(c), 1e-9)
    return ((cos > cos_min) & (norms > min_norm)).reshape(img.shape[:2])


def body_pixels(frame, colours) -> np.ndarray:
    upper, lower = colours
    return colour_match(frame.rgb, upper) | colour_match(frame.rgb, lower)


def crop(img, box, margin=0):
    x, y, w, h = (int(round(v)) for v in box)
    H, W = img.shape[:2]
    return img[max(y - margin, 0):min(y + h + margin, H), max(x - margin, 0):min(x + w + margin, W)]


def ring_mask(shape, box, inner_margin, outer_margin):
    H, W = shape
    yy, xx = np.mgrid[0:H, 0:W]
    x, y, w, h = box

    def inside(m):
        return (xx >= x - m) & (xx < x + w + m) & (yy >= y - m) & (yy < y + h + m)
    return inside(outer_margin) & ~inside(inner_margin)


# ---------------------------------------------------------------- determinism, random access

def test_same_seed_gives_identical_frames_and_another_seed_differs():
    a, b, c = crowd_scene(5, seed=3, frames=60), crowd_scene(5, seed=3, frames=60), \
        crowd_scene(5, seed=4, frames=60)
    for i in (0, 31, 59):
        fa, fb, fc = a.frame(i), b.frame(i), c.frame(i)
        assert np.array_equal(fa.rgb, fb.rgb) and np.array_equal(fa.thermal, fb.thermal)
        assert fa.objects == fb.objects
        assert not np.array_equal(fa.rgb, fc.rgb)
        assert not np.array_equal(fa.thermal, fc.thermal)
        assert [o.box_thermal for o in fa.objects] != [o.box_thermal for o in fc.objects]


def test_random_access_equals_sequential_rendering():
    scene = crossing_scene(seed=7, frames=40)
    sequential = [scene.frame(i) for i in range(40)]
    fresh = crossing_scene(seed=7, frames=40)
    for i in (39, 0, 17, 17, 25):
        f = fresh.frame(i)
        assert np.array_equal(f.rgb, sequential[i].rgb)
        assert np.array_equal(f.thermal, sequential[i].thermal)
        assert f.objects == sequential[i].objects
        assert f.stamp == pytest.approx(i / 25.0)
    # consecutive frames differ (sensor noise and motion)
    assert not np.array_equal(sequential[10].rgb, sequential[11].rgb)
    # ground_truth() without rendering agrees with the rendered frame
    assert fresh.ground_truth(17) == sequential[17].objects


def test_long_scene_is_lazy_and_its_last_frame_renders():
    scene = crowd_scene(3, seed=1, frames=10_000)
    assert len(scene) == 10_000
    last = scene.frame(9_999)
    assert last.stamp == pytest.approx(9_999 / 25.0)
    assert last.rgb.shape == (480, 640, 3) and last.rgb.dtype == np.uint8
    assert np.array_equal(scene.frame(-1).thermal, last.thermal)


# ---------------------------------------------------------------- ground truth vs pixels

def test_rgb_box_contains_the_body_colours_and_the_margin_does_not():
    scene = crossing_scene(seed=2)
    frame = scene.frame(5)  # the two people are far apart
    for obj in frame.objects:
        assert obj.visible_fraction == 1.0 and obj.in_frame
        body = body_pixels(frame, scene.colors[obj.id])
        x, y, w, h = obj.box_rgb
        inside = crop(body, obj.box_rgb)
        assert inside.mean() > 0.35, obj.id
        ring = ring_mask(body.shape, obj.box_rgb, 2, 12)
        assert body[ring].mean() < 0.01, obj.id
        # the box is tight: body pixels reach all four sides (within 2 px)
        ys, xs = np.nonzero(crop(body, obj.box_rgb, margin=3))
        assert xs.min() <= 3 + 0.08 * w and ys.min() <= 3 + 0.25 * h  # head is skin, not body
        assert xs.max() >= w + 2 - 0.08 * w and ys.max() >= h + 2 - 0.1 * h  # shoes are dark


def test_thermal_box_is_warm_and_its_surroundings_are_not():
    scene = make_scene(dataclasses.replace(crossing_scene(seed=2).config,
                                           thermal_encoding="32FC1"))
    frame = scene.frame(5)
    kelvin = frame.thermal
    assert kelvin.dtype == np.float32
    for obj in frame.objects:
        inside = crop(kelvin, obj.box_thermal)
        ring = ring_mask(kelvin.shape, obj.box_thermal, 2, 12)
        assert np.percentile(inside, 90) > 303.0      # torso 303 K, head 307 K
        assert np.percentile(kelvin[ring], 99) < 296.0  # background 293 +- 1 K + noise


# ---------------------------------------------------------------- occlusion

def test_full_occluder_hides_the_person_for_about_hidden_frames():
    scene = occlusion_scene(seed=0, hidden_frames=20, full=True)
    colours = scene.colors[1]
    vis = np.array([scene.ground_truth(i)[0].visible_fraction for i in range(len(scene))])
    assert vis[0] == 1.0 and vis[-1] == 1.0
    hidden = np.nonzero(vis < 0.01)[0]
    assert 20 <= len(hidden) <= 24
    assert np.all(np.diff(hidden) == 1)  # one contiguous stretch
    # the pixels agree: while hidden, none of the person's colours is in the image
    mid = int(hidden[len(hidden) // 2])
    f = scene.frame(mid)
    assert f.objects[0].in_frame
    assert body_pixels(f, colours).sum() < 20
    assert body_pixels(scene.frame(0), colours).sum() > 1500


def test_partial_occluder_hides_the_lower_body_only():
    scene = occlusion_scene(seed=0, hidden_frames=20, full=False)
    upper, lower = scene.colors[1]
    f = scene.frame(len(scene) // 2)
    obj = f.objects[0]
    assert 0.4 < obj.visible_fraction < 0.75
    box_pixels = crop(f.rgb, obj.box_rgb)
    assert colour_match(box_pixels, upper).sum() > 800
    assert colour_match(box_pixels, lower).sum() < 20
    f0 = scene.frame(0)
    assert colour_match(crop(f0.rgb, f0.objects[0].box_rgb), lower).sum() > 500


def test_crossing_is_a_full_mutual_occlusion_with_depth_order():
    scene = crossing_scene(seed=1)
    vis = np.array([[o.visible_fraction for o in scene.ground_truth(i)]
                    for i in range(len(scene))])
    assert np.all(vis[:, 0] == 1.0)           # the closer person is always in front
    hidden = np.nonzero(vis[:, 1] < 0.01)[0]
    assert len(hidden) >= 5
    assert vis[0, 1] == 1.0 and vis[-1, 1] == 1.0
    f = scene.frame(int(hidden[len(hidden) // 2]))
    back_colours = scene.colors[2]
    assert body_pixels(f, back_colours).sum() < 5
    b1, b2 = f.objects[0].box_rgb, f.objects[1].box_rgb
    assert b2[0] >= b1[0] and b2[0] + b2[2] <= b1[0] + b1[2]  # box 2 inside box 1


# ---------------------------------------------------------------- the paper's synthetic test

def test_paper_scene_matches_schizas_2018_section_6():
    scene = paper_scene(seed=11)
    assert len(scene) == 60
    frames = [scene.frame(i) for i in range(60)]
    f = frames[0]
    assert f.thermal.shape == (100, 100) and f.thermal.dtype == np.uint8
    assert len(f.objects) == 3
    centres = np.array([[[o.box_thermal[0] + o.box_thermal[2] / 2,
                          o.box_thermal[1] + o.box_thermal[3] / 2] for o in fr.objects]
                        for fr in frames])  # (60, 3, 2)
    for fr in frames:
        mask = np.zeros((100, 100), bool)
        for o in fr.objects:
            assert o.box_thermal[2:] == (10.0, 10.0)
            x, y = int(round(o.box_thermal[0])), int(round(o.box_thermal[1]))
            patch = fr.thermal[y:y + 10, x:x + 10]
            assert patch.shape == (10, 10)
            assert patch.min() >= 240 and patch.max() <= 255
            mask[max(y - 1, 0):y + 11, max(x - 1, 0):x + 11] = True
        background = fr.thermal[~mask].astype(np.float64)
        assert background.var() == pytest.approx(20.0, rel=0.12)
        assert background.max() < 100
    all_bg = np.concatenate([fr.thermal[:, :].astype(float).ravel() for fr in frames])
    assert np.mean(all_bg > 200) < 0.05
    # object pixels vary within 240..255 (not a constant)
    o = frames[30].objects[0]
    x, y = int(round(o.box_thermal[0])), int(round(o.box_thermal[1]))
    assert len(np.unique(frames[30].thermal[y:y + 10, x:x + 10])) > 8
    # directions: 1 left->right, 2 top->bottom, 3 right->left, each across the frame
    d = centres[-1] - centres[0]
    assert d[0, 0] > 80 and abs(d[0, 1]) < 1e-6
    assert d[1, 1] > 80 and abs(d[1, 0]) < 1e-6
    assert d[2, 0] < -80 and abs(d[2, 1]) < 1e-6
    steps = np.diff(centres, axis=0)
    assert np.allclose(np.linalg.norm(steps, axis=2), steps[0, 0, 0])  # constant speed
    # the objects never overlap
    for fr in frames:
        assert all(o.visible_fraction == 1.0 for o in fr.objects)
    # the noise is independent over time too: a corner no object visits
    corner = np.stack([fr.thermal[0:15, 0:40].astype(np.float64) for fr in frames])
    assert corner.var(axis=0).mean() == pytest.approx(20.0, rel=0.08)
    assert corner.mean() == pytest.approx(20.0, abs=0.2)
    centred = corner - corner.mean(axis=0)
    lag1 = (centred[1:] * centred[:-1]).mean() / centred.var()
    assert abs(lag1) < 0.05


# ---------------------------------------------------------------- geometry of other presets

def test_approach_scene_grows_the_box_as_the_person_comes_closer():
    scene = approach_scene(seed=0)
    heights = np.array([scene.ground_truth(i)[0].box_thermal[3] for i in range(len(scene))])
    feet = np.array([scene.foot_points(i)[0, 1] for i in range(len(scene))])
    assert np.all(np.diff(feet) > 0)
    assert np.all(np.diff(heights) > 0)
    assert heights[-1] / heights[0] > 2.5
    for i in (0, len(scene) - 1):
        f = scene.frame(i)
        x, y, w, h = f.objects[0].box_rgb
        assert 2.5 <= h / w <= 3.0
        assert body_pixels(f, scene.colors[1]).sum() > 0.2 * w * h


def test_enter_leave_scene_flags_in_frame():
    scene = enter_leave_scene(seed=0)
    first, last = scene.ground_truth(0), scene.ground_truth(len(scene) - 1)
    assert not first[0].in_frame and first[0].visible_fraction == 0.0
    assert last[0].in_frame and last[0].visible_fraction == 1.0
    assert first[1].in_frame and first[1].visible_fraction == 1.0
    assert not last[1].in_frame and last[1].visible_fraction == 0.0
    # partially outside: visible fraction strictly between 0 and 1
    partial = [o.visible_fraction for i in range(len(scene))
               for o in scene.ground_truth(i)[:1] if 0.0 < o.visible_fraction < 1.0]
    assert partial and all(0 < v < 1 for v in partial)


def test_crowd_has_requested_people_crossings_and_occluders():
    scene = crowd_scene(15, seed=5, frames=200)
    gt = [scene.ground_truth(i) for i in range(0, 200, 5)]
    assert [o.id for o in gt[0]] == list(range(1, 16))
    vis = np.array([[o.visible_fraction for o in g] for g in gt])
    assert (vis < 0.5).sum() > 10          # occlusions happen
    assert len(scene.config.occluders) == 2
    heights = np.array([[o.box_thermal[3] for o in g] for g in gt])
    assert heights.max() / heights.min() > 1.3  # perspective
    # every person moves and changes direction at least once
    feet = np.array([scene.foot_points(i) for i in range(200)])
    v = np.diff(feet, axis=0)
    headings = np.arctan2(v[..., 1], v[..., 0])
    assert np.all(np.ptp(np.unwrap(headings, axis=0), axis=0) > 0.3)
    # different people get different colours
    assert len({scene.colors[k][0] for k in range(1, 16)}) == 15


# ---------------------------------------------------------------- homography, encodings

def test_cross_modal_boxes_are_related_by_the_homography():
    scene = cross_modal_scene(seed=0)
    H = np.asarray(CROSS_MODAL_HOMOGRAPHY).reshape(3, 3)
    assert scene.thermal_size == (320, 240) and scene.rgb_size == (640, 480)
    assert np.allclose(scene.homography, H)
    f = scene.frame(50)
    assert f.thermal.shape == (240, 320) and f.rgb.shape == (480, 640, 3)
    for obj in f.objects:
        assert np.allclose(obj.box_rgb, transform_box(obj.box_thermal, H))
        assert obj.box_rgb[2] > 1.8 * obj.box_thermal[2]
        x, y, w, h = obj.box_rgb
        assert crop(body_pixels(f, scene.colors[obj.id]), obj.box_rgb).mean() > 0.3
        # the thermal box holds the warm body: mono16 is centikelvin
        assert np.percentile(crop(f.thermal, obj.box_thermal), 90) > 30_300
    assert np.median(f.thermal) == pytest.approx(29_300, abs=150)


def test_cross_modal_scene_with_a_640x512_thermal_camera():
    scene = cross_modal_scene(seed=0, frames=60, thermal_size=(640, 512))
    small = cross_modal_scene(seed=0, frames=60)
    assert scene.thermal_size == (640, 512)
    f, g = scene.frame(30), small.frame(30)
    assert f.thermal.shape == (512, 640)
    for obj, ref in zip(f.objects, g.objects):
        assert np.allclose(obj.box_rgb, transform_box(obj.box_thermal, scene.homography))
        assert obj.box_thermal[3] == pytest.approx(ref.box_thermal[3] * 512 / 240)
        cx, cy = obj.box_rgb[0] + obj.box_rgb[2] / 2, obj.box_rgb[1] + obj.box_rgb[3]
        rx, ry = ref.box_rgb[0] + ref.box_rgb[2] / 2, ref.box_rgb[1] + ref.box_rgb[3]
        assert abs(cx - rx) < 3.0 and abs(cy - ry) < 3.0  # same place in the RGB image
    with pytest.raises(SceneError):
        cross_modal_scene(thermal_size=(0, 10))


def test_replaced_builds_a_variant_and_rejects_unknown_fields():
    base = paper_scene(seed=1)
    lossy = base.replaced(missing_pixel_fraction=0.05)
    assert lossy.config.missing_pixel_fraction == 0.05
    assert (lossy.frame(3).thermal == 0).mean() == pytest.approx(0.05, abs=0.01)
    assert (base.frame(3).thermal == 0).mean() == 0.0
    with pytest.raises(SceneError):
        base.replaced(no_such_field=1)
    with pytest.raises(SceneError):
        base.replaced(missing_pixel_fraction=1.5)


def test_default_homography_scales_between_plane_sizes():
    cfg = SceneConfig(width=640, height=480, thermal_width=320, thermal_height=240,
                      frames=2, people=(PersonSpec(waypoints=((100.0, 200.0),)),))
    scene = make_scene(cfg)
    assert np.allclose(scene.homography, np.diag([2.0, 2.0, 1.0]))
    obj = scene.frame(0).objects[0]
    assert np.allclose(obj.box_rgb, [2 * v for v in obj.box_thermal])
    same = make_scene(dataclasses.replace(cfg, thermal_width=0, thermal_height=0))
    assert np.allclose(same.homography, np.eye(3))


@pytest.mark.parametrize("encoding", ["mono8", "mono16", "32FC1"])
def test_missing_pixel_fraction_is_measured(encoding):
    cfg = dataclasses.replace(crowd_scene(2, seed=0, frames=3).config,
                              thermal_encoding=encoding, missing_pixel_fraction=0.05)
    scene = make_scene(cfg)
    clean = make_scene(dataclasses.replace(cfg, missing_pixel_fraction=0.0))
    for i in range(3):
        t = scene.frame(i).thermal
        missing = np.isnan(t) if encoding == "32FC1" else t == 0
        assert missing.mean() == pytest.approx(0.05, abs=0.005)
        c = clean.frame(i).thermal
        assert not (np.isnan(c).any() if encoding == "32FC1" else (c == 0).any())
        # the other pixels are unchanged
        assert np.array_equal(t[~missing], c[~missing])


def test_static_warm_objects_are_static_and_warmer_than_the_person():
    base = static_warm_objects_scene(seed=0)
    scene = make_scene(dataclasses.replace(base.config, thermal_encoding="32FC1"))
    boxes = [o.box for o in scene.config.warm_objects]
    means = []
    for i in range(0, len(scene), 9):
        f = scene.frame(i)
        means.append([crop(f.thermal, b)[4:-4, 4:-4].mean() for b in boxes])
        person = crop(f.thermal, f.objects[0].box_thermal)
        assert np.nanmax(person) < min(m for m in means[-1]) - 5.0
    means = np.array(means)
    assert np.all(means > 315.0)
    assert np.all(np.ptp(means, axis=0) < 0.1)  # never moving, only sensor noise
    # a threshold between the person and the radiators flags only the radiators; one below
    # the person's torso also flags the radiators: they are false people for a threshold
    f = scene.frame(40)
    hot = f.thermal > 310.0
    assert hot[crop_mask(f.thermal.shape, f.objects[0].box_thermal)].sum() == 0
    assert all(hot[crop_mask(f.thermal.shape, b)].mean() > 0.8 for b in boxes[:2])


def crop_mask(shape, box):
    m = np.zeros(shape, bool)
    x, y, w, h = (int(round(v)) for v in box)
    m[max(y, 0):y + h, max(x, 0):x + w] = True
    return m


def test_thermal_blur_softens_edges_but_keeps_the_mean():
    sharp = make_scene(dataclasses.replace(crossing_scene(seed=3, frames=2).config,
                                           thermal_encoding="32FC1", thermal_noise_std=0.0))
    soft = sharp.replaced(thermal_blur_sigma=2.0)
    a, b = sharp.frame(1).thermal, soft.frame(1).thermal
    grad_a = np.abs(np.diff(a, axis=1)).max()
    grad_b = np.abs(np.diff(b, axis=1)).max()
    assert grad_a > 5.0 and grad_b < 0.5 * grad_a
    assert b.mean() == pytest.approx(a.mean(), abs=0.01)
    assert sharp.frame(1).objects == soft.frame(1).objects


def test_mono8_and_mono16_encode_the_same_temperatures():
    cfg = crowd_scene(3, seed=2, frames=2).config
    k = make_scene(dataclasses.replace(cfg, thermal_encoding="32FC1")).frame(1).thermal
    m16 = make_scene(dataclasses.replace(cfg, thermal_encoding="mono16")).frame(1).thermal
    m8 = make_scene(dataclasses.replace(cfg, thermal_encoding="mono8")).frame(1).thermal
    assert m16.dtype == np.uint16 and m8.dtype == np.uint8
    assert np.abs(m16 / 100.0 - k).max() <= 0.0051
    expected8 = np.clip((k - 288.0) * 255.0 / 30.0, 0, 255)
    assert np.abs(m8 - expected8).max() <= 0.51


# ---------------------------------------------------------------- bad input

def test_bad_configs_and_indices_raise_scene_error():
    with pytest.raises(SceneError):
        make_scene(SceneConfig(frames=0))
    with pytest.raises(SceneError):
        make_scene(SceneConfig(thermal_encoding="rgb8"))
    with pytest.raises(SceneError):
        make_scene(SceneConfig(people=(PersonSpec(waypoints=()),)))
    with pytest.raises(SceneError):
        make_scene(SceneConfig(people=(PersonSpec(waypoints=((1.0, float("nan")),)),)))
    with pytest.raises(SceneError):
        make_scene(SceneConfig(people=(PersonSpec(upper_color=(300, 0, 0)),)))
    with pytest.raises(SceneError):
        make_scene(SceneConfig(occluders=(OccluderSpec(box=(0, 0, -5, 10)),)))
    with pytest.raises(SceneError):
        make_scene(SceneConfig(homography=(0.0,) * 9))
    with pytest.raises(SceneError):
        make_scene({"frames": 3})
    scene = paper_scene()
    with pytest.raises(SceneIndexError):
        scene.frame(60)
    with pytest.raises(IndexError):
        scene.frame(-61)
    with pytest.raises(SceneError):
        scene.frame(1.5)
    with pytest.raises(SceneError):
        crowd_scene(-1)
    assert isinstance(SceneError("x"), ValueError)
    # iteration stops at the end
    assert sum(1 for _ in paper_scene()) == 60


def test_texture_is_fixed_to_the_body_and_the_head_is_warmest():
    scene = make_scene(dataclasses.replace(crossing_scene(seed=4).config,
                                           thermal_encoding="32FC1"))

    def torso(frame, obj_id=1):
        x, y, w, h = (int(round(v)) for v in frame.object(obj_id).box_rgb)
        return frame.rgb[y + int(0.25 * h):y + int(0.5 * h),
                         x + int(0.3 * w):x + int(0.7 * w)].astype(float)

    f0, f10 = scene.frame(0), scene.frame(10)
    assert f10.object(1).box_rgb[0] - f0.object(1).box_rgb[0] == pytest.approx(30.0)
    a, b = torso(f0), torso(f10)
    assert a.shape == b.shape
    assert a.std() > 12.0                       # a pattern, not a flat colour (noise is 4)
    assert np.abs(a - b).mean() < 7.0           # the same pattern 30 px later
    assert np.abs(a - np.roll(b, 5, axis=(0, 1))).mean() > 1.5 * np.abs(a - b).mean()
    # thermal: head warmer than torso warmer than legs
    x, y, w, h = (int(round(v)) for v in f0.object(1).box_thermal)
    k = f0.thermal
    head = k[y + int(0.03 * h):y + int(0.12 * h), x + int(0.4 * w):x + int(0.6 * w)].mean()
    chest = k[y + int(0.25 * h):y + int(0.5 * h), x + int(0.3 * w):x + int(0.7 * w)].mean()
    legs_row = k[y + int(0.8 * h):y + int(0.9 * h), x:x + w]
    legs = legs_row[legs_row > 296.0].mean()
    assert head > chest + 2.0 and chest > legs + 1.0 and legs > 296.0



@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_preset_rejects_bad_arguments_and_accepts_one_frame(name):
    factory = PRESETS[name]
    with pytest.raises(SceneError):
        factory(seed=-1)
    with pytest.raises(SceneError):
        factory(seed=1.5)
    if "frames" in inspect.signature(factory).parameters:
        with pytest.raises(SceneError):
            factory(seed=0, frames=0)
        scene = factory(seed=0, frames=1)
        assert len(scene) == 1
        frame = scene.frame(0)
        assert frame.rgb.shape == (scene.rgb_size[1], scene.rgb_size[0], 3)
    if name == "crowd":
        for bad in ({"n_people": -1}, {"occluders": -2}, {"width": 0}, {"height": 4}):
            with pytest.raises(SceneError):
                factory(seed=0, frames=2, **bad)


def test_far_view_scene_is_7_fps_small_people_entering_and_leaving_at_the_edges():
    from mk_tracker.synthetic.people import PERSON_ASPECT
    from mk_tracker.synthetic.presets import far_view_scene
    scene = far_view_scene(seed=3, frames=40)
    cfg = scene.config
    assert cfg.fps == 7.0 and scene.frame(1).stamp == pytest.approx(1.0 / 7.0)
    assert len(cfg.people) == 10
    for p in cfg.people:
        assert 50.0 <= p.height <= 105.0 * 1.05 + 1e-9          # pairs: +5% for the second
        assert 18.0 <= p.height * PERSON_ASPECT <= 40.0           # 18-38 px wide (+5%)
        (x0, _), (x1, _) = p.waypoints
        # starts outside one edge and walks across towards the other, then straight on
        # (after_last "continue") until it has left the image
        assert (x0 < 0 and x1 > x0 + 600) or (x0 > 640 and x1 < x0 - 600)
        assert 6.0 <= p.speed <= 16.0 and p.after_last == "continue"
    with pytest.raises(SceneError):
        far_view_scene(n_people=-1)
    with pytest.raises(SceneError):
        far_view_scene(fps=0.0)


# ---------------------------------------------------------------- RGB shadows, lighting drift

def _standing_person_scene(**changes):
    """One person standing at foot point (200, 300), 100 px tall, on a flat noiseless
    background of grey 120 (every RGB change is the one under test)."""
    person = PersonSpec(waypoints=((200.0, 300.0),), speed=0.0, height=100.0)
    cfg = SceneConfig(seed=1, frames=3, width=400, height=400, rgb_noise_std=0.0,
                      rgb_background="flat", rgb_background_level=120, people=(person,))
    return make_scene(dataclasses.replace(cfg, **changes))


def test_cast_shadow_darkens_the_ground_beside_the_feet_and_nothing_else():
    plain = _standing_person_scene().frame(0)
    shaded = _standing_person_scene(rgb_shadow_strength=0.5, rgb_shadow_length=1.0).frame(0)
    x, y, w, h = plain.object(1).box_rgb
    foot_y = int(round(y + h)) - 1
    # one person height long from the feet to the right: the ground 30 px right of the
    # box, at the feet, is half as bright; the same distance to the left is not shadowed
    right = shaded.rgb[foot_y, int(x + w + 30)]
    assert np.array_equal(plain.rgb[foot_y, int(x + w + 30)], [120, 120, 120])
    assert np.array_equal(right, [60, 60, 60])
    assert np.array_equal(shaded.rgb[foot_y, int(x - 30)], [120, 120, 120])
    # well above the feet (the upper body's row band) nothing changes, person included
    top = slice(int(y), int(y + 0.6 * h))
    assert np.array_equal(shaded.rgb[top], plain.rgb[top])
    # the ground truth does not include the shadow
    assert shaded.object(1).box_rgb == plain.object(1).box_rgb


def test_illumination_drift_scales_the_image_linearly_in_time():
    plain = _standing_person_scene()
    drift = _standing_person_scene(rgb_illumination_drift=-0.5)
    assert np.array_equal(drift.frame(0).rgb, plain.frame(0).rgb)     # gain 1 at the start
    # gain 0.75 at the middle frame, 0.5 at the last: grey 120 -> 90 -> 60
    assert np.array_equal(drift.frame(1).rgb[5, 5], [90, 90, 90])
    assert np.array_equal(drift.frame(2).rgb[5, 5], [60, 60, 60])
    assert drift.frame(2).objects == plain.frame(2).objects


def test_far_view_stops_keep_the_walkers_and_stop_them_inside_the_image():
    from mk_tracker.synthetic.presets import far_view_scene
    walking = far_view_scene(seed=4, frames=60).config.people
    stopping = far_view_scene(seed=4, frames=60, stop_fraction=1.0).config.people
    # the same walkers (the stops draw from a stream of their own) ...
    assert [(p.speed, p.height, p.start_frame, p.waypoints[0]) for p in walking] == \
        [(p.speed, p.height, p.start_frame, p.waypoints[0]) for p in stopping]
    for walk, stop in zip(walking, stopping):
        (x0, y0), (x1, y1) = walk.waypoints
        (sx, sy) = stop.waypoints[1]
        # ... each stopping for good 30-70% of its way across, inside the image
        t = (sx - x0) / (x1 - x0)
        assert stop.after_last == "stop" and 0.3 <= t <= 0.7
        assert sy == pytest.approx(y0 + t * (y1 - y0))
        assert 0.0 < sx < 640.0
    with pytest.raises(SceneError):
        far_view_scene(stop_fraction=1.5)


def test_static_camera_preset_has_stops_shadows_drift_and_takes_a_frame_rate():
    from mk_tracker.synthetic.scene_bag import SceneBagError, build_preset
    scene = build_preset("static_camera", seed=2, frames=5, fps=25.0)
    cfg = scene.config
    assert cfg.fps == 25.0
    assert cfg.rgb_shadow_strength == 0.45 and cfg.rgb_illumination_drift == -0.25
    assert 0 < sum(p.after_last == "stop" for p in cfg.people) < len(cfg.people)
    # a ground plane: adults of 72-88 px at the reference row (80% of 480), sizes
    # proportional to the row of the feet
    assert cfg.perspective == 1.0
    assert all(72.0 <= p.height <= 88.0 * 1.05 + 1e-9 for p in cfg.people)
    boxes = scene.boxes_thermal(0)
    for (x, y, w, h), p in zip(boxes, cfg.people):
        assert h == pytest.approx(max(4.0, p.height * (y + h) / 384.0))
    with pytest.raises(SceneBagError, match="does not take --fps"):
        build_preset("crowd", fps=7.0)


def test_static_camera_takes_smaller_people_and_slower_walkers():
    from mk_tracker.synthetic.presets import static_camera_scene
    base = static_camera_scene(seed=3, frames=30).config.people
    far = static_camera_scene(seed=3, frames=30, heights=(40.0, 60.0),
                              speed_scale=0.5).config.people
    assert all(40.0 <= p.height <= 60.0 * 1.05 + 1e-9 for p in far)
    assert not all(72.0 <= p.height for p in far)
    for a, b in zip(base, far):
        assert b.speed == pytest.approx(a.speed * 0.5, abs=2e-3)


def test_far_view_walkers_keep_their_speed_in_seconds_at_another_frame_rate():
    from mk_tracker.synthetic.presets import far_view_scene
    slow = far_view_scene(seed=6, frames=30).config.people
    fast = far_view_scene(seed=6, frames=30, fps=28.0).config.people
    # four times the frame rate: a quarter of the motion per frame (rounded to 3 decimals)
    for a, b in zip(slow, fast):
        assert b.speed == pytest.approx(a.speed / 4.0, abs=1e-3)


def test_crowd_stops_cut_the_same_walks_and_people_then_stand_still():
    walking = crowd_scene(6, seed=3, frames=300)
    assert crowd_scene(6, seed=3, frames=300, stop_fraction=0.0).config == walking.config
    scene = crowd_scene(6, seed=3, frames=300, stop_fraction=1.0)
    feet = np.array([scene.foot_points(i) for i in range(300)])
    for k, (walk, stop) in enumerate(zip(walking.config.people, scene.config.people)):
        # the same walk (the stops draw from a stream of their own), cut at a waypoint
        n = len(stop.waypoints)
        assert 2 <= n < len(walk.waypoints) and stop.waypoints == walk.waypoints[:n]
        assert (stop.speed, stop.height) == (walk.speed, walk.height)
        legs = np.hypot(*np.diff(np.array(stop.waypoints), axis=0).T)
        # within half the clip's walk, unless the first leg alone is longer
        assert n == 2 or legs.sum() <= 0.5 * 300 * stop.speed
        # standing on the last waypoint, still, over the last 60 frames (a first leg is at
        # most 0.3 * 640 = 192 px, walked at >= 1 px/frame)
        assert np.allclose(feet[-60:, k], stop.waypoints[-1])
    with pytest.raises(SceneError):
        crowd_scene(stop_fraction=-0.1)


def test_far_view_scene_speed_scale_scales_only_the_walking_speeds():
    """speed_scale (the issue #16 unseen-B proxy: small people walking as many body heights
    per second as the default ones) multiplies every speed and leaves the rest alone."""
    from mk_tracker.synthetic.presets import far_view_scene
    base = far_view_scene(seed=4, frames=30, heights=(40.0, 60.0)).config.people
    slow = far_view_scene(seed=4, frames=30, heights=(40.0, 60.0),
                          speed_scale=0.5).config.people
    assert len(base) == len(slow) and len(base) > 0
    for a, b in zip(base, slow):
        assert b.speed == pytest.approx(0.5 * a.speed, abs=1e-3)
        assert (b.height, b.waypoints, b.start_frame) == (a.height, a.waypoints, a.start_frame)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(SceneError):
            far_view_scene(seed=0, frames=2, speed_scale=bad)
