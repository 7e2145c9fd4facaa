"""Camera-motion compensation (tracking/camera_motion.py): the estimate on frames with a
known motion, its fall-backs, and the warp of a track's Kalman state (hand-computed)."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from mk_tracker.tracking.camera_motion import (CameraMotion, CameraMotionConfig,
                                               CameraMotionEstimator, compensate)
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker
from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig
from mk_tracker.tracking.track import LifecycleConfig, Track
from mk_tracker.kalman import KalmanConfig


def texture(width: int, height: int, seed: int = 0, contrast: float = 1.0) -> np.ndarray:
    """A BGR frame of blurred random blobs: corners everywhere, no repeated pattern."""
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0, 255, (height, width)).astype(np.float32)
    blurred = cv2.GaussianBlur(noise, (0, 0), 3.0)
    grey = cv2.normalize(blurred, None, 0, 255, cv2.NORM_MINMAX)
    grey = 128 + contrast * (grey - 128)
    return cv2.cvtColor(np.clip(grey, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)


def crop(world: np.ndarray, ox: float, oy: float, width: int = 640, height: int = 480):
    """The view of a camera whose top-left corner looks at world pixel (ox, oy)."""
    m = np.array([[1.0, 0.0, -ox], [0.0, 1.0, -oy]])
    return cv2.warpAffine(world, m, (width, height), flags=cv2.INTER_LINEAR)


@pytest.mark.parametrize("method", ["sparse", "ecc"])
@pytest.mark.parametrize("dx,dy", [(7.0, -4.0), (3.5, 2.25), (-12.0, 0.0)])
def test_pure_translation_is_estimated_within_half_a_pixel(method, dx, dy):
    world = texture(720, 560, seed=1)
    est = CameraMotionEstimator(CameraMotionConfig(method=method))
    assert est.estimate(crop(world, 40, 40)).status == "first"
    # the camera moves by (dx, dy): world pixel p was at p - 40, now at p - 40 - (dx, dy)
    m = est.estimate(crop(world, 40 + dx, 40 + dy))
    assert m.status == "estimated"
    np.testing.assert_allclose(m.translation, [-dx, -dy], atol=0.5)
    np.testing.assert_allclose(m.linear, np.eye(2), atol=0.01)


def test_still_camera_gives_the_identity():
    world = texture(640, 480, seed=2)
    rng = np.random.default_rng(3)
    est = CameraMotionEstimator()
    for _ in range(4):              # the same view with fresh sensor noise each frame
        noisy = np.clip(world + rng.normal(0, 3, world.shape), 0, 255).astype(np.uint8)
        m = est.estimate(noisy)
    assert m.status == "still" and m.identity and not m.fallback
    np.testing.assert_array_equal(m.matrix, [[1, 0, 0], [0, 1, 0]])
    assert est.fallbacks == 0


def test_blank_frame_gives_the_identity_and_is_counted():
    world = texture(640, 480, seed=4)
    est = CameraMotionEstimator()
    est.estimate(world)
    m = est.estimate(np.full((480, 640, 3), 90, np.uint8))
    assert m.status == "blank" and m.fallback
    np.testing.assert_array_equal(m.matrix, [[1, 0, 0], [0, 1, 0]])
    assert est.counts["blank"] == 1 and est.fallbacks == 1


def test_size_change_gives_the_identity_and_is_counted():
    est = CameraMotionEstimator()
    est.estimate(texture(640, 480, seed=5))
    m = est.estimate(texture(320, 240, seed=5))
    assert m.status == "size_change" and est.fallbacks == 1
    # the new size is the reference from now on
    assert est.estimate(texture(320, 240, seed=5)).status == "still"


def test_implausible_jump_gives_the_identity():
    world = texture(1400, 480, seed=6)
    est = CameraMotionEstimator(CameraMotionConfig(max_translation=0.05))
    est.estimate(crop(world, 100, 0))
    m = est.estimate(crop(world, 140, 0))      # 40 px > 0.05 * 640 = 32 px
    assert m.status == "implausible" and m.identity and est.fallbacks == 1


def _people_frames(camera_dx: float):
    """A low-contrast background seen by a camera moving by ``camera_dx``, and three
    high-contrast 'people' covering ~40 % of the frame walking 12 px to the right in the
    image.  Returns both frames and the people's boxes in the first."""
    world = texture(900, 480, seed=7, contrast=0.35)
    person = texture(150, 400, seed=8, contrast=1.0)
    frames, boxes = [], []
    for k, shift in enumerate((0.0, 12.0)):
        img = crop(world, 100 + k * camera_dx, 0)
        for x in (40, 250, 460):
            xi = int(x + shift)
            img[40:440, xi:xi + 150] = person
        frames.append(img)
    boxes = [(x, 40.0, 150.0, 400.0) for x in (40, 250, 460)]
    return frames, boxes


