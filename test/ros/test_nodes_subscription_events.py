"""The matched-event log lines of the nodes' subscriptions (mk_tracker.ros.subscription_events);
the DDS side (a real tracker_node logging its match with a real detector) is exercised by
test_faults_nodes, which waits for these lines."""

from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy")

from mk_tracker.ros.subscription_events import log_matches, matched_text  # noqa: E402


def test_text_says_how_many_publishers_and_what_changed():
    assert matched_text("/thermal/detections", 1, 1) == \
        "/thermal/detections: 1 publisher matched (gained 1)"
    assert matched_text("/image_raw", 2, 1) == "/image_raw: 2 publishers matched (gained 1)"
    assert matched_text("/image_raw", 1, -1) == "/image_raw: 1 publisher matched (lost 1)"
    assert matched_text("/image_raw", 0, -2) == "/image_raw: no publisher matched any more"


def test_callback_logs_changes_only():
    lines: list[str] = []
    callbacks = log_matches(lines.append, "/tracks_in")
    on_matched = callbacks.matched
    on_matched(SimpleNamespace(current_count=1, current_count_change=1, total_count=1))
    on_matched(SimpleNamespace(current_count=1, current_count_change=0, total_count=1))
    on_matched(SimpleNamespace(current_count=0, current_count_change=-1, total_count=1))
    assert lines == ["/tracks_in: 1 publisher matched (gained 1)",
                     "/tracks_in: no publisher matched any more"]
    assert callbacks.use_default_callbacks     # rclpy's incompatible-QoS warning stays on
