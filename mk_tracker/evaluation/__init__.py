"""Scoring tracking results against ground truth, and plotting the errors.

* :mod:`~mk_tracker.evaluation.metrics` -- multi-object CLEAR-MOT (MOTA, MOTP, ID switches
  ...) and identity metrics (IDF1) with ``motmetrics`` at IoU >= 0.5; single target: the
  centre location error per frame, precision at 20 px and the success AUC.
* :mod:`~mk_tracker.evaluation.eval_command` -- ``mk_tracker eval`` over MOTChallenge /
  OTB result files.
* :mod:`~mk_tracker.evaluation.error_plots` -- per-frame error plots (matplotlib, no
  display).
* :mod:`~mk_tracker.evaluation.annotation_occlusion` -- how occluded the annotated people
  of a ground truth are, from its boxes alone (which people a ground truth counts).

From the papers: the centre error is the measure of Chu et al. 2013 (Sec. IV-B, Fig. 6
and Table I: pixel distance between the result's and the ground truth's centroid); the
thermal benchmark's detection counts and centroid RMSE follow Schizas et al. 2018 (Secs. 6
and 7, Table 1) and live in ``benchmarks/``, not here.  Open
:mod:`~mk_tracker.evaluation.metrics` first.
"""
