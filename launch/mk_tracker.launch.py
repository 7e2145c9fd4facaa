"""Launch both mk_tracker nodes on a real ROS 2 Jazzy install (``ros2 launch``).

    ros2 launch mk_tracker mk_tracker.launch.py
    ros2 launch mk_tracker mk_tracker.launch.py bag:=out/scene rate:=2.0 record:=out/run1 \\
        image_topic:=/camera/image_raw thermal_image_topic:=/flir/image_raw
    ros2 launch mk_tracker mk_tracker.launch.py namespace:=cam1   # one launch per camera pair
    ros2 launch mk_tracker mk_tracker.launch.py thermal_only:=true  # no RGB camera
    ros2 launch mk_tracker mk_tracker.launch.py public_detections:=true \
        detections_topic:=/detector/detections      # another detector's boxes, scored in [0, 1]
    ros2 launch mk_tracker mk_tracker.launch.py background_detections:=true \
        detector_params:=rgb_only.yaml thermal_image_topic:=/image_raw   # RGB only

* ``detector_node`` reads thermal images and publishes ``vision_msgs/Detection2DArray``;
  ``tracker_node`` reads RGB images plus those detections and publishes the tracks.
* Each node loads its parameters file (``detector_params`` / ``tracker_params``, by default
  the files installed in ``share/mk_tracker/config``; their sections are keyed
  ``/**/detector_node`` and ``/**/tracker_node``, so they apply in any namespace, and one file
  holding both sections can be given to both).
* ``namespace:=NS`` runs both nodes in ``/NS``; the topic arguments are relative by default,
  so they resolve inside it (``/NS/image_raw`` ...) and several pairs run side by side.
* ``thermal_only:=true`` (a thermal camera and no RGB camera): the tracker reads the
  thermal image too, and follows the people found in it there (issue #19).
* ``public_detections:=true`` (the tracker follows another detector's boxes, scored in
  [0, 1]): ``config/tracker_public_detections.yaml`` is loaded after ``tracker_params``,
  the leave-one-sequence-out protocol's values for such detections (issue #16; what
  ``mk_tracker process`` applies by itself to such a detection topic).
* ``background_detections:=true`` (the detector runs ``method: background``, background
  subtraction on a static RGB camera, given in ``detector_params``, its input remapped to
  the RGB topic): ``config/tracker_background_detections.yaml`` is loaded after
  ``tracker_params`` (and after the public overlay), the leave-one-sequence-out protocol's
  values for that detector's boxes (issue #13; what ``mk_tracker process`` applies by itself
  to ``--detections background``).
* Topics are remapped from the nodes' names (``thermal/image_raw``, ``image_raw``,
  ``thermal/detections``, ``tracks``; they are not parameters) to the launch arguments.
* With ``bag:=PATH`` the bag is played with ``ros2 bag play --clock`` (add
  ``use_sim_time:=true`` to run the nodes on the bag's time), as recorded (topic names
  unchanged: with a namespace, pass absolute topic arguments that name the bag's topics, or
  play a bag recorded under the namespace).  The player starts only once both nodes have
  logged their ready line (:data:`READY_LINES`: they log it after warming up their numba
  kernels, about 1 s with a warm cache and 8-35 s on a first run, and subscribing), plus
  ``play_delay`` seconds for discovery, so the first frames of the bag are not lost.
  With ``record:=PATH`` the detections and tracks are recorded with ``ros2 bag record``.
* Fast DDS shared memory: every process gets ``config/fastdds_shm.xml`` as
  ``FASTRTPS_DEFAULT_PROFILES_FILE`` and ``FASTDDS_DEFAULT_PROFILES_FILE`` (640x480 frames
  between processes are mostly lost with the default transports, docs/fastdds_transport.md),
  unless either variable is already set or ``fastdds_shm:=false``.

Where only the pip wheels of rclpy are installed there is no ``ros2 launch``: ``mk_launch``
(mk_tracker/ros/launcher.py) starts the same processes, in the same order, with the
package's own bag player and recorder.
"""

from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, ExecuteProcess, GroupAction,
                            RegisterEventHandler, SetEnvironmentVariable)
from launch.conditions import IfCondition
from launch.event_handlers import OnProcessIO
from launch.substitutions import (EnvironmentVariable, LaunchConfiguration,
                                  PathJoinSubstitution, PythonExpression)
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

PACKAGE = "mk_tracker"

# node topic (relative, as the nodes name them: IMAGE_TOPIC ... in mk_tracker/ros/*_node.py;
# they are not parameters) -> launch argument it is remapped to
DETECTOR_REMAPS = {"thermal/image_raw": "thermal_image_topic",
                   "thermal/detections": "detections_topic"}
TRACKER_REMAPS = {"image_raw": "image_topic", "thermal/detections": "detections_topic",
                  "tracks": "tracks_topic"}
FASTDDS_PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
TOPIC_DEFAULTS = {"thermal_image_topic": "thermal/image_raw", "image_topic": "image_raw",
                  "detections_topic": "thermal/detections", "tracks_topic": "tracks"}
# what each node logs once it has warmed up and subscribed (as mk_launch waits for them)
READY_LINES = {"detector_node": "detecting people (", "tracker_node": " with detections from "}