@pytest.mark.parametrize("camera_dx", [0.0, 6.0])
def test_people_inside_tracked_boxes_do_not_bias_the_estimate(camera_dx):
    (f0, f1), boxes = _people_frames(camera_dx)
    # without the boxes most corners are on the people: the estimate follows them
    blind = CameraMotionEstimator(CameraMotionConfig(min_motion=0.0))
    blind.estimate(f0)
    biased = blind.estimate(f1)
    assert biased.status == "estimated"
    assert abs(biased.translation[0] - (-camera_dx)) > 3.0
    # with the tracked boxes left out it is the camera's motion
    est = CameraMotionEstimator(CameraMotionConfig(min_motion=0.0))
    est.estimate(f0, boxes)
    m = est.estimate(f1, boxes)
    assert m.status == "estimated"
    np.testing.assert_allclose(m.translation, [-camera_dx, 0.0], atol=0.5)


def test_compensate_moves_the_track_and_its_remembered_boxes():
    t = Track(1, np.array([100.0, 50.0, 40.0, 80.0]), 0.0, score=1.0,
              kalman=KalmanConfig(), config=LifecycleConfig())
    p0 = t.kf.covariance                      # diag(4, 4, 2500, 2500) from KalmanConfig
    motion = CameraMotion(matrix=np.array([[1.0, 0.0, -15.0], [0.0, 1.0, 4.0]]),
                          status="estimated")
    assert compensate([t], motion) == 1
    np.testing.assert_allclose(t.kf.covariance, p0)             # a shift leaves P alone
    np.testing.assert_allclose(t.center, [105.0, 94.0])        # (120 - 15, 90 + 4)
    np.testing.assert_allclose(t.kf.velocity, [0.0, 0.0])
    np.testing.assert_allclose(t.detected_box, [85.0, 54.0, 40.0, 80.0])
    np.testing.assert_allclose(t.size, [40.0, 80.0])
    # the identity (a fall-back) moves nothing
    assert compensate([t], CameraMotion(status="blank")) == 0
    np.testing.assert_allclose(t.center, [105.0, 94.0])
    # a zoom by 2 about the origin: centre doubles, size and reported velocity scale
    t.smoothed_velocity = np.array([3.0, -1.0])
    compensate([t], CameraMotion(matrix=np.array([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]]),
                                 status="estimated"))
    np.testing.assert_allclose(t.center, [210.0, 188.0])
    # P' = diag(L, L) P diag(L, L)^T = 4 P: position 4 -> 16, velocity 2500 -> 10000 (px/s)^2
    np.testing.assert_allclose(np.diag(t.kf.covariance), [16.0, 16.0, 1e4, 1e4])
    np.testing.assert_allclose(t.size, [80.0, 160.0])
    np.testing.assert_allclose(t.smoothed_velocity, [6.0, -2.0])
    # detected box: centre (105, 94) -> (210, 188), size (80, 160): corner (170, 108)
    np.testing.assert_allclose(t.detected_box, [170.0, 108.0, 80.0, 160.0])


def test_tracker_counts_fallbacks_and_keeps_the_track_on_a_blank_frame():
    cfg = replace(MultiObjectTrackerConfig(use_multi_kernel=False),
                  camera_motion=CameraMotionConfig(enabled=True))
    trk = MultiObjectTracker(cfg)
    world = texture(640, 480, seed=9)
    tid = trk.start_track(world, 0.0, (300, 200, 40, 80))
    trk.step(world, 0.0)
    trk.step(np.zeros_like(world), 0.04)
    assert trk.totals["camera_motion_fallbacks"] == 1
    assert trk.camera_motion.counts.get("blank") == 1
    box = [t.box for t in trk.step(world, 0.08).tracks if t.id == tid][0]
    # never moved by a camera motion: the still track stays where it was started
    np.testing.assert_allclose(box, (300, 200, 40, 80), atol=1e-6)
    assert trk.totals["camera_motion_fallbacks"] == 2   # blank -> textured: blank again


def test_tracker_moves_a_track_by_the_camera_pan():
    cfg = replace(MultiObjectTrackerConfig(use_multi_kernel=False),
                  camera_motion=CameraMotionConfig(enabled=True))
    trk = MultiObjectTracker(cfg)
    world = texture(900, 480, seed=10)
    tid = trk.start_track(crop(world, 100, 0), 0.0, (300, 200, 40, 80))
    trk.step(crop(world, 100, 0), 0.0)
    res = trk.step(crop(world, 110, 0), 0.04)        # the camera turns 10 px right
    box = [t.box for t in res.tracks if t.id == tid][0]
    # a point of the world now 10 px further left in the image (velocity stays 0)
    assert abs(box[0] - 290.0) < 0.5 and abs(box[1] - 200.0) < 0.5
    assert trk.totals["camera_motion_fallbacks"] == 0


