"""mk_tracker: thermal detection and multiple-kernel tracking of people through occlusion.

The modules of this package are pure Python (numpy, OpenCV, scipy, rosbags); none of them
imports rclpy.  The ROS 2 nodes live in :mod:`mk_tracker.ros`, and are thin adapters around
these libraries.
"""

__version__ = "0.1.0"
