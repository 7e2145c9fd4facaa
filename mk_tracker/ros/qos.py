"""QoS profiles of the mk_tracker nodes.

* Image subscriptions start from the sensor-data profile (best effort, volatile, keep last)
  with depth 1 by default: a node that cannot keep up should see the newest frame, not a
  queue of old ones.  Reliability and depth are node parameters.
* Detection subscriptions are best effort by default too, because a best-effort reader
  matches both reliable and best-effort writers ("any Detection2DArray publisher will do");
  they keep a few messages, since detections are small and buffered by the tracker.
* Publishers are reliable, keep last: a reliable writer matches readers of either kind
  (rviz, ``ros2 topic echo``, the tests), and keep-last bounds its memory.
"""

from __future__ import annotations

from dataclasses import dataclass

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy,
                       qos_profile_sensor_data)

from mk_tracker.parameters import parameter

RELIABILITY_CHOICES = ("best_effort", "reliable")

_RELIABILITY = {"best_effort": ReliabilityPolicy.BEST_EFFORT,
                "reliable": ReliabilityPolicy.RELIABLE}


@dataclass(frozen=True)
class SubscriptionQosConfig:
    """Reliability and queue depth of one subscription (start-up only)."""

    reliability: str = parameter("best_effort", "Subscription reliability",
                                 choices=RELIABILITY_CHOICES, read_only=True)
    depth: int = parameter(1, "Subscription queue depth (keep last N)", minimum=1,
                           maximum=1000, read_only=True)


def subscription_qos(config: SubscriptionQosConfig) -> QoSProfile:
    """Sensor-data style profile (volatile, keep last) with the configured reliability/depth."""
    if config.reliability not in _RELIABILITY:
        raise ValueError(f"reliability must be one of {RELIABILITY_CHOICES}, "
                         f"got {config.reliability!r}")
    if int(config.depth) < 1:
        raise ValueError(f"QoS depth must be >= 1, got {config.depth}")
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(config.depth),
                      reliability=_RELIABILITY[config.reliability],
                      durability=DurabilityPolicy.VOLATILE,
                      deadline=qos_profile_sensor_data.deadline,
                      lifespan=qos_profile_sensor_data.lifespan,
                      liveliness=qos_profile_sensor_data.liveliness,
                      liveliness_lease_duration=qos_profile_sensor_data.liveliness_lease_duration)


def image_subscription_qos(reliability: str = "best_effort", depth: int = 1) -> QoSProfile:
    """QoS for an image subscription: sensor data, depth 1 unless told otherwise."""
    return subscription_qos(SubscriptionQosConfig(reliability=reliability, depth=depth))


def publisher_qos(depth: int = 10) -> QoSProfile:
    """Reliable keep-last publisher profile: matches best-effort and reliable readers."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(depth),
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
