"""A fake multiple-kernel refiner for tracker tests that control appearance by hand.

A target is the label of the nearest x position in ``labels_at`` (set by the test, also
after construction); a refinement finds nothing (the undetected track coasts, and
``refined`` counts the calls); the appearance similarity is 0.9 at a box of the same label
and ``other`` at any other box.
"""

from __future__ import annotations


class LabelRefiner:
    def __init__(self, labels_at: dict | None = None, other: float = 0.05):
        self.labels_at = dict(labels_at or {})
        self.other = other
        self.refined = 0

    def _label(self, box):
        return min(self.labels_at.items(), key=lambda kv: abs(kv[0] - box[0]))[1]

    def start(self, image, box):
        return self._label(box)

    def refine(self, image, state, predicted_center=None):
        self.refined += 1
        return type("R", (), {"box": None, "similarity": 0.0, "lost": True})()

    def appearance_similarity(self, image, state, box):
        return 0.9 if self._label(box) == state else self.other
