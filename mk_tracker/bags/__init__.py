"""rosbag2 bags and datasets without ROS: reading, writing, playback timing, imports.

* :mod:`~mk_tracker.bags.bag_io` -- :func:`~mk_tracker.bags.bag_io.open_bag` /
  ``BagReader``: a bag directory (or one ``.mcap`` / ``.db3`` file) in time order over all
  split files, including bags of real ``ros2 bag record``; re-exports the names below.
* :mod:`~mk_tracker.bags.bag_storage` -- one storage file (MCAP, sqlite3), with salvage of
  damaged files.
* :mod:`~mk_tracker.bags.bag_writer` -- ``BagWriter``: new bags from message objects or
  copied CDR bytes.
* :mod:`~mk_tracker.bags.bag_typestore` -- the ROS 2 Jazzy typestore with vision_msgs
  registered, plus definitions stored in a bag.
* :mod:`~mk_tracker.bags.bag_errors` -- ``BagError`` and the ``on_error`` policy.
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
