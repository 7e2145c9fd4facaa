"""Helpers of the node integration tests (test_nodes_*.py): node processes and a test peer.

* :func:`ros_env` -- environment of one test: its own ROS_DOMAIN_ID, discovery limited to
  localhost, the shared-memory Fast DDS profile of config/fastdds_shm.xml.
* :class:`NodeProcess` -- a node started as a separate process
  (``python -m mk_tracker.ros.<node> --ros-args ...``) in its own process group; ``stop()``
  sends SIGINT, then SIGTERM, then SIGKILL to the whole group, so nothing is left behind.
* :class:`Peer` -- an rclpy node in the test process (own context and executor) with
  publishers, collecting subscriptions and ``spin_until``.
* :class:`NodeGroup` -- starts nodes of the package (waiting for each one's ready line) and
  stops them all at the end; :data:`READY` is each node's ready line.
* :func:`reliable_qos`, :func:`latest_at` -- the peer's QoS and the lock-step look-up of the
  answer to one stamp.
* :func:`publishers_matched`, :meth:`Peer.wait_matched` -- wait until both ends of every
  connection between the test and the nodes have matched (discovery is not symmetric; see
  :meth:`Peer.wait_matched`).
* :func:`call_service` -- a service call that re-sends an idempotent request until it is
  answered (a service's two DDS directions match independently).
* :func:`start_bag_player`, :func:`stop_process_group` -- our ``bag_player`` playing a bag
  into the test's domain, and its clean-up.
* Fixtures ``domain`` (own ROS_DOMAIN_ID, also in the test process) and ``peer``: a test
  module imports them (``from nodes_harness import domain, peer``).
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable, Sequence

import pytest

REPO = Path(__file__).resolve().parents[1]
FASTDDS_PROFILE = REPO / "config" / "fastdds_shm.xml"
_counter = itertools.count()


def unique_domain() -> int:
    """A ROS domain id for one test, spread by pid so parallel sessions rarely collide."""
    return 1 + (os.getpid() * 13 + next(_counter) * 7) % 100


def ros_env(domain: int) -> dict[str, str]:
    env = dict(os.environ)
    env.update({
        "ROS_DOMAIN_ID": str(domain),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "FASTRTPS_DEFAULT_PROFILES_FILE": str(FASTDDS_PROFILE),
        "FASTDDS_DEFAULT_PROFILES_FILE": str(FASTDDS_PROFILE),
        "PYTHONPATH": os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]).rstrip(os.pathsep),
        "PYTHONUNBUFFERED": "1",
        "RCUTILS_COLORIZED_OUTPUT": "0",
        "RCUTILS_LOGGING_BUFFERED_STREAM": "0",
    })
    env.pop("ROS_LOCALHOST_ONLY", None)
    return env


def apply_env_to_test_process(monkeypatch: Any, domain: int) -> None:
    """Same discovery settings in the test process (rmw reads them when a context starts)."""
    for key, value in ros_env(domain).items():
        if key.startswith(("ROS_", "FASTRTPS_", "FASTDDS_")):
            monkeypatch.setenv(key, value)


class NodeProcess:
    """One node as a child process; output goes to ``log_path``."""

    def __init__(self, module: str, ros_args: list[str], env: dict[str, str],
                 log_path: Path) -> None:
        self.log_path = log_path
        self._log = open(log_path, "w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", module, "--ros-args", *ros_args],
            env=env, cwd=str(REPO), stdout=self._log, stderr=subprocess.STDOUT,
            start_new_session=True)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def output(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors="replace")

    def wait_for_output(self, text: str, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.output():
                return True
            if not self.alive():
                return text in self.output()
            time.sleep(0.05)
        return False

    def stop(self) -> int | None:
        """SIGINT, then SIGTERM, then SIGKILL to the process group; returns the exit code."""
        if self.proc.poll() is None:
            for sig, wait in ((signal.SIGINT, 5.0), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
                try:
                    os.killpg(self.proc.pid, sig)
                except ProcessLookupError:
                    break
                try:
                    self.proc.wait(wait)
                    break
                except subprocess.TimeoutExpired:
                    continue
        try:                       # anything the node may have spawned in its group
            os.killpg(self.proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        self._log.close()
        return self.proc.returncode


#: Upper bound of a wait for DDS discovery (normally 0.1-3 s on localhost, even loaded).
MATCH_TIMEOUT_S = 30.0


def publishers_matched(node: "NodeProcess", topic: str) -> int:
    """How many publishers ``node``'s subscription of ``topic`` (resolved name, e.g.
    ``/thermal/detections``) has matched, by its latest matched-event log line (0 before
    the first one)."""
    count = 0
    for line in node.output().splitlines():
        _, sep, rest = line.partition(f" {topic}: ")
        if not sep:
            continue
        if rest.startswith("no publisher matched"):
            count = 0
        elif " matched (" in rest:
            count = int(rest.split(" ", 1)[0])
    return count


def matched_events(node: "NodeProcess", topic: str) -> int:
    """How many times ``node``'s subscription of ``topic`` logged that it gained a
    publisher (a restarted peer node is a new match)."""
    return sum(1 for line in node.output().splitlines()
               if f" {topic}: " in line and "(gained" in line)


class Peer:
    """An rclpy node in the test process, on its own context."""

    def __init__(self, domain: int, name: str = "test_peer") -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain, args=[])
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.received: dict[str, list] = {}
        self.subscriptions: dict[str, Any] = {}
        self._matches: dict[Any, list[int]] = {}     # endpoint -> [matches ever (total)]

    def _counter(self) -> tuple[list[int], Callable[[Any], None]]:
        box = [0]

        def on_matched(status: Any) -> None:
            box[0] = max(box[0], int(status.total_count))
        return box, on_matched

    def publisher(self, msg_type: Any, topic: str, qos: Any) -> Any:
        """A publisher whose DDS matches are counted (:meth:`matches`)."""
        from rclpy.event_handler import PublisherEventCallbacks
        box, on_matched = self._counter()
        pub = self.node.create_publisher(
            msg_type, topic, qos, event_callbacks=PublisherEventCallbacks(matched=on_matched))
        self._matches[pub] = box
        return pub

    def subscribe(self, msg_type: Any, topic: str, callback: Callable[[Any], None],
                  qos: Any) -> Any:
        """A subscription whose DDS matches are counted (:meth:`matches`)."""
        from rclpy.event_handler import SubscriptionEventCallbacks
        box, on_matched = self._counter()
        sub = self.node.create_subscription(
            msg_type, topic, callback, qos,
            event_callbacks=SubscriptionEventCallbacks(matched=on_matched))
        self._matches[sub] = box
        return sub

    def collect(self, msg_type: Any, topic: str, qos: Any) -> list:
        """Subscribe ``topic``; its messages are appended to the returned list."""
        store = self.received.setdefault(topic, [])
        self.subscriptions[topic] = self.subscribe(msg_type, topic, store.append, qos)
        return store

    def matches(self, endpoint: Any) -> int:
        """How many remote endpoints ``endpoint`` (made by :meth:`publisher`,
        :meth:`subscribe` or :meth:`collect`) has matched since it was created, counting
        ones that went away: a restarted node's endpoint is a new match, while the current
        count (``get_subscription_count``) still includes the killed process's endpoint
        until its lease runs out."""
        return self._matches[endpoint][0]

    def wait_matched(self, publishers: Sequence[Any] = (), subscriptions: Sequence[Any] = (),
                     node_inputs: Sequence[tuple] = (),
                     timeout: float = MATCH_TIMEOUT_S) -> bool:
        """Spin until every connection the test will use is matched at both ends it can see:

        * each of ``publishers`` (the peer's) has matched a subscription, and each node of
          ``node_inputs`` (node, topic) has logged that its reader of ``topic`` matched a
          publisher (mk_tracker.ros.subscription_events) -- both ends of peer -> node;
        * each of ``subscriptions`` (the peer's; a topic name means the one :meth:`collect`
          made) has matched a publisher -- the reader's end of node -> peer.

        An item ``(endpoint, n)`` of ``publishers``/``subscriptions`` asks for ``n`` matches
        since it was created (:meth:`matches`; after a node was restarted: 2), and an item
        ``(node, topic, n)`` of ``node_inputs`` for ``n`` logged gains
        (:func:`matched_events`).

        Discovery is not symmetric: a writer can match a reader before the reader has
        matched it; a reliable sample sent in between is dropped by the reader and repaired
        only after the writer's next heartbeat (Fast DDS: up to ~3 s later), so the first
        answer of a lock-step test arrived late or, with a short timeout, "never".  Checking
        the peer's publisher alone (``get_subscription_count``) was the cause of late first
        messages.  The remaining end (a node's writer matching the peer's reader) is not
        observable from here; it is announced in the same discovery exchange, so once the
        visible ends matched the peer spins a settle time more: half the time the visible
        matches took in this run, at least 0.5 s (as ``bag_player`` does), at most 3 s --
        longer on a machine where discovery was slow.

        ``timeout`` only bounds a wait for something that must happen; discovery on
        localhost took 0.1-3 s here, idle or loaded."""
        def wanted(items: Sequence[Any]) -> list[tuple[Any, int]]:
            out = []
            for item in items:
                endpoint, n = item if isinstance(item, tuple) else (item, 1)
                out.append((self.subscriptions[endpoint] if isinstance(endpoint, str)
                            else endpoint, n))
            return out
        pubs, subs = wanted(publishers), wanted(subscriptions)
        inputs = [(item[0], item[1], item[2] if len(item) > 2 else 1) for item in node_inputs]

        def matched() -> bool:
            return (all(p.get_subscription_count() > 0 and self.matches(p) >= n
                        for p, n in pubs)
                    and all(s.get_publisher_count() > 0 and self.matches(s) >= n
                            for s, n in subs)
                    and all(publishers_matched(node, topic) > 0
                            and matched_events(node, topic) >= n
                            for node, topic, n in inputs))
        t0 = time.monotonic()
        if not self.spin_until(matched, timeout):
            return False
        self.spin_for(min(3.0, max(0.5, (time.monotonic() - t0) / 2)))
        return True

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return predicate()

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def close(self) -> None:
        import rclpy
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def call_service(peer: "Peer", client: Any, request: Any, timeout: float,
                 resend_after: float | None = None) -> Any:
    """The answer of ``client`` (a service client of ``peer.node``) to ``request``.

    Waits up to ``timeout`` s for the service, then for an answer.  The two directions of a
    service are two DDS topics discovered independently: a request sent after the client
    saw the server's request reader but before the server's response writer matched the
    client's response reader is answered into the void, and its future never completes
    (seen once in CI, under load, on a namespaced parameter service).  So an *idempotent*
    request (get or set parameters) is sent again every ``resend_after`` s until one of the
    sends is answered; the first answer counts, whenever it comes.  Not for requests with
    effects (start a track): leave ``resend_after`` None there.
    """
    assert client.wait_for_service(timeout_sec=timeout), "service not available"
    deadline = time.monotonic() + timeout
    futures = [client.call_async(request)]
    while True:
        remaining = deadline - time.monotonic()
        step = remaining if resend_after is None else min(resend_after, remaining)
        if step > 0 and peer.spin_until(lambda: any(f.done() for f in futures), step):
            return next(f for f in futures if f.done()).result()
        if resend_after is None or time.monotonic() >= deadline:
            raise AssertionError(f"no answer from the service within {timeout} s "
                                 f"({len(futures)} request(s) sent)")
        futures.append(client.call_async(request))


def stamp_of(msg: Any) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def make_stamp(seconds: float) -> Any:
    from builtin_interfaces.msg import Time
    ns = int(round(seconds * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def latest_at(messages: Sequence[Any], stamp: float, first: int = 0) -> Any:
    """The newest message of ``stamp`` among ``messages[first:]``, or None (lock-step: only
    an answer to this very frame counts)."""
    for msg in reversed(messages[first:]):
        if abs(stamp_of(msg) - stamp) < 1e-6:
            return msg
    return None


def reliable_qos(depth: int = 10) -> Any:
    """Reliable keep-last QoS of the test peer's publishers and subscriptions."""
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE)


