"""Launch both mk_tracker nodes on a real ROS 2 Jazzy install (``ros2 launch``).

    ros2 launch mk_tracker mk_tracker.launch.py
    ros2 launch mk_tracker mk_tracker.launch.py bag:=out/scene rate:=2.0 record:=out/run1 \\
        image_topic:=/camera/image_raw thermal_image_topic:=/flir/image_raw

* ``detector_node`` reads thermal images and publishes ``vision_msgs/Detection2DArray``;
  ``tracker_node`` reads RGB images plus those detections and publishes the tracks.
* Each node loads its parameters file (``detector_params`` / ``tracker_params``, by default
  the files installed in ``share/mk_tracker/config``; ROS parameter files are keyed by node
  name, so one file holding both sections can be given to both).
* Topics are remapped from the nodes' defaults (``thermal/image_raw``, ``image_raw``,
  ``thermal/detections``, ``tracks``) to the launch arguments.
* With ``bag:=PATH`` the bag is played with ``ros2 bag play --clock`` (add
  ``use_sim_time:=true`` to run the nodes on the bag's time); with ``record:=PATH`` the detections and tracks are recorded
  with ``ros2 bag record``.
* Fast DDS shared memory: every process gets ``config/fastdds_shm.xml`` as
  ``FASTRTPS_DEFAULT_PROFILES_FILE`` and ``FASTDDS_DEFAULT_PROFILES_FILE`` (640x480 frames
  between processes are mostly lost with the default transports, docs/fastdds_transport.md),
  unless either variable is already set or ``fastdds_shm:=false``.

Where only the pip wheels of rclpy are installed there is no ``ros2 launch``: ``mk_launch``
(mk_tracker/ros/launcher.py) starts the same processes with the package's own bag player
and recorder.
"""

from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, ExecuteProcess, GroupAction,
                            SetEnvironmentVariable)
from launch.conditions import IfCondition
from launch.substitutions import (EnvironmentVariable, LaunchConfiguration,
                                  PathJoinSubstitution, PythonExpression)
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

PACKAGE = "mk_tracker"

# node default topic (relative, as declared in the nodes' configs) -> launch argument
DETECTOR_REMAPS = {"thermal/image_raw": "thermal_image_topic",
                   "thermal/detections": "detections_topic"}
TRACKER_REMAPS = {"image_raw": "image_topic", "thermal/detections": "detections_topic",
                  "tracks": "tracks_topic"}
FASTDDS_PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
TOPIC_DEFAULTS = {"thermal_image_topic": "thermal/image_raw", "image_topic": "image_raw",
                  "detections_topic": "thermal/detections", "tracks_topic": "tracks"}


def _not_empty(name):
    return IfCondition(PythonExpression(["'", LaunchConfiguration(name), "' != ''"]))


def generate_launch_description():
    config_dir = PathJoinSubstitution([FindPackageShare(PACKAGE), "config"])
    arguments = [
        DeclareLaunchArgument("detector_params",
                              default_value=PathJoinSubstitution([config_dir, "detector.yaml"]),
                              description="parameters file of detector_node"),
        DeclareLaunchArgument("tracker_params",
                              default_value=PathJoinSubstitution([config_dir, "tracker.yaml"]),
                              description="parameters file of tracker_node"),
        DeclareLaunchArgument("use_sim_time", default_value="false",
                              description="follow /clock (the bag's time)"),
        DeclareLaunchArgument("bag", default_value="", description="bag to play (optional)"),
        DeclareLaunchArgument("rate", default_value="1.0", description="playback rate"),
        DeclareLaunchArgument("record", default_value="",
                              description="record detections and tracks into this new bag"),
        DeclareLaunchArgument("fastdds_shm", default_value="true",
                              description="give every process config/fastdds_shm.xml (Fast "
                              "DDS shared memory) unless a profiles file is already set"),
    ]
    arguments += [DeclareLaunchArgument(name, default_value=default, description=f"{name}")
                  for name, default in TOPIC_DEFAULTS.items()]
    use_sim_time = LaunchConfiguration("use_sim_time")
    # one condition for both variables, evaluated before either is set; not scoped, so the
    # variables reach the processes started after the group
    shm_wanted = ["'", LaunchConfiguration("fastdds_shm"), "'.lower() == 'true'"]
    for variable in FASTDDS_PROFILE_VARIABLES:
        shm_wanted += [" and '", EnvironmentVariable(variable, default_value=""), "' == ''"]
    profile = PathJoinSubstitution([config_dir, "fastdds_shm.xml"])
    fastdds_shm = GroupAction(
        [SetEnvironmentVariable(variable, profile) for variable in FASTDDS_PROFILE_VARIABLES],
        condition=IfCondition(PythonExpression(shm_wanted)), scoped=False)

    detector = Node(
        package=PACKAGE, executable="detector_node", name="detector_node", output="screen",
        parameters=[LaunchConfiguration("detector_params"), {"use_sim_time": use_sim_time}],
        remappings=[(src, LaunchConfiguration(arg)) for src, arg in DETECTOR_REMAPS.items()])
    tracker = Node(
        package=PACKAGE, executable="tracker_node", name="tracker_node", output="screen",
        parameters=[LaunchConfiguration("tracker_params"), {"use_sim_time": use_sim_time}],
        remappings=[(src, LaunchConfiguration(arg)) for src, arg in TRACKER_REMAPS.items()])
    player = ExecuteProcess(
        cmd=["ros2", "bag", "play", LaunchConfiguration("bag"), "--rate",
             LaunchConfiguration("rate"), "--clock"],
        output="screen", condition=_not_empty("bag"))
    recorder = ExecuteProcess(
        cmd=["ros2", "bag", "record", "--output", LaunchConfiguration("record"),
             LaunchConfiguration("detections_topic"), LaunchConfiguration("tracks_topic")],
        output="screen", condition=_not_empty("record"))
    return LaunchDescription([*arguments, fastdds_shm, detector, tracker, recorder, player])
