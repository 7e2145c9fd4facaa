"""Annotated images and videos of what the detector and the tracker see.

* :mod:`~mk_tracker.drawing.debug_image` -- pure OpenCV drawing: a colour-mapped thermal
  frame, detection boxes with scores, track boxes with id, state and score, and each
  track's kernels as ellipses (the multiple kernels of Chu et al. 2013, Sec. III and the
  layouts of Sec. IV-A).  The nodes publish these on ``~/debug_image``.
* :mod:`~mk_tracker.drawing.video_output` -- an MP4 writer that checks it really opened.

No equations live here.  Open :mod:`~mk_tracker.drawing.debug_image` first.
"""
