"""Bags whose detections arrive after their image, as a running detector's do (used by the
offline and the node tests of tracker_node's ``detection_wait``)."""

from __future__ import annotations

from pathlib import Path

from mk_tracker.bags.bag_io import open_bag
from mk_tracker.bags.bag_writer import BagWriter
from mk_tracker.messages.detection_messages import Detection, make_detection_array, read_detection_array
from mk_tracker.messages.message_types import bag_message_types


def detections_bag(scene_bag: Path, dst: Path, offset_ns: int) -> None:
    """The scene bag's RGB images plus its ground truth as ``/detections`` (header stamps
    unchanged), stored ``offset_ns`` after (or before, when negative) their image in bag
    time -- how a detector's answer arrives after its frame.  Bag time starts at 1 s (room
    for the negative offset).  The first image is left out: a frame is only held for
    detections once a detector has been heard from, and a bag that starts with an image
    would make the first frame differ for that reason alone."""
    with open_bag(scene_bag) as reader, BagWriter(dst, typestore=reader.typestore) as writer:
        types = bag_message_types(reader.typestore)
        writer.add_topic("/image_raw", "sensor_msgs/msg/Image")
        writer.add_topic("/detections", "vision_msgs/msg/Detection2DArray")
        out = []
        first_image = True
        for m in reader.messages(["/image_raw", "/ground_truth"]):
            if m.topic == "/image_raw":
                if first_image:
                    first_image = False
                    continue
                out.append((m.timestamp_ns + 10**9, 1, m.topic, m.data))
                continue
            msg = reader.deserialize(m)
            dets = [Detection(d.box, 0.9) for d in read_detection_array(msg)]
            out.append((m.timestamp_ns + 10**9 + offset_ns, 0, "/detections",
                        make_detection_array(dets, msg.header, types)))
        for ns, _, topic, payload in sorted(out, key=lambda t: t[:2]):
            if isinstance(payload, (bytes, bytearray, memoryview)):
                writer.write_raw(topic, ns, payload)
            else:
                writer.write(topic, ns, payload)

