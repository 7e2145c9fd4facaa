"""Hypothesis profiles of the property tests (test_property_*.py).

``ci`` (the default) is derandomized: the same examples every run, so a failure in CI is
reproducible on any machine, and deadlines are off (the 2-core CI machine is noisy).
``dev`` explores new random examples: ``MK_TRACKER_HYPOTHESIS_PROFILE=dev pytest ...``.
Each test still bounds its own ``max_examples`` so the suite stays fast.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", derandomize=False, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("MK_TRACKER_HYPOTHESIS_PROFILE", "ci"))
