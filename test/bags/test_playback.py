"""Pure playback scheduling: timing, rate, offset, selection, remapping, QoS, /clock."""

import pytest

from mk_tracker.bags.playback import (BEST_EFFORT, RELIABLE, TRANSIENT_LOCAL, VOLATILE,
                                 PlaybackError, PlaybackOptions, PlaybackPlan, TopicQos,
                                 offered_qos_from_metadata, output_topics, parse_qos_override,
                                 parse_remaps, resolve_qos)

S = 1_000_000_000
START = 1_700_000_000 * S
MESSAGES = [
    ("/a", "std_msgs/msg/String", START, b"a0"),
    ("/b", "std_msgs/msg/String", START + S // 2, b"b0"),
    ("/a", "std_msgs/msg/String", START + S, b"a1"),
    ("/b", "std_msgs/msg/String", START + 3 * S // 2, b"b1"),
    ("/a", "std_msgs/msg/String", START + 2 * S, b"a2"),
]


def plan(**kw):
    return PlaybackPlan(START, ["/a", "/b"], PlaybackOptions(**kw))


def test_rate_one_keeps_original_timing_and_bytes():
    out = list(plan().schedule(MESSAGES))
    assert [m.due_ns for m in out] == [0, S // 2, S, 3 * S // 2, 2 * S]
    assert [m.data for m in out] == [b"a0", b"b0", b"a1", b"b1", b"a2"]
    assert [m.topic for m in out] == ["/a", "/b", "/a", "/b", "/a"]


def test_rate_two_halves_every_delay_and_rate_half_doubles_it():
    assert [m.due_ns for m in plan(rate=2.0).schedule(MESSAGES)] == [0, S // 4, S // 2,
                                                                       3 * S // 4, S]
    assert [m.due_ns for m in plan(rate=0.5).schedule(MESSAGES)] == [0, S, 2 * S, 3 * S, 4 * S]


def test_start_offset_skips_earlier_messages_and_shifts_the_rest():
    out = list(plan(start_offset_s=1.0).schedule(MESSAGES))
    assert [m.data for m in out] == [b"a1", b"b1", b"a2"]
    assert [m.due_ns for m in out] == [0, S // 2, S]


def test_clock_reads_bag_time_scaled_by_rate_from_the_offset():
    p = plan(rate=2.0, start_offset_s=0.5)
    assert p.clock_ns(0) == START + S // 2
    assert p.clock_ns(S) == START + S // 2 + 2 * S
    assert p.clock_ns(-5) == START + S // 2


def test_topic_selection_and_remap():
    out = list(plan(topics=("b",), remaps={"/b": "/renamed"}).schedule(MESSAGES))
    assert [(m.topic, m.bag_topic, m.data) for m in out] == [("/renamed", "/b", b"b0"),
                                                             ("/renamed", "/b", b"b1")]


def test_relative_bag_topics_are_published_absolute():
    assert output_topics(["AAA", "BBB"], ["/AAA"]) == {"AAA": "/AAA"}
    assert output_topics(["AAA"], None, {"AAA": "x"}) == {"AAA": "/x"}


def test_unknown_selected_or_remapped_topic_is_a_clear_error():
    with pytest.raises(PlaybackError, match="not in the bag"):
        output_topics(["/a"], ["/typo"])
    with pytest.raises(PlaybackError, match="not in the bag"):
        output_topics(["/a"], None, {"/typo": "/x"})


def test_two_topics_remapped_onto_one_is_rejected():
    with pytest.raises(PlaybackError, match="both"):
        output_topics(["/a", "/b"], None, {"/a": "/b"})


def test_parse_remaps():
    assert parse_remaps(["/a:=/b", "c:=/d"]) == {"/a": "/b", "c": "/d"}
    for bad in ["/a", ":=/b", "/a:=", "/a=/b"]:
        with pytest.raises(PlaybackError):
            parse_remaps([bad])
    with pytest.raises(PlaybackError, match="twice"):
        parse_remaps(["/a:=/b", "/a:=/c"])


def test_out_of_order_messages_are_rejected():
    with pytest.raises(PlaybackError, match="time order"):
        list(plan().schedule([MESSAGES[2], MESSAGES[0]]))


@pytest.mark.parametrize("kw", [{"rate": 0}, {"rate": -1}, {"rate": float("nan")},
                                {"rate": float("inf")}, {"start_offset_s": -1.0},
                                {"start_offset_s": float("nan")}])
def test_bad_options_raise_playback_error(kw):
    with pytest.raises(PlaybackError):
        PlaybackOptions(**kw)


def test_qos_follows_the_bag_when_publishers_agree():
    q = resolve_qos([(BEST_EFFORT, TRANSIENT_LOCAL), (BEST_EFFORT, TRANSIENT_LOCAL)])
    assert (q.reliability, q.durability, q.depth) == (BEST_EFFORT, TRANSIENT_LOCAL, 10)


def test_qos_defaults_to_reliable_volatile_without_or_with_disagreeing_profiles():
    assert resolve_qos([]) == TopicQos(RELIABLE, VOLATILE, 10)
    mixed = resolve_qos([(BEST_EFFORT, VOLATILE), (RELIABLE, TRANSIENT_LOCAL)],
                        default_depth=3)
    assert mixed == TopicQos(RELIABLE, VOLATILE, 3)


def test_qos_override_wins_and_parses():
    topic, q = parse_qos_override("/image=best_effort,5")
    assert topic == "/image" and q == TopicQos(BEST_EFFORT, VOLATILE, 5)
    assert resolve_qos([(RELIABLE, TRANSIENT_LOCAL)], override=q) is q
    _, q2 = parse_qos_override("/x=transient_local", default_depth=7)
    assert q2 == TopicQos(RELIABLE, TRANSIENT_LOCAL, 7)
    for bad in ["/x", "/x=", "/x=fast", "/x=0"]:
        with pytest.raises(PlaybackError):
            parse_qos_override(bad)


def test_offered_qos_from_metadata_reads_old_strings_and_new_lists():
    old = ("- history: 3\n  depth: 0\n  reliability: 2\n  durability: 1\n"
           "- history: 3\n  depth: 0\n  reliability: 0\n  durability: 0\n")
    metadata = {"rosbag2_bagfile_information": {"topics_with_message_count": [
        {"message_count": 3, "topic_metadata": {"name": "/old", "offered_qos_profiles": old}},
        {"message_count": 1, "topic_metadata": {"name": "/new", "offered_qos_profiles": [
            {"reliability": "reliable", "durability": "volatile", "history": "unknown"}]}},
        {"message_count": 1, "topic_metadata": {"name": "/none", "offered_qos_profiles": ""}},
        {"message_count": 1, "topic_metadata": {"name": "/bad", "offered_qos_profiles": "[:"}},
    ]}}
    offered = offered_qos_from_metadata(metadata)
    # the system-default profile of /old says nothing and is left out
    assert offered["/old"] == [(BEST_EFFORT, TRANSIENT_LOCAL)]
    assert offered["/new"] == [(RELIABLE, VOLATILE)]
    assert offered["/none"] == []
    assert "/bad" not in offered
    assert resolve_qos(offered["/old"]) == TopicQos(BEST_EFFORT, TRANSIENT_LOCAL, 10)
    assert offered_qos_from_metadata({}) == {}