#: Bound of a wait for a node's ready line: 2-5 s here with the numba kernels cached (the
#: session compiles them first, test/conftest.py); 60 s leaves 10x for a slower or loaded
#: machine.
READY_TIMEOUT_S = 60.0

#: The line each node logs once it is subscribed and publishing.
READY = {"mk_tracker.ros.detector_node": "detecting people",
         "mk_tracker.ros.tracker_node": "tracking /image_raw"}


class NodeGroup:
    """Nodes started for one test (``start``); ``stop_all`` stops every one of them."""

    def __init__(self, domain: int, log_dir: Path) -> None:
        self.domain = domain
        self.log_dir = log_dir
        self.started: list[NodeProcess] = []

    def start(self, module: str, *ros_args: str, timeout: float = READY_TIMEOUT_S,
              ready: str | None = None) -> NodeProcess:
        """Start ``module`` with ``--ros-args ros_args`` and wait for its ready line
        (``ready``, by default :data:`READY`'s, which names the root namespace's topic)."""
        name = module.rsplit(".", 1)[-1]
        node = NodeProcess(module, list(ros_args), ros_env(self.domain),
                           self.log_dir / f"{name}_{len(self.started)}.log")
        self.started.append(node)
        assert node.wait_for_output(ready or READY[module], timeout), node.output()
        return node

    def starter(self, module: str) -> Callable[..., NodeProcess]:
        """``start(*ros_args)`` for one module (a test's node factory)."""
        return lambda *ros_args: self.start(module, *ros_args)

    def stop_all(self) -> None:
        for node in self.started:
            node.stop()
        assert not any(node.alive() for node in self.started)


