"""ROS 2 adapters around the mk_tracker libraries.

Everything that imports rclpy lives in this sub-package.  The nodes are thin: they convert
messages, call a library, and publish.

* :mod:`mk_tracker.ros.parameter_bridge` turns the libraries' config dataclasses into
  declared ROS parameters (with descriptions and ranges) and validates run-time changes.
* :mod:`mk_tracker.ros.qos` builds the QoS profiles the nodes use.
* :mod:`mk_tracker.ros.detector_node` and :mod:`mk_tracker.ros.tracker_node` are the two
  nodes (console scripts ``detector_node`` and ``tracker_node``).
"""
