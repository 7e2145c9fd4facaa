"""bag_recorder over real DDS: record what bag_player plays, stop on SIGINT/SIGTERM, and
compare the recorded bag with the source bag.

Timing (issue #12): the recorder is stopped as soon as the player has had every message
acknowledged (so each is in the recorder's reader): the recorder writes what its readers
hold before it closes the bag (no fixed sleep for it to catch up); the receive-time spacing is compared with the source's within 60 ms plus the
player's own publish lateness measured in the same run (test_bag_player.player_lateness).
Waits for lines only bound things that must happen.
"""

from __future__ import annotations

import signal
import time

import pytest
import yaml

from mk_tracker.bags import bag_io
from test_bag_player import (S, Processes, fresh_domain, module_argv, play_argv,  # noqa: F401
                             player_lateness, processes, same_cdr, write_test_bag)


def wait_for_line(proc, text: str, timeout: float) -> list[str]:
    """Lines of ``proc.stdout`` up to the one containing ``text`` (fails on timeout/exit)."""
    lines: list[str] = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if text in line:
            return lines
    raise AssertionError(f"no {text!r} from the process; got {lines}")


@pytest.mark.parametrize("storage,stop_signal", [("mcap", signal.SIGINT),
                                                 ("sqlite3", signal.SIGTERM)])
def test_recording_of_a_played_bag_matches_the_source(tmp_path, processes, storage,
                                                      stop_signal):
    source = tmp_path / "source"
    written = write_test_bag(source)
    out_bag = tmp_path / "recorded"
    domain = fresh_domain()
    recorder = processes.start(module_argv("mk_tracker.ros.bag_recorder", "-o", str(out_bag),
                                           "--storage", storage, "/chatter", "/image"), domain)
    wait_for_line(recorder, "recording into", 20)
    # the player exits once the recorder acknowledged every message (up to 20 s)
    player = processes.start(play_argv(source, "--min-subscribers", "1", "--ack-timeout",
                                       "20"), domain)
    # the recorder subscribes once it sees the player's publishers in the graph
    lines = wait_for_line(recorder, "recording /", 20)
    lines += wait_for_line(recorder, "recording /", 20)
    assert any("recording /chatter [std_msgs/msg/String]" in x for x in lines)
    assert any("recording /image [sensor_msgs/msg/Image]" in x for x in lines)
    played, err = player.communicate(timeout=60)
    assert player.returncode == 0, err
    lateness = player_lateness(played)
    # acknowledged = in the recorder's reader; stopped at once, it must still write them all
    recorder.send_signal(stop_signal)
    out, err = recorder.communicate(timeout=20)
    assert recorder.returncode == 0, err
    assert "recorded 15 messages" in out
    assert "Traceback" not in err

    # finalised: metadata written with counts, storage as asked, QoS of the publisher
    meta = yaml.safe_load((out_bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == storage
    assert meta["message_count"] == 15
    qos = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
           for t in meta["topics_with_message_count"]}
    assert qos["/chatter"][0]["reliability"] in ("reliable", 1)

    with bag_io.open_bag(out_bag) as reader:
        assert {n: (t.msgtype, t.count) for n, t in reader.topics.items()} == {
            "/chatter": ("std_msgs/msg/String", 11), "/image": ("sensor_msgs/msg/Image", 4)}
        recorded: dict[str, list] = {}
        for m in reader.messages():
            recorded.setdefault(m.topic, []).append((m.timestamp_ns, bytes(m.data)))
        # the recorded bag deserializes into the same messages
        first_image = reader.deserialize(next(reader.messages(["/image"])))
        assert (first_image.width, first_image.height, first_image.encoding) == (4, 3, "mono8")
    for topic, source_messages in written.items():
        got = recorded[topic]
        assert same_cdr([d for _, d in got], [d for _, d in source_messages])
        # receive-time stamps keep the source spacing (within scheduling jitter)
        for (t_rec, _), (t_src, _) in zip(got, source_messages):
            assert abs((t_rec - got[0][0]) - (t_src - source_messages[0][0])) < \
                (0.06 + lateness[1]) * S, lateness
    # and across topics the recorded order is the bag order
    merged = sorted((t, topic) for topic, msgs in recorded.items() for t, _ in msgs)
    source_order = sorted((t, topic) for topic, msgs in written.items() for t, _ in msgs)
    assert [topic for _, topic in merged] == [topic for _, topic in source_order]


def test_recorder_with_no_publisher_still_writes_a_valid_empty_bag(tmp_path, processes):
    out_bag = tmp_path / "empty"
    recorder = processes.start(module_argv("mk_tracker.ros.bag_recorder", "-o", str(out_bag),
                                           "/nobody"), fresh_domain())
    wait_for_line(recorder, "recording into", 20)
    recorder.send_signal(signal.SIGINT)
    out, err = recorder.communicate(timeout=20)
    assert recorder.returncode == 0, err
    assert "recorded 0 messages" in out
    with bag_io.open_bag(out_bag) as reader:
        assert reader.message_count == 0


def test_recorder_refuses_to_overwrite_a_bag(tmp_path, processes):
    out_bag = tmp_path / "exists"
    out_bag.mkdir()
    recorder = processes.start(module_argv("mk_tracker.ros.bag_recorder", "-o", str(out_bag),
                                           "/x"), fresh_domain())
    _, err = recorder.communicate(timeout=20)
    assert recorder.returncode == 2
    assert "exists already" in err and "Traceback" not in err
