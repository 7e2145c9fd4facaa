"""The interface package interfaces/mk_tracker_msgs as scripts/setup_env.sh builds it.

* Every message and service imports with the field list and constants written here by hand
  from the .msg/.srv files' documentation.
* RIHS01 type hashes (REP 2011): the hash read from the type support through rclpy's graph
  API equals the hash in the installed type description JSON, equals the hash recomputed
  here from that JSON's description by REP 2011's rule, and equals the hash pinned below.
  The pin is the wire contract: a subscriber built from an older definition no longer
  matches a publisher of a changed one, so a change of a definition must change the pin
  and the package version together.
* The referenced vision_msgs and std_msgs types carry the hashes of the real ROS 2 Jazzy
  packages (test_environment.py's references): the package was built against them, so it
  interoperates with apt's ros-jazzy-vision-msgs.
"""

from __future__ import annotations

import copy
import hashlib
import importlib
import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path

from test_environment import REFERENCE_HASHES, REFERENCE_HEADER_HASH, ros_graph_node  # noqa: F401

REPO = Path(__file__).resolve().parents[1]
PACKAGE_DIR = REPO / "interfaces" / "mk_tracker_msgs"

# Pinned by the first build of version 0.1.0, TrackedObject and TrackedObjectArray again by
# version 0.2.0 (TrackedObject.published added; see the module docstring).
PINNED_HASHES = {
    "msg/TrackedObject":
        "RIHS01_2f4cfa6e22ff9edec4f4fa4c3726b6654aaafb5f61b19e7b5c1c8e1a8730aef0",
    "msg/TrackedObjectArray":
        "RIHS01_af3029113ba5643a7a9acdabe5432ceef25c2492f6a5f1346c559d312323cec6",
    "srv/StartTrack":
        "RIHS01_c3657d39baf260bea8ab350ba625766f35f87649cdbfa943756469496db55871",
    "srv/StopTrack":
        "RIHS01_c003f3a3a7980133b43d9e268d4e403a8ec08046ca44d10d1781031237783568",
}

EXPECTED_FIELDS = {
    "TrackedObject": {
        "detection": "vision_msgs/Detection2D", "state": "uint8", "velocity_x": "double",
        "velocity_y": "double", "velocity_covariance": "double[4]",
        "position_covariance": "double[4]", "age": "builtin_interfaces/Duration",
        "time_since_detected": "builtin_interfaces/Duration", "hits": "uint32",
        "started_by_hand": "boolean", "published": "boolean"},
    "TrackedObjectArray": {"header": "std_msgs/Header",
                           "tracks": "sequence<mk_tracker_msgs/TrackedObject>"},
}
EXPECTED_SERVICE_FIELDS = {
    "StartTrack": ({"box": "vision_msgs/BoundingBox2D", "frame_id": "string"},
                   {"success": "boolean", "track_id": "string", "message": "string"}),
    "StopTrack": ({"track_id": "string"}, {"success": "boolean", "message": "string"}),
}


def _share() -> Path:
    module = Path(importlib.import_module("mk_tracker_msgs").__file__).resolve()
    share = module.parents[4] / "share" / "mk_tracker_msgs"
    assert share.is_dir(), f"{share} absent: mk_tracker_msgs was installed without its share"
    return share


def _rihs01(description: dict) -> str:
    """REP 2011's RIHS01: sha256 of the JSON of the type description without default
    values, separators ', ' and ': ', keys in their given order."""
    hashable = copy.deepcopy(description)
    for td in [hashable["type_description"], *hashable["referenced_type_descriptions"]]:
        for field in td["fields"]:
            del field["default_value"]
    text = json.dumps(hashable, ensure_ascii=True, allow_nan=False, indent=None,
                      separators=(", ", ": "), sort_keys=False)
    return "RIHS01_" + hashlib.sha256(text.encode("utf-8")).hexdigest()


def test_messages_have_the_documented_fields_and_constants():
    module = importlib.import_module("mk_tracker_msgs.msg")
    for name, expected in EXPECTED_FIELDS.items():
        assert getattr(module, name).get_fields_and_field_types() == expected, name
    t = module.TrackedObject
    assert (t.TENTATIVE, t.CONFIRMED, t.OCCLUDED, t.LOST) == (0, 1, 2, 3)


def test_services_have_the_documented_fields():
    module = importlib.import_module("mk_tracker_msgs.srv")
    for name, (request, response) in EXPECTED_SERVICE_FIELDS.items():
        srv = getattr(module, name)
        assert srv.Request.get_fields_and_field_types() == request, name
        assert srv.Response.get_fields_and_field_types() == response, name


def test_installed_descriptions_hash_as_rep_2011_says_and_as_pinned():
    share = _share()
    for name, pinned in PINNED_HASHES.items():
        data = json.loads((share / f"{name}.json").read_text())
        full = f"mk_tracker_msgs/{name}"
        hashes = {h["type_name"]: h["hash_string"] for h in data["type_hashes"]}
        assert data["type_description_msg"]["type_description"]["type_name"] == full
        assert _rihs01(data["type_description_msg"]) == hashes[full] == pinned, name


def test_referenced_types_are_the_real_jazzy_ones():
    share = _share()
    data = json.loads((share / "msg" / "TrackedObject.json").read_text())
    hashes = {h["type_name"]: h["hash_string"] for h in data["type_hashes"]}
    assert hashes["std_msgs/msg/Header"] == REFERENCE_HEADER_HASH
    for name in ("BoundingBox2D", "Point2D", "Pose2D", "ObjectHypothesisWithPose",
                 "ObjectHypothesis"):
        assert hashes[f"vision_msgs/msg/{name}"] == REFERENCE_HASHES[name], name


def test_runtime_hashes_equal_the_pinned_ones(ros_graph_node):  # noqa: F811
    from mk_tracker_msgs.msg import TrackedObject, TrackedObjectArray
    for msg_type, name in ((TrackedObject, "msg/TrackedObject"),
                           (TrackedObjectArray, "msg/TrackedObjectArray")):
        topic = f"/mk_msgs_probe_{msg_type.__name__.lower()}_{os.getpid()}"
        publisher = ros_graph_node.create_publisher(msg_type, topic, 1)
        try:
            infos = ros_graph_node.get_publishers_info_by_topic(topic)
            assert len(infos) == 1
            assert str(infos[0].topic_type_hash) == PINNED_HASHES[name]
        finally:
            ros_graph_node.destroy_publisher(publisher)


def test_package_xml_is_a_format_3_interface_package_and_colcon_sees_it():
    root = ET.parse(PACKAGE_DIR / "package.xml").getroot()
    assert root.get("format") == "3"
    assert root.find("name").text == "mk_tracker_msgs"
    assert root.find("export/build_type").text == "ament_cmake"
    assert root.find("member_of_group").text == "rosidl_interface_packages"
    assert {e.text for e in root.findall("depend")} == {"builtin_interfaces", "std_msgs",
                                                        "vision_msgs"}
    # unlike interfaces/vision_msgs, colcon must build this one on a ROS system
    for marker in ("COLCON_IGNORE", "AMENT_IGNORE"):
        assert not (PACKAGE_DIR / marker).exists()
    listed = ET.parse(REPO / "package.xml").getroot()
    assert "mk_tracker_msgs" in {e.text for e in listed.findall("exec_depend")}