class StartWhenReady:
    """Start ``actions`` once every node in ``READY_LINES`` has logged its ready line.

    ``handler(node_action, name)`` is the event handler to register for one node: it reads
    the node's stdout and stderr (ROS logs go to stderr) and, on the output that completes
    the set, returns ``actions`` for launch to execute -- once.
    """

    def __init__(self, actions):
        self._actions = list(actions)
        self._seen = {name: "" for name in READY_LINES}
        self._started = False

    def ready(self) -> bool:
        return all(READY_LINES[name] in text for name, text in self._seen.items())

    def on_output(self, name, text):
        """Record ``text`` (bytes or str) output by node ``name``; the actions to start."""
        if self._started or READY_LINES[name] in self._seen[name]:
            return None
        if isinstance(text, bytes):
            text = text.decode(errors="replace")
        # keep a tail long enough for a ready line split over two reads
        self._seen[name] = (self._seen[name] + text)[-4096:]
        if not self.ready():
            return None
        self._started = True
        return self._actions

    def handler(self, node_action, name):
        def on_io(event):
            return self.on_output(name, event.text)
        return RegisterEventHandler(OnProcessIO(target_action=node_action, on_stdout=on_io,
                                                on_stderr=on_io))


def _in_namespace(topic_argument):
    """The recorder's name for a topic argument: a relative one inside ``namespace``."""
    return PythonExpression([
        "(lambda ns, t: t if t.startswith('/') else '/' + '/'.join(p for p in "
        "ns.split('/') + t.split('/') if p))('", LaunchConfiguration("namespace"), "', '",
        LaunchConfiguration(topic_argument), "')"])


def _tracker_topic(argument):
    """The tracker's topic for a launch argument; with ``thermal_only:=true`` its RGB image
    (``image_topic``) is the thermal camera (``thermal_image_topic``), issue #19."""
    if argument != "image_topic":
        return LaunchConfiguration(argument)
    return PythonExpression([
        "'", LaunchConfiguration("thermal_image_topic"), "' if '",
        LaunchConfiguration("thermal_only"), "'.lower() == 'true' else '",
        LaunchConfiguration("image_topic"), "'"])


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
        DeclareLaunchArgument("namespace", default_value="",
                              description="namespace of both nodes (one per camera pair)"),
        DeclareLaunchArgument("bag", default_value="", description="bag to play (optional)"),
        DeclareLaunchArgument("play_delay", default_value="1.0",
                              description="seconds between the nodes' ready lines and the "
                              "first played message (DDS discovery of the player)"),
        DeclareLaunchArgument("rate", default_value="1.0", description="playback rate"),
        DeclareLaunchArgument("record", default_value="",
                              description="record detections and tracks into this new bag"),
        DeclareLaunchArgument("thermal_only", default_value="false",
                              description="no RGB camera: the tracker follows the people in "
                              "the thermal image (its image_raw is remapped to "
                              "thermal_image_topic)"),
        DeclareLaunchArgument("public_detections", default_value="false",
                              description="the detections come from another detector, "
                              "scored in [0, 1]: load config/tracker_public_detections.yaml "
                              "after tracker_params"),
        DeclareLaunchArgument("background_detections", default_value="false",
                              description="the detections come from the detector's "
                              "background subtraction (method: background): load "
                              "config/tracker_background_detections.yaml after "
                              "tracker_params"),
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

    namespace = LaunchConfiguration("namespace")
    detector = Node(
        package=PACKAGE, executable="detector_node", name="detector_node", output="screen",
        namespace=namespace,
        parameters=[LaunchConfiguration("detector_params"), {"use_sim_time": use_sim_time}],
        remappings=[(src, LaunchConfiguration(arg)) for src, arg in DETECTOR_REMAPS.items()])
    # the overlay when public_detections:=true, else the parameters file once more (no-op)
    tracker_overlay = PythonExpression([
        "'", PathJoinSubstitution([config_dir, "tracker_public_detections.yaml"]), "' if '",
        LaunchConfiguration("public_detections"), "'.lower() == 'true' else '",
        LaunchConfiguration("tracker_params"), "'"])
    background_overlay = PythonExpression([
        "'", PathJoinSubstitution([config_dir, "tracker_background_detections.yaml"]),
        "' if '", LaunchConfiguration("background_detections"), "'.lower() == 'true' else '",
        LaunchConfiguration("tracker_params"), "'"])
    tracker = Node(
        package=PACKAGE, executable="tracker_node", name="tracker_node", output="screen",
        namespace=namespace,
        parameters=[LaunchConfiguration("tracker_params"), tracker_overlay,
                    background_overlay, {"use_sim_time": use_sim_time}],
        remappings=[(src, _tracker_topic(arg)) for src, arg in TRACKER_REMAPS.items()])
    player = ExecuteProcess(
        cmd=["ros2", "bag", "play", LaunchConfiguration("bag"), "--rate",
             LaunchConfiguration("rate"), "--clock", "--delay",
             LaunchConfiguration("play_delay"), "--disable-keyboard-controls"],
        output="screen", condition=_not_empty("bag"))
    recorder = ExecuteProcess(
        cmd=["ros2", "bag", "record", "--output", LaunchConfiguration("record"),
             _in_namespace("detections_topic"), _in_namespace("tracks_topic")],
        output="screen", condition=_not_empty("record"))
    # the recorder and the player start when both nodes are ready (issue #14: a player
    # started with the nodes played the first seconds of the bag to nobody)
    when_ready = StartWhenReady([recorder, player])
    return LaunchDescription([*arguments, fastdds_shm,
                              when_ready.handler(detector, "detector_node"),
                              when_ready.handler(tracker, "tracker_node"),
                              detector, tracker])
