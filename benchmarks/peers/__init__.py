"""Benchmark peers of the multi-object tracker: a SORT-style tracker and a norfair adapter.

Both consume the same per-frame lists of ``(x, y, w, h, score)`` detections and return
``[(track_id, (x, y, w, h)), ...]`` per frame, so the benchmark can score them alike.
"""
