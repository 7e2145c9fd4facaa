"""Interface definitions shipped as package data.

The ``vision_msgs`` folder holds the message definitions of ROS 2 Jazzy's
vision_msgs 4.1 (field names, types and order identical to the upstream
package, so the RIHS01 type hashes agree).  They are the single source for the
pip build in ``interfaces/vision_msgs`` and for rosbags type registration.
"""
