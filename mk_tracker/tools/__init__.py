"""The ``mk_tracker`` command and the whole-system tools (may use ROS, like :mod:`mk_tracker.ros`).

* :mod:`~mk_tracker.tools.cli` -- one entry point, one sub-command per module:
  ``generate`` (:mod:`mk_tracker.synthetic.scene_bag`), ``import``
  (:mod:`mk_tracker.bags.dataset_import`), ``process``, ``eval``
  (:mod:`mk_tracker.evaluation.eval_command`) and ``demo``.
* :mod:`~mk_tracker.tools.pipeline` -- ``mk_tracker process``: detection and tracking over a
  bag, offline, making every per-frame decision through :mod:`mk_tracker.frame_processing`
  as the nodes do; writes the tracks bag, a MOT file, an annotated video and plots.
  ``--init-from-gt`` runs the single-target protocol of Chu et al. 2013 (Sec. IV-B: one
  person started from its first ground-truth box).
* :mod:`~mk_tracker.tools.pipeline_config` -- the nodes' parameter files read as the
  pipeline's configuration, without rclpy.
* :mod:`~mk_tracker.tools.pipeline_outputs` -- what a run leaves: MOT file, scores (the
  centre error and overlap of Chu et al. Table I for a single target), plots, summary.
  Parameter files: ``pipeline_config``; scores and files after the run: ``pipeline_outputs``.
* :mod:`~mk_tracker.tools.demo` -- ``mk_tracker demo`` / ``make demo``: a synthetic scene
  played through both nodes over DDS (via :mod:`mk_tracker.ros.launcher`), then scored.

The algorithms (Schizas et al. 2018 Algorithm 2; Chu et al. 2013 Sec. IV-D) are those of
:mod:`mk_tracker.detection` and :mod:`mk_tracker.tracking`; nothing is re-implemented here.
Open :mod:`~mk_tracker.tools.pipeline` first.
"""
