"""Seeded synthetic RGB + thermal scenes with exact ground truth, and their bags.

Every test scene of the project is rendered here, deterministically from a seed: people
with colour and temperature, pillars and walls that hide them, static warm objects, two
image planes (thermal = world plane, RGB) linked by a homography.

* :mod:`~mk_tracker.synthetic.presets` -- the named scenes (``PRESETS``,
  ``mk_tracker generate --preset``): the synthetic test of Schizas et al. 2018 (Sec. 6,
  :func:`~mk_tracker.synthetic.presets.paper_scene`), static warm objects for the
  threshold comparison of its Table 1 (Sec. 7), occlusion behind a pillar or a low wall,
  two people crossing and a person approaching the camera (the occlusion and scale-change
  cases of Chu et al. 2013, Secs. IV-B and IV-C), crowds, people entering and leaving, and
  thermal and RGB planes of different sizes.
* :mod:`~mk_tracker.synthetic.scene_config` -- what defines a scene (``SceneConfig`` and
  its specs) and what a rendered frame reports (``SceneFrame``, ``ObjectTruth``).
* :mod:`~mk_tracker.synthetic.people` -- how people move (the constant-velocity model
  (2.1)-(2.2) of Schizas et al., with bounded turns) and how they look.
* :mod:`~mk_tracker.synthetic.scene` -- ``SyntheticScene``: rendering of both planes,
  visibility and boxes of every object, thermal encodings.
* :mod:`~mk_tracker.synthetic.camera_pan` -- a panning camera over a scene: a moving crop
  window with exactly known image motion and shifted truth boxes.
* :mod:`~mk_tracker.synthetic.scene_bag` -- a scene as a rosbag2 bag (``mk_tracker
  generate``), with ground truth and the homography in ``/scene_info``.

Open :mod:`~mk_tracker.synthetic.presets` first.
"""