@pytest.fixture
def domain(monkeypatch: Any) -> int:
    """A ROS domain with no other node in it for one test (test/quiet_domain.py: another
    session's frames of another size would reset the tracker), set in the test process too."""
    from quiet_domain import quiet_domain      # it imports this module
    return quiet_domain(monkeypatch)


@pytest.fixture
def peer(domain: int) -> Any:
    """The test's rclpy peer node, closed at the end."""
    p = Peer(domain)
    yield p
    p.close()


@pytest.fixture
def node_group(domain: int, tmp_path: Path) -> Any:
    """A :class:`NodeGroup` of the test's domain; its nodes are stopped at the end."""
    group = NodeGroup(domain, tmp_path)
    try:
        yield group
    finally:
        group.stop_all()


def start_bag_player(bag: Path, domain: int, log: Path, rate: float,
                     topics: Sequence[str]) -> subprocess.Popen:
    """``bag_player`` playing ``topics`` of ``bag`` at ``rate`` into ``domain`` (it waits up
    to 20 s for the subscribers of every topic, and for their acknowledgements at the end);
    its output goes to ``log``."""
    argv = [sys.executable, "-m", "mk_tracker.ros.bag_player", str(bag),
            "--rate", str(rate), "--topics", *topics,
            "--wait-for-subscribers", "20", "--ack-timeout", "3"]
    return subprocess.Popen(argv, env=ros_env(domain), cwd=str(REPO), stdout=log.open("w"),
                            stderr=subprocess.STDOUT, start_new_session=True)


def stop_process_group(proc: subprocess.Popen) -> None:
    """SIGINT, then SIGKILL, the process group of ``proc`` if it still runs."""
    if proc.poll() is None:
        for sig in (signal.SIGINT, signal.SIGKILL):
            try:
                os.killpg(proc.pid, sig)
                proc.wait(3.0)
                break
            except ProcessLookupError:
                break
            except subprocess.TimeoutExpired:
                continue
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
