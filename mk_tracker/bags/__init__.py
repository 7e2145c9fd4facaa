"""rosbag2 bags and datasets without ROS: reading, writing, playback timing, imports.

* :mod:`~mk_tracker.bags.bag_io` -- read and write sqlite3 and mcap bags with ``rosbags``
  (split bags, bags of real ``ros2 bag record``), vision_msgs registered in the typestore.
  Split out: ``bag_writer``, ``bag_storage`` (one storage file), ``bag_typestore``, ``bag_errors``.
* :mod:`~mk_tracker.bags.playback` -- when each recorded message is due, on which topic,
  with which QoS and ``/clock``: the pure core of :mod:`mk_tracker.ros.bag_player`.
* :mod:`~mk_tracker.bags.datasets` -- MOTChallenge and OTB sequence folders (images, ground
  truth, public detections).
* :mod:`~mk_tracker.bags.dataset_import` -- ``mk_tracker import``: such a folder as a bag.

No paper equations live here.  The datasets serve the evaluation: TUD-Campus (MOTChallenge)
for multi-object tracking, and single persons of it and OTB Crossing for the single-target
centre error that Chu et al. 2013 report (Sec. IV-B, Table I).  Open
:mod:`~mk_tracker.bags.bag_io` first.
"""
