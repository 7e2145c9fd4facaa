"""ROS messages <-> plain data, without rclpy: images, detections, and one set of builders
for live nodes and for bags.

* :mod:`~mk_tracker.messages.detection_messages` -- ``vision_msgs/Detection2DArray`` <-> a
  list of :class:`~mk_tracker.messages.detection_messages.Detection`; the conventions every
  topic of the project follows (box centre in the message, top-left corner in the
  libraries, ``id`` = track id, one hypothesis with class id and score).
* :mod:`~mk_tracker.messages.image_conversion` -- ``sensor_msgs/Image`` <-> numpy without
  cv_bridge (``step``, endianness, mono8/mono16/16UC1/32FC1 and rgb8/bgr8/rgba8/bgra8).
* :mod:`~mk_tracker.messages.message_types` -- the message classes of the rclpy world (the
  nodes) and of a rosbags typestore (the offline tools) behind one namespace; the ROS
  ``*.msg`` packages are imported lazily, only when the nodes ask for them.
* ``definitions/vision_msgs/*.msg`` -- vision_msgs 4.1 as package data: built into a wheel
  by ``scripts/setup_env.sh`` and registered in rosbags typestores.

No paper equations live here: this is the boundary between ROS and the algorithms of
Schizas et al. 2018 and Chu et al. 2013.  Open :mod:`~mk_tracker.messages.detection_messages`
first.
"""
