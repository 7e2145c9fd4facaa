"""Tracking every person in RGB through occlusion: Kalman prediction, association, and the
projected-gradient multiple-kernel mean shift of Chu, Hwang, Pai & Lan (IEEE TMM 2013).

The system is Chu et al.'s Sec. IV-D: the Kalman prediction starts the multiple-kernel
search and its result is the Kalman measurement, here combined with the thermal
detections of :mod:`mk_tracker.detection`.  The Kalman filter itself is
:mod:`mk_tracker.kalman` (Schizas et al. 2018, (2.1)-(2.3), (4.1)-(4.5)).

* :mod:`~mk_tracker.tracking.multi_object_tracker` -- one ``step`` per RGB frame: detections
  to the RGB plane and the frame time, prediction (4.2)-(4.3), association, refinement of
  tracks without a detection, Kalman update (4.4)-(4.5), lifecycle.
* :mod:`~mk_tracker.tracking.detection_input` -- a frame's detections checked, mapped into
  the RGB plane (homography) and brought to the frame time.
* :mod:`~mk_tracker.tracking.camera_motion` -- the image motion between frames (corners,
  Lucas-Kanade, RANSAC; or ECC) moving every track's Kalman state and kernels before the
  prediction, for a moving camera (BoT-SORT; off by default).
* :mod:`~mk_tracker.tracking.duplicate_tracks` -- two tracks stacked on one person, never
  detected as two, become the older one (track-level suppression of duplicates).
* :mod:`~mk_tracker.tracking.association` -- Hungarian assignment on 1 - IoU and the
  Mahalanobis distance gated by the innovation covariance (the bracket of (4.5)).
* :mod:`~mk_tracker.tracking.recovery` -- a second round for tracks whose estimate drifted
  while undetected: from their last detected box, checked by appearance (OC-SORT's
  observation-centric recovery; not in the papers).
* :mod:`~mk_tracker.tracking.multi_kernel` -- one target as N kernels (Sec. IV-A):
  min J(x) = sum_i W_i J_i(x) (3), (7) subject to C(x) = 0 (4), by Algorithm 1 (Sec.
  III-C), the adaptive weights (Sec. III-D), the scale update (9)-(11) (Sec. III-E) and the
  box from the kernels' extremes (14); its parameters (the paper's values by default) in
  :mod:`~mk_tracker.tracking.multi_kernel_config`.
* :mod:`~mk_tracker.tracking.projected_gradient` -- the constraints (12)-(13) and the step
  dx_A + dx_B of (5) / (8) (Appendix A), safe when C_x^T C_x is singular.
* :mod:`~mk_tracker.tracking.kernel_histograms` -- the appearance model: kernel-weighted
  colour histograms (Sec. III-A), the K-L cost and the mean-shift vector used as -J_x
  (Appendix C), the scale ratio of (9)-(10); the numpy reference.
* :mod:`~mk_tracker.tracking.search_region` -- the same numbers, fast: a quantised search
  region and all kernels of a target evaluated in one call (numba loops, numpy fallback).
* :mod:`~mk_tracker.tracking.kernel_layouts` -- where the kernels sit in a box (Sec. IV-A,
  Fig. 4; Sec. V-C, Fig. 14).
* :mod:`~mk_tracker.tracking.track` -- one track's state and lifecycle (tentative,
  confirmed, occluded, lost, deleted); "lost" with re-acquisition is our answer to the
  long-occlusion limitation of Sec. V-D.
* :mod:`~mk_tracker.tracking.manual_track` -- tracks started by hand (the single-target
  protocol of Sec. IV-B): their settings and the column re-centring of their search.

Open :mod:`~mk_tracker.tracking.multi_object_tracker` first.
"""
