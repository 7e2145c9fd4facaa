"""ROS 2 adapters around the mk_tracker libraries.

Everything that imports rclpy lives in this sub-package (:mod:`mk_tracker.tools` may too;
no library module does: ``test/test_import_direction.py``).  The nodes are thin: they
convert messages, call a library through :mod:`mk_tracker.frame_processing`, and publish.

* :mod:`mk_tracker.ros.detector_node` and :mod:`mk_tracker.ros.tracker_node` are the two
  nodes (console scripts ``detector_node`` and ``tracker_node``): the thermal detector of
  Schizas et al. 2018 (Algorithm 2) and the multi-object tracker built on Chu et al. 2013
  (Sec. IV-D).
* :mod:`mk_tracker.ros.parameter_bridge` turns the libraries' config dataclasses into
  declared ROS parameters (with descriptions and ranges) and validates run-time changes.
* :mod:`mk_tracker.ros.qos` builds the QoS profiles the nodes use;
  :mod:`mk_tracker.ros.latest_frame` keeps only the newest frame for a worker thread;
  :mod:`mk_tracker.ros.subscription_events` logs publishers matched and lost;
  :mod:`mk_tracker.ros.throttled_log` limits repeated warnings;
  :mod:`mk_tracker.ros.node_runner` spins a node and shuts it down cleanly.
* :mod:`mk_tracker.ros.bag_player`, :mod:`mk_tracker.ros.bag_recorder` and
  :mod:`mk_tracker.ros.launcher` replace ``ros2 bag play``, ``ros2 bag record`` and
  ``ros2 launch`` for pip installs.

Open :mod:`mk_tracker.ros.tracker_node` first.
"""
