"""Thermal detection of moving warm people: Schizas, Maroulas & Ren 2018, and its baseline.

The paper's method finds the pixels that *changed* over a window of F thermal frames: the
kernel covariance of every pixel pair is near zero unless both change, and a sparse
factor of that matrix is non-zero exactly on the moving objects.

* :mod:`~mk_tracker.detection.thermal_detector` -- Algorithm 2 (Sec. 5.2): full-frame
  start-up and reconfiguration passes every T_c frames, tracking passes in windows around
  each object's Kalman prediction (5.2), one Kalman filter per object (Secs. 2 and 4,
  (2.1)-(2.3), (4.1)-(4.5), :mod:`mk_tracker.kalman`); what we add where the paper is
  silent is listed there, each with its switch.
* :mod:`~mk_tracker.detection.thermal_detector_config` -- its parameters (``detector.*``),
  each with the paper's symbol where there is one, a description and a range.
* :mod:`~mk_tracker.detection.thermal_image` -- frames to the unit intensity scale the
  kernel (3.6) assumes (sigma^2 = 0.01, Sec. 6); missing pixels (the case of Sec. 8) hold
  their last value.
* :mod:`~mk_tracker.detection.block_support` -- divide and conquer over rho x rho blocks
  (Sec. 5.1), the exact skip of blocks whose factor is zero, and the support of the
  stacked factors (5.1).
* :mod:`~mk_tracker.detection.kernel_covariance` -- the kernel covariance (3.1)-(3.5) with
  the Gaussian RBF kernel (3.6) (Sec. 3.1).
* :mod:`~mk_tracker.detection.sparse_factorization` -- the sparse factorization (3.7) by
  coordinate descent with exact cubic-root updates (3.8)-(3.11), Algorithm 1 (Sec. 3.2;
  supplementary Secs. 10-11).
* :mod:`~mk_tracker.detection.pixel_clustering` -- K-means of the support pixels (3.12)
  with the merge rule (3.13) (Sec. 3.3), and the optional valley split (ours).
* :mod:`~mk_tracker.detection.footprint` -- which support pixels each object owns in a
  tracking pass, and its footprint in the newest frame (ours, built on (3.6)).
* :mod:`~mk_tracker.detection.threshold_detector` -- the pixel-threshold baseline the paper
  compares against (Sec. 7, Table 1).

Open :mod:`~mk_tracker.detection.thermal_detector` first.
"""
