"""A ROS domain nobody else on this machine is using right now, for the DDS fault tests.

Several test sessions run on one machine at the same time, all with localhost discovery;
``nodes_harness.unique_domain`` spreads them by pid over 100 ids, so two sessions sometimes
meet in one domain and a test then receives the other session's images or tracks (e.g. a
frame of another size resets the tracker).  :func:`quiet_domain` probes candidate domains
and returns one in which no other ROS node is visible.
"""

from __future__ import annotations

import random
import time

from nodes_harness import Peer, apply_env_to_test_process

PROBE_NAME = "mk_tracker_domain_probe"


def quiet_domain(monkeypatch, attempts: int = 8, listen_s: float = 1.0) -> int:
    """A domain id in 1..101 with no visible ROS node (after ``listen_s`` of discovery);
    the last candidate if every attempt found company.  Also applies the discovery
    settings of that domain to the test process (``apply_env_to_test_process``)."""
    rng = random.Random(time.time_ns())
    domain = rng.randint(1, 101)
    for _ in range(attempts):
        apply_env_to_test_process(monkeypatch, domain)
        probe = Peer(domain, PROBE_NAME)
        try:
            probe.spin_for(listen_s)
            others = [n for n in probe.node.get_node_names() if n != PROBE_NAME]
        finally:
            probe.close()
        if not others:
            return domain
        domain = rng.randint(1, 101)
    return domain
