"""The harness's service call (nodes_harness.call_service) with a fake client and peer: an
idempotent request is re-sent until one send is answered; a request with effects is sent
once."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from nodes_harness import call_service  # noqa: E402


class Future:
    def __init__(self):
        self.answer = None

    def done(self):
        return self.answer is not None

    def result(self):
        return self.answer


class Client:
    """Answers the ``answered``-th send (0-based) as soon as the peer spins; loses the
    others, like a request sent before the response path has matched."""

    def __init__(self, answered):
        self.answered, self.sent = answered, []

    def wait_for_service(self, timeout_sec):
        return True

    def call_async(self, request):
        self.sent.append(Future())
        return self.sent[-1]


class Peer:
    """Spins by answering the client's pending send, if it is the one to answer; the
    clock is a counter of spins, so no real time passes."""

    def __init__(self, client, monkeypatch):
        self.client, self.now = client, 0.0
        monkeypatch.setattr("nodes_harness.time.monotonic", lambda: self.now)

    def spin_until(self, predicate, timeout):
        self.now += timeout
        if len(self.client.sent) > self.client.answered:
            self.client.sent[self.client.answered].answer = f"answer {self.client.answered}"
        return predicate()


def test_a_lost_request_is_sent_again_until_answered(monkeypatch):
    client = Client(answered=2)
    peer = Peer(client, monkeypatch)
    assert call_service(peer, client, "get", timeout=30.0, resend_after=5.0) == "answer 2"
    assert len(client.sent) == 3 and peer.now == 15.0


def test_a_request_with_effects_is_sent_once(monkeypatch):
    client = Client(answered=1)
    peer = Peer(client, monkeypatch)
    with pytest.raises(AssertionError, match=r"within 30.0 s \(1 request"):
        call_service(peer, client, "start", timeout=30.0)
    assert len(client.sent) == 1


def test_resending_stops_at_the_timeout(monkeypatch):
    client = Client(answered=100)
    peer = Peer(client, monkeypatch)
    with pytest.raises(AssertionError, match=r"\(6 request\(s\) sent\)"):
        call_service(peer, client, "get", timeout=30.0, resend_after=5.0)
    assert peer.now == 30.0