def _panned_walk(frames: int, speed: float):
    """A person walking 2 px/frame right under a camera panning in bursts of ``speed``
    px/frame (mk_tracker.synthetic.camera_pan), and a second person for company."""
    from mk_tracker.synthetic.camera_pan import panned_frames, robot_pan_offsets
    from mk_tracker.synthetic.scene import make_scene
    from mk_tracker.synthetic.scene_config import PersonSpec, SceneConfig

    offsets = robot_pan_offsets(frames, speed=speed, still=8, moving=10, start=(200.0, 0.0))
    width = int(max(o[0] for o in offsets)) + 650
    people = (PersonSpec(waypoints=((500.0, 400.0), (900.0, 400.0)), speed=2.0,
                         height=140.0, after_last="continue"),
              PersonSpec(waypoints=((900.0, 300.0), (400.0, 300.0)), speed=1.5,
                         height=100.0, after_last="continue"))
    scene = make_scene(SceneConfig(seed=5, frames=frames, width=width, height=480,
                                   people=people))
    return list(panned_frames(scene, offsets, 640, 480))


def test_pan_offsets_and_crops_move_the_truth_by_the_offset():
    from mk_tracker.synthetic.camera_pan import robot_pan_offsets

    offs = robot_pan_offsets(40, speed=5.0, still=2, moving=3)
    steps = np.diff([o[0] for o in offs])
    # frames 2-4 pan right, 7-9 back left; the path returns to its start every period
    assert steps.tolist()[:10] == [0, 5, 5, 5, 0, 0, -5, -5, -5, 0]
    assert offs[9][0] == offs[0][0]
    frames = _panned_walk(3, 20.0)
    x0 = frames[0].boxes[1][0]
    # the offset stands still for 8 frames: the person walks 2 px/frame to the right
    assert frames[1].boxes[1][0] == pytest.approx(x0 + 2.0, abs=0.6)


def test_hand_started_track_follows_a_panning_camera_only_with_compensation():
    frames = _panned_walk(60, 20.0)
    errors = {}
    for enabled in (False, True):
        trk = MultiObjectTracker(replace(MultiObjectTrackerConfig(),
                                         camera_motion=CameraMotionConfig(enabled=enabled)))
        tid = trk.start_track(frames[0].rgb, frames[0].stamp, frames[0].boxes[1])
        worst = 0.0
        for f in frames:
            mine = [t for t in trk.step(f.rgb, f.stamp).tracks if t.id == tid]
            assert mine, "the hand-started track was deleted"
            b, g = mine[0].box, f.boxes[1]
            worst = max(worst, float(np.hypot(b[0] + b[2] / 2 - g[0] - g[2] / 2,
                                              b[1] + b[3] / 2 - g[1] - g[3] / 2)))
        errors[enabled] = worst
    # 20 px per frame of pan: the image-pixel constant-velocity model overshoots at every
    # start and stop of the pan; compensated, the track stays on the person
    assert errors[True] < 10.0
    assert errors[False] > 30.0


def test_frames_without_tracks_are_not_estimated_but_remembered():
    cfg = replace(MultiObjectTrackerConfig(use_multi_kernel=False),
                  camera_motion=CameraMotionConfig(enabled=True))
    trk = MultiObjectTracker(cfg)
    world = texture(900, 480, seed=11)
    trk.step(crop(world, 100, 0), 0.0)
    trk.step(crop(world, 110, 0), 0.04)
    assert trk.camera_motion.counts == {}          # no track: nothing estimated
    tid = trk.start_track(crop(world, 120, 0), 0.08, (300, 200, 40, 80))
    trk.step(crop(world, 120, 0), 0.08)
    res = trk.step(crop(world, 125, 0), 0.12)
    assert trk.camera_motion.counts == {"still": 1, "estimated": 1}
    box = [t.box for t in res.tracks if t.id == tid][0]
    assert abs(box[0] - 295.0) < 0.5


def test_pan_crop_outside_the_scene_is_refused():
    from mk_tracker.synthetic.camera_pan import panned_frames, robot_pan_offsets
    from mk_tracker.synthetic.scene import make_scene
    from mk_tracker.synthetic.scene_config import SceneConfig

    scene = make_scene(SceneConfig(seed=1, frames=3, width=700, height=480))
    with pytest.raises(ValueError, match="leaves"):
        list(panned_frames(scene, [(0.0, 0.0), (61.0, 0.0)], 640, 480))
    with pytest.raises(ValueError):
        robot_pan_offsets(0)


@pytest.mark.parametrize("method", ["sparse", "ecc"])
@pytest.mark.parametrize("shape,dtype", [((1, 1, 3), np.uint8), ((3, 5, 3), np.uint8),
                                         ((12, 16, 4), np.uint8), ((60, 80), np.uint16),
                                         ((60, 80, 3), np.float32)])
def test_odd_frames_never_raise_and_give_a_status(method, shape, dtype):
    rng = np.random.default_rng(12)
    est = CameraMotionEstimator(CameraMotionConfig(method=method))
    for _ in range(3):
        img = (rng.random(shape) * 1000).astype(dtype)
        if dtype == np.float32:
            img.flat[0] = np.nan
        m = est.estimate(img, [(0, 0, 2, 2), (float("nan"), 0, 1, 1)])
        assert m.matrix.shape == (2, 3) and np.all(np.isfinite(m.matrix))
    assert sum(est.counts.values()) == 3
