"""The generator's motion variation (PersonSpec ``motion_*``; crowd_scene / far_view_scene
``motion``): off, every scene walks exactly as before it existed; on, heading and speed
vary around the waypoint course with the configured statistics, reproducibly by seed."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import diagnose_motion as dm  # noqa: E402
from mk_tracker.synthetic.people import ou_offsets, simulate_paths  # noqa: E402
from mk_tracker.synthetic.presets import crowd_scene, far_view_scene  # noqa: E402
from mk_tracker.synthetic.scene_config import PersonSpec, SceneError  # noqa: E402

MATCHED = {"heading_std": 0.1, "speed_std": 0.1, "time_constant": 2.0}

# Foot points of the bench's scenes before the motion variation existed (commit 5cb20d6):
# sum over all frames/people/axes and the last frame's first person.
BEFORE = {
    "crowd": (2839485.671782247, (223.1316414510122, 333.73807583302755)),
    "far": (978987.7622047572, (-1080.457506602962, 246.2620951080333)),
    "far_stop": (924824.1752537371, (-250.4419515361268, 129.11198083458746)),
}


def _scenes(motion=None):
    return {"crowd": crowd_scene(15, seed=1, frames=300, motion=motion),
            "far": far_view_scene(seed=1, motion=motion),
            "far_stop": far_view_scene(seed=3, stop_fraction=0.5, motion=motion)}


def test_off_by_default_the_paths_are_those_before_the_variation_existed():
    for name, scene in _scenes().items():
        paths = scene._paths
        total, last = BEFORE[name]
        assert float(paths.sum()) == pytest.approx(total, rel=1e-12, abs=1e-9), name
        assert paths[-1, 0].tolist() == pytest.approx(list(last), rel=1e-12, abs=1e-9), name


def test_zero_stds_are_the_same_as_no_variation():
    zero = {"heading_std": 0.0, "speed_std": 0.0, "time_constant": 3.0}
    for (name, a), b in zip(_scenes().items(), _scenes(zero).values()):
        assert np.array_equal(a._paths, b._paths), name


def test_ou_offsets_have_the_configured_std_and_correlation_time():
    rng = np.random.default_rng(5)
    fps, tau = 25.0, 2.0
    x = ou_offsets(rng, 200_000, fps, tau, (0.1, 0.3))
    assert x.std(axis=0) == pytest.approx([0.1, 0.3], rel=0.05)
    lag = int(tau * fps)   # one time constant apart: correlation exp(-1)
    for j in range(2):
        r = np.corrcoef(x[:-lag, j], x[lag:, j])[0, 1]
        assert r == pytest.approx(math.exp(-1.0), abs=0.04)
    assert abs(np.corrcoef(x[:, 0], x[:, 1])[0, 1]) < 0.03   # independent processes


def test_variation_is_reproducible_by_seed_and_changes_with_it():
    p = PersonSpec(waypoints=((0.0, 100.0), (600.0, 100.0)), speed=3.0,
                   motion_heading_std=0.2, motion_speed_std=0.2, motion_time_constant=1.0)
    a = simulate_paths([p], 150, math.radians(8.0), fps=25.0, seed=4)
    b = simulate_paths([p], 150, math.radians(8.0), fps=25.0, seed=4)
    c = simulate_paths([p], 150, math.radians(8.0), fps=25.0, seed=5)
    assert np.array_equal(a, b)
    assert np.abs(a - c).max() > 1.0
    straight = simulate_paths([PersonSpec(waypoints=p.waypoints, speed=3.0)], 150,
                              math.radians(8.0))
    assert np.abs(a[:, 0, 1] - 100.0).max() > 1.0            # leaves the straight line
    assert np.abs(straight[:, 0, 1] - 100.0).max() == 0.0


def test_varied_people_keep_their_course_and_stop_where_they_stop():
    still = _scenes()["far_stop"]
    varied = far_view_scene(seed=3, stop_fraction=0.5, motion=MATCHED)
    stoppers = [k for k, p in enumerate(still.config.people) if p.after_last == "stop"]
    assert stoppers
    for k in stoppers:   # the walk ends on the final waypoint, standing still
        end = np.asarray(varied.config.people[k].waypoints[-1])
        assert np.hypot(*(varied._paths[-1, k] - end)) < 1e-6
        assert np.array_equal(varied._paths[-1, k], varied._paths[-5, k])
    # crowd: the same waypoints, and the people stay near their straight-walk paths
    a, b = crowd_scene(15, seed=1, frames=300), crowd_scene(15, seed=1, frames=300,
                                                             motion=MATCHED)
    assert [p.waypoints for p in a.config.people] == [p.waypoints for p in b.config.people]
    floor = (b._paths[..., 1] > 0.3 * 480) & (b._paths[..., 0] > 0) & (b._paths[..., 0] < 640)
    assert floor.mean() > 0.97


@pytest.mark.parametrize("make", [lambda m: far_view_scene(seed=1, motion=m),
                                  lambda m: crowd_scene(15, seed=1, frames=300, motion=m)])
def test_matched_motion_drifts_like_the_real_clips(make):
    """The constant-velocity drift after 0.5 s (velocity over 0.5 s), in box heights, of
    the TUD clips' ground truth (diagnose_motion.py --window 0.5): median 0.009
    (Stadtmitte) and 0.050 (Campus).  The straight generator's medians lie below that
    range (no drift between waypoint turns); the matched one's inside it."""
    def median_drift(motion):
        tracks, fps = dm.generated_tracks(make(motion))
        return float(np.median(dm.motion_statistics(tracks, fps, window=0.5)["drift"][0.5]))

    assert median_drift(None) < 0.009
    assert 0.009 <= median_drift(MATCHED) <= 0.050


def test_bad_motion_argument_is_a_clear_error():
    with pytest.raises(SceneError, match="motion"):
        crowd_scene(3, seed=0, frames=10, motion={"heading": 0.1})
    with pytest.raises(SceneError, match="motion"):
        far_view_scene(seed=0, frames=10, motion=[0.1, 0.1, 1.0])
