"""HOTA of the benchmarks: :func:`mk_tracker.evaluation.hota.hota` (the package's own
implementation; it agrees with TrackEval 1.3.0, the reference implementation, to 6 decimals
on TUD-Campus and TUD-Stadtmitte: ``benchmarks/hota_check.py`` where ``trackeval`` is
installed)."""

from __future__ import annotations

from mk_tracker.evaluation.hota import hota as _hota


def hota(gt_rows, hyp_rows, n_frames: int | None = None) -> float:
    """HOTA averaged over the IoU thresholds 0.05..0.95 (``n_frames``: unused, frames
    without boxes do not change it)."""
    return _hota(gt_rows, hyp_rows)["hota"]
