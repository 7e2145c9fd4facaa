"""mk_tracker.node_health: rolling rates, drops and latency, and the OK/WARN/ERROR rules of
/diagnostics.  A fake clock drives every test; expected figures are worked out by hand in
the comments."""

from __future__ import annotations

import pytest

from mk_tracker.node_health import (ERROR, OK, WARN, DiagnosticsConfig, FrameCounts,
                                    HealthWindow, diagnose)
from mk_tracker.parameters import ParameterError, parameter_specs, updated


class FakeClock:
    def __init__(self, t: float = 0.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def test_rates_cover_the_window_once_the_node_has_run_that_long():
    clock = FakeClock(0.0)
    health = HealthWindow(5.0, clock)
    # 30 images/s arrive, 25/s are published, 5/s dropped
    for t in range(1, 7):
        clock.t = float(t)
        health.sample(FrameCounts(received=30 * t, processed=25 * t, dropped=5 * t))
    s = health.summary()
    # at t = 6 the base is the newest sample at least 5 s old: t = 1
    assert s.span == 5.0
    assert s.window == FrameCounts(received=150, processed=125, dropped=25, skipped=0)
    assert s.total == FrameCounts(received=180, processed=150, dropped=30, skipped=0)
    assert s.input_rate == 30.0
    assert s.processed_rate == 25.0


def test_rates_before_a_full_window_cover_the_time_since_start():
    clock = FakeClock(10.0)
    health = HealthWindow(5.0, clock)
    clock.t = 12.0
    health.sample(FrameCounts(received=20, processed=20))
    s = health.summary()
    assert s.span == 2.0
    assert s.input_rate == 10.0              # 20 images in 2 s
    assert s.processed_rate == 10.0


def test_no_sample_yet_gives_zero_rates_not_a_division_by_zero():
    health = HealthWindow(5.0, FakeClock(3.0))
    s = health.summary()
    assert (s.span, s.input_rate, s.processed_rate) == (0.0, 0.0, 0.0)
    assert s.latency_median is None and s.latency_max is None


def test_latency_median_and_max_over_the_window_only():
    clock = FakeClock(0.0)
    health = HealthWindow(2.0, clock)
    clock.t = 0.5
    health.latency(5.0)                   # old: leaves with the base sample of t = 0
    for t, counts in ((1.0, 1), (2.0, 1), (3.0, 1)):
        clock.t = t
        health.sample(FrameCounts(received=counts, processed=counts))
    clock.t = 3.2
    for value in (0.010, 0.030, 0.020, 0.900):
        health.latency(value)
    s = health.summary()
    # base = t 1 (newest sample at least 2 s before 3.2); the 5.0 s latency of t 0.5 is out
    assert s.latency_median == pytest.approx(0.025)   # (0.020 + 0.030) / 2
    assert s.latency_max == pytest.approx(0.900)


def test_ok_with_rates_and_every_key():
    clock = FakeClock(0.0)
    health = HealthWindow(4.0, clock)
    clock.t = 4.0
    health.sample(FrameCounts(received=40, processed=39, dropped=1, skipped=0))
    health.latency(0.012)
    health.latency(0.018)
    level, message, values = diagnose(health.summary(), DiagnosticsConfig(),
                                      {"detections": 7})
    assert level == OK
    assert message == "9.8 Hz processed"            # 39 / 4 s, rounded
    v = dict(values)
    assert v["input rate (Hz)"] == "10.00"          # 40 / 4 s
    assert v["processed rate (Hz)"] == "9.75"       # 39 / 4 s
    assert v["dropped in window"] == "1"            # 1/40 = 2.5 % < 10 %: still OK
    assert v["latency median (ms)"] == "15.0"
    assert v["latency max (ms)"] == "18.0"
    assert v["frames processed"] == "39"
    assert v["detections"] == "7"                   # the node's extra values come last
    assert values[-1] == ("detections", "7")


def test_dropping_more_than_the_fraction_warns_and_exactly_the_fraction_does_not():
    clock = FakeClock(0.0)
    health = HealthWindow(5.0, clock)
    clock.t = 5.0
    health.sample(FrameCounts(received=100, processed=90, dropped=6, skipped=4))
    config = DiagnosticsConfig(warn_drop_fraction=0.1)
    level, message, _ = diagnose(health.summary(), config)
    assert level == OK                               # 10 of 100 lost = 0.1, not above
    config = DiagnosticsConfig(warn_drop_fraction=0.09)
    level, message, _ = diagnose(health.summary(), config)
    assert level == WARN
    assert message == "10 of 100 images lost in 5.0 s (6 dropped, 4 skipped)"


def test_median_latency_above_the_limit_warns():
    clock = FakeClock(0.0)
    health = HealthWindow(5.0, clock)
    clock.t = 1.0
    health.sample(FrameCounts(received=3, processed=3))
    for value in (0.2, 0.7, 0.8):
        health.latency(value)
    level, message, _ = diagnose(health.summary(), DiagnosticsConfig(warn_latency=0.5))
    assert level == WARN
    assert message == "median latency 700.0 ms above 500.0 ms"
    level, _, _ = diagnose(health.summary(), DiagnosticsConfig(warn_latency=0.7))
    assert level == OK                               # median 0.7 is not above 0.7


def test_no_input_for_n_periods_is_an_error_before_and_after_the_first_image():
    clock = FakeClock(100.0)
    health = HealthWindow(5.0, clock)
    config = DiagnosticsConfig(period=1.0, error_no_input_periods=3)
    clock.t = 102.5
    health.sample(FrameCounts())
    assert diagnose(health.summary(), config)[0] == OK          # 2.5 s < 3 periods
    clock.t = 103.0
    health.sample(FrameCounts())
    level, message, _ = diagnose(health.summary(), config)
    assert level == ERROR
    assert message == "no image for 3.0 s (none since start)"
    clock.t = 104.0                                  # an image came since 103
    health.sample(FrameCounts(received=1, processed=1))
    assert diagnose(health.summary(), config)[0] == OK
    clock.t = 106.9
    health.sample(FrameCounts(received=1, processed=1))
    assert diagnose(health.summary(), config)[0] == OK           # 2.9 s since 104
    clock.t = 107.0
    health.sample(FrameCounts(received=1, processed=1))
    level, message, values = diagnose(health.summary(), config)
    assert level == ERROR
    assert message == "no image for 3.0 s"
    assert dict(values)["seconds since last image"] == "3.00"


def test_an_error_keeps_the_warnings_in_its_message():
    clock = FakeClock(0.0)
    health = HealthWindow(10.0, clock)
    clock.t = 1.0
    health.sample(FrameCounts(received=10, processed=5, dropped=5))
    clock.t = 4.0
    health.sample(FrameCounts(received=10, processed=5, dropped=5))
    level, message, _ = diagnose(health.summary(), DiagnosticsConfig(
        period=1.0, error_no_input_periods=3))
    assert level == ERROR
    assert message == "no image for 3.0 s; 5 of 10 images lost in 4.0 s (5 dropped, 0 skipped)"


def test_a_shorter_window_set_at_run_time_drops_old_samples():
    clock = FakeClock(0.0)
    health = HealthWindow(10.0, clock)
    for t in range(1, 11):
        clock.t = float(t)
        health.sample(FrameCounts(received=t * t, processed=t * t))
    assert health.summary().span == 10.0
    health.window = 2.0
    s = health.summary()
    assert s.span == 2.0                             # base t = 8: 100 - 64 images
    assert s.window.received == 36
    assert s.input_rate == 18.0


def test_config_ranges_and_a_window_of_zero_are_refused():
    specs = {s.name: s for s in parameter_specs(DiagnosticsConfig)}
    assert set(specs) == {"period", "window", "warn_drop_fraction", "warn_latency",
                          "error_no_input_periods"}
    assert specs["period"].read_only and specs["period"].minimum == 0.0
    assert specs["warn_drop_fraction"].maximum == 1.0
    assert all(spec.description for spec in specs.values())
    with pytest.raises(ParameterError, match="window"):
        updated(DiagnosticsConfig(), {"window": 0.0})
    with pytest.raises(ParameterError, match="warn_drop_fraction"):
        updated(DiagnosticsConfig(), {"warn_drop_fraction": 1.5})
    with pytest.raises(ValueError):
        HealthWindow(0.0)
