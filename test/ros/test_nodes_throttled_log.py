"""Per-kind log throttling used by the nodes for bad input."""

from mk_tracker.ros.throttled_log import ThrottledLog, message_kind


def test_numbers_do_not_make_a_new_kind_but_words_do():
    assert message_kind("data has 1000 bytes, fewer than 921600") == \
        message_kind("data has 12 bytes, fewer than 9")
    assert message_kind("time went back by 0.44 s") == message_kind("time went back by 3 s")
    assert message_kind("encoding 'yuv422'") != message_kind("zero size (0x0)")


def test_each_kind_is_logged_once_per_period_with_a_count_of_the_suppressed():
    now = [0.0]
    lines = []
    log = ThrottledLog(lines.append, period=1.0, clock=lambda: now[0])
    assert log("short data: 10 bytes")
    assert log("unsupported encoding 'yuv422'")          # another kind: not throttled
    assert not log("short data: 20 bytes")
    assert not log("short data: 30 bytes")
    now[0] = 1.5
    assert log("short data: 40 bytes")
    assert lines == ["short data: 10 bytes", "unsupported encoding 'yuv422'",
                     "short data: 40 bytes (2 similar message(s) suppressed)"]


def test_ros_loggers_of_different_severities_do_not_collide():
    # rclpy fixes the severity per call site and raises when one site logs at two
    from rclpy.logging import get_logger

    from mk_tracker.ros.throttled_log import throttled_ros_log

    logger = get_logger("throttled_log_test")
    warn = throttled_ros_log(logger, "warning")
    info = throttled_ros_log(logger, "info")
    error = throttled_ros_log(logger, "error")
    assert warn("a warning") and info("an event") and error("an error")
    assert info("another event")
