"""``mk_launch``: start the bag player, both nodes and the recorder where ``ros2 launch`` is
not available (the pip-installed rclpy wheels).

It does what ``launch/mk_tracker.launch.py`` describes for a real ROS 2 install: every
process gets the same parameters file and remappings, ``--namespace`` puts both nodes (and
the topics the player plays to them) into a namespace, so that several camera pairs run side
by side, their output is printed line by line
with a ``[name]`` prefix, and Ctrl-C (or SIGTERM) stops them all cleanly -- SIGINT to each,
a grace period, then SIGTERM, then SIGKILL.  When the bag has been played (and ``--linger``
seconds have passed so that the last frames are processed) everything is stopped the same
way.  The exit status is 0 when every process ended on its own with status 0 or was stopped
by us; it is 1 if any process crashed (exited non-zero, or died while it was expected to
run), and the crash is named.

Fast DDS: every process gets the shared-memory profile ``config/fastdds_shm.xml``
(``FASTRTPS_DEFAULT_PROFILES_FILE`` and ``FASTDDS_DEFAULT_PROFILES_FILE``; with the default
transports 640x480 frames at 30 Hz lose most best-effort samples between processes, see
docs/fastdds_transport.md) unless either variable is already set in the environment, which
then wins, or ``--no-fastdds-shm`` is given.

Start-up order (issue #14): the nodes warm up their numba kernels before they subscribe
(about 1 s with a warm cache, 8-35 s on a first run).  Both nodes start at once; the recorder
starts once both have printed their ready line (:data:`READY_LINES`, logged after their
subscriptions exist), and the player once the recorder, if any, has subscribed; the player
then also waits until the nodes' input topics have matched subscribers
(``--wait-topics``), so no frame of the bag is played to nobody.  Discovery is not symmetric:
the player's writer can match a node's reader before that reader has matched the writer, and
a best-effort reader drops what an unmatched writer sends.  So the player then waits for a go line on its stdin
(``--go-on-stdin``), which mk_launch sends once every node has logged that its input topic
matched a publisher (:func:`matched_input`), or after ``--ready-timeout``.  The launch file
applies the first rule with launch's ``OnProcessIO`` events, and a fixed ``play_delay`` for
the second.

This module does not import rclpy: it only manages processes.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence, TextIO

GRACE_S = 5.0
#: Longest wait for a process's ready lines before the next one starts anyway.
READY_TIMEOUT_S = 120.0
#: Environment variables naming Fast DDS's XML profiles file (Fast DDS 2.x reads the first,
#: 3.x the second).
FASTDDS_PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
SHM_PROFILE_NAME = "fastdds_shm.xml"


class LaunchError(ValueError):
    """Invalid launch options."""


@dataclass(frozen=True)
class ProcessSpec:
    """One process to start.  ``essential`` processes stop the launch when they exit;
    a non-essential one (the bag player) may finish on its own."""

    name: str
    argv: tuple[str, ...]
    essential: bool = True
    env: dict = field(default_factory=dict)
    # texts that must each appear in this process's output before later processes start
    # (the recorder announces "recording /topic [type]" once it is subscribed)
    ready_lines: tuple[str, ...] = ()
    # False: start right after the previous process, without waiting for the ready lines
    # of the processes before (the two nodes warm up side by side)
    waits: bool = True
    # (process name, topic): after this process has started, each named process must log
    # that its subscription to topic matched a publisher (:func:`matched_input`); then a
    # go line is written to this process's stdin (the player's ``--go-on-stdin``)
    go_after: tuple[tuple[str, str], ...] = ()


def shm_profile_path() -> str | None:
    """``config/fastdds_shm.xml`` of this checkout, else of the installed package
    (``<prefix>/share/mk_tracker/config``), else None."""
    candidates = (Path(__file__).resolve().parents[2] / "config" / SHM_PROFILE_NAME,
                  Path(sys.prefix) / "share" / "mk_tracker" / "config" / SHM_PROFILE_NAME)
    for path in candidates:
        if path.is_file():
            return str(path)
    return None


def fastdds_environment(environ: Mapping[str, str], profile: str | None,
                        enabled: bool = True) -> dict[str, str]:
    """Variables to add to the children's environment: both profile variables set to
    ``profile``, unless disabled, there is no profile, or the user's environment already
    names a profiles file in either variable (the user's choice wins)."""
    if not enabled or profile is None or any(environ.get(v) for v in FASTDDS_PROFILE_VARIABLES):
        return {}
    return {v: profile for v in FASTDDS_PROFILE_VARIABLES}


def module_command(module: str, args: Sequence[str] = ()) -> tuple[str, ...]:
    """Run ``module.main()`` with the current interpreter (the same venv), ``args`` as argv."""
    code = f"import sys; from {module} import main; sys.exit(main())"
    return (sys.executable, "-c", code, *args)


# Inputs of the nodes as they declare them (relative names resolve to /image_raw ...).
NODE_INPUTS = {"detector_node": ("thermal/image_raw",), "tracker_node": ("image_raw",)}
#: What each node logs once it has warmed up and subscribed (the detector's
#: "detecting people (<method>) in ...", the tracker's "tracking <topic> with detections
#: from ..."); the launch file waits for the same texts.
READY_LINES = {"detector_node": "detecting people (", "tracker_node": " with detections from "}


#: What a node's log line says when a subscription gained a publisher; the whole line is
#: ``"<topic>: <n> publisher(s) matched (gained <k>)"``
#: (:func:`mk_tracker.ros.subscription_events.matched_text`).
MATCHED_MARK = " matched (gained "


def matched_input(line: str, topic: str) -> bool:
    """Whether a node's output ``line`` says that its subscription to ``topic`` (or to its
    compressed transport, ``topic/compressed``) has matched a publisher."""
    if MATCHED_MARK not in line:
        return False
    # the topic as a whole name: "/thermal/image_raw: ..." is no match of /image_raw
    return re.search(rf"(^|\s){re.escape(topic)}(/compressed)?: ", line) is not None


def normalize_namespace(namespace: str) -> str:
    """``cam1``, ``/cam1/`` -> ``/cam1``; empty -> ``""`` (the root)."""
    parts = [p for p in namespace.strip().split("/") if p]
    for part in parts:
        if not part.replace("_", "a").isalnum() or part[0].isdigit():
            raise LaunchError(f"namespace {namespace!r}: {part!r} is not a valid name "
                              "(letters, digits and _, not starting with a digit)")
    return "/" + "/".join(parts) if parts else ""


def remapped(topic: str, remaps: Sequence[str], namespace: str = "") -> str:
    """Absolute name of node topic ``topic`` after ``from:=to`` remappings, for a node in
    ``namespace`` (relative names, on either side of a rule, resolve inside it)."""
    def resolve(name: str) -> str:
        name = name.strip()
        return name if name.startswith("/") else f"{namespace}/{name}"

    absolute = resolve(topic)
    for remap in remaps:
        source, _, target = remap.partition(":=")
        if resolve(source) == absolute:
            absolute = resolve(target)
    return absolute


def ros_args(params_files: Sequence[str] = (), remaps: Sequence[str] = (),
             node_name: str | None = None, use_sim_time: bool = False,
             namespace: str = "") -> list[str]:
    """``--ros-args`` tail with the params files and ``from:=to`` remappings."""
    tail: list[str] = []
    for params_file in params_files:
        tail += ["--params-file", params_file]
    if use_sim_time:
        tail += ["-p", "use_sim_time:=true"]
    if node_name:
        tail += ["-r", f"__node:={node_name}"]
    if namespace:
        tail += ["-r", f"__ns:={namespace}"]
    for remap in remaps:
        if ":=" not in remap:
            raise LaunchError(f"remap {remap!r} is not of the form FROM:=TO")
        tail += ["-r", remap]
    return ["--ros-args", *tail] if tail else []


def _bag_topics(bag: str) -> set[str]:
    """Absolute names of the topics of ``bag`` (empty if it cannot be read: the player
    will report that itself)."""
    try:
        from rosbags.typesys import Stores, get_typestore

        from mk_tracker.bags import bag_io
    except ImportError:
        return set()       # the player says that rosbags is missing
    try:
        with bag_io.open_bag(bag, on_error="skip",
                             typestore=get_typestore(Stores.EMPTY)) as reader:
            return {"/" + name.lstrip("/") for name in reader.topics}
    except bag_io.BagError:
        return set()


def player_waits(specs: Sequence[ProcessSpec], remaps: Sequence[str] = (),
                 namespace: str = "") -> tuple[list[str], tuple[tuple[str, str], ...]]:
    """The player's arguments and ``go_after`` for the nodes among ``specs``: wait for its
    writers to match the nodes' inputs, then for the go line that follows the nodes' own
    match lines (none of it when no node runs: nobody to wait for)."""
    go_after = tuple((spec.name, remapped(topic, remaps, namespace)) for spec in specs
                     for topic in NODE_INPUTS.get(spec.name, ()))
    if not go_after:
        return [], ()
    return ["--wait-topics", *(topic for _, topic in go_after), "--go-on-stdin"], go_after


def thermal_only_remaps(remaps: Sequence[str], namespace: str = "") -> list[str]:
    """``remaps`` plus the rule of thermal-only mode (issue #19: no RGB camera): the
    tracker's ``image_raw`` is the thermal camera the detector reads (``thermal/image_raw``
    after ``remaps``), so the people found in the thermal image are tracked in it.  The
    detector's own input is not matched by the new rule (ROS remaps whole names)."""
    return [*remaps, f"image_raw:={remapped('thermal/image_raw', remaps, namespace)}"]


def build_specs(args: argparse.Namespace) -> list[ProcessSpec]:
    """The processes ``mk_launch`` starts for parsed command-line ``args``."""
    for params_file in args.params_file:
        if not os.path.isfile(params_file):
            raise LaunchError(f"parameters file {params_file!r} does not exist")
    if args.bag and not os.path.exists(args.bag):
        raise LaunchError(f"bag {args.bag!r} does not exist")
    namespace = normalize_namespace(args.namespace)
    remaps = (thermal_only_remaps(args.remap, namespace) if args.thermal_only
              else list(args.remap))
    # the thermal-only rule is the tracker's: the bag's own /image_raw, if it has one,
    # is not played onto the thermal topic
    nodes_only = set(remaps[len(args.remap):])
    specs: list[ProcessSpec] = []
    for name, skip in (("detector_node", args.no_detector), ("tracker_node", args.no_tracker)):
        if not skip:       # both warm up at once; what follows waits for their ready lines
            specs.append(ProcessSpec(name, module_command(
                f"mk_tracker.ros.{name}", ros_args(args.params_file, remaps,
                                                   use_sim_time=args.clock,
                                                   namespace=namespace)),
                ready_lines=(READY_LINES[name],), waits=False))
    if args.record:
        if not args.record_topics:
            raise LaunchError("--record needs --record-topics")
        rec = ["-o", args.record, "--storage", args.storage, *args.record_topics]
        # the player starts once the recorder has subscribed to every recorded topic
        # that the nodes publish (topics only the player publishes appear with it)
        played = _bag_topics(args.bag) if args.bag else set()
        awaited = ["/" + t.lstrip("/") for t in args.record_topics]
        ready = tuple(f"recording {t} [" for t in awaited
                      if remapped(t, remaps, namespace) not in played and t not in played)
        specs.append(ProcessSpec("bag_recorder", module_command(
            "mk_tracker.ros.bag_recorder", rec), ready_lines=("recording into",) + ready))
    if args.bag:
        play = [args.bag, "--rate", str(args.rate), "--wait-for-subscribers",
                str(args.wait_for_subscribers)]
        wait_args, go_after = player_waits(specs, remaps, namespace)
        play += wait_args
        if args.clock:
            play += ["--clock"]
        played = _bag_topics(args.bag)
        for remap in remaps:
            # a rule for a topic the bag does not have (e.g. the detector's input remapped
            # to the RGB camera of an RGB-only bag) is the nodes' alone
            if remap not in nodes_only and (
                    not played or remapped(remap.partition(":=")[0], ()) in played):
                play += ["--remap", remap]
        if namespace:   # the bag's topics at the root go to the nodes in the namespace
            for spec in specs:
                for topic in NODE_INPUTS.get(spec.name, ()):
                    root, inside = remapped(topic, remaps), remapped(
                        topic, remaps, namespace)
                    if root != inside:
                        play += ["--remap", f"{root}:={inside}"]
        specs.append(ProcessSpec("bag_player", module_command(
            "mk_tracker.ros.bag_player", play), essential=False, go_after=go_after))
    if not specs:
        raise LaunchError("nothing to launch")
    dds = fastdds_environment(os.environ, shm_profile_path(), not args.no_fastdds_shm)
    if dds:
        specs = [replace(spec, env={**dds, **spec.env}) for spec in specs]
    return specs


def _die_with_parent() -> None:
    """In the child before exec: get SIGTERM when mk_launch dies, even by SIGKILL, so no
    node outlives a killed launcher (Linux prctl PR_SET_PDEATHSIG; elsewhere a no-op)."""
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        pass


class _Running:
    def __init__(self, spec: ProcessSpec, out: TextIO, lock: threading.Lock) -> None:
        env = dict(os.environ)
        env.update(spec.env)
        env.setdefault("PYTHONUNBUFFERED", "1")
        self.spec = spec
        self.stopped_by_us = False
        self.waiting_for = list(spec.ready_lines)
        self.lines: list[tuple[float, str]] = []   # (monotonic time, line) of match lines
        self.started = time.monotonic()
        self.go_sent = not spec.go_after
        self.proc = subprocess.Popen(spec.argv, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT,
                                     stdin=subprocess.PIPE if spec.go_after
                                     else subprocess.DEVNULL,
                                     env=env, text=True, errors="replace", bufsize=1,
                                     start_new_session=True,
                                     preexec_fn=_die_with_parent if sys.platform.startswith(
                                         "linux") else None)
        self.pump = threading.Thread(target=self._copy, args=(out, lock), daemon=True)
        self.pump.start()

    def ready(self) -> bool:
        return not self.waiting_for

    def _copy(self, out: TextIO, lock: threading.Lock) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.waiting_for = [t for t in self.waiting_for if t not in line]
            if MATCHED_MARK in line:
                self.lines.append((time.monotonic(), line))
            with lock:
                out.write(f"[{self.spec.name}] {line.rstrip()}\n")
                out.flush()


def _terminate(procs: list[_Running], grace_s: float, log) -> None:
    """SIGINT every live process, wait; then SIGTERM; then SIGKILL."""
    for sig, label in ((signal.SIGINT, "SIGINT"), (signal.SIGTERM, "SIGTERM"),
                       (signal.SIGKILL, "SIGKILL")):
        live = [p for p in procs if p.proc.poll() is None]
        if not live:
            return
        if sig != signal.SIGINT:
            log(f"{', '.join(p.spec.name for p in live)} still running: sending {label}")
        for p in live:
            p.stopped_by_us = True
            try:
                p.proc.send_signal(sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + grace_s
        while time.monotonic() < deadline and any(p.proc.poll() is None for p in live):
            time.sleep(0.05)
    for p in procs:
        p.proc.wait()


def crashed(returncode: int, stopped_by_us: bool) -> bool:
    """Whether an exit status is a crash: non-zero, unless it is the expected result of a
    signal we sent (Python exits 130/-2 on SIGINT, -15 on SIGTERM, -9 on SIGKILL)."""
    if returncode == 0:
        return False
    if stopped_by_us and returncode in (-signal.SIGINT, -signal.SIGTERM, -signal.SIGKILL,
                                        130, 143):
        return False
    return True


def _wait_ready(procs: list[_Running], timeout_s: float, stop_event: threading.Event,
                log) -> None:
    """Wait until every started process has printed its ``ready_lines`` (or exited)."""
    deadline = time.monotonic() + timeout_s
    while not stop_event.is_set():
        waiting = [p for p in procs if not p.ready() and p.proc.poll() is None]
        if not waiting:
            return
        if time.monotonic() >= deadline:
            for p in waiting:
                log(f"{p.spec.name} not ready after {timeout_s:g} s (still waiting for "
                    f"{', '.join(repr(t) for t in p.waiting_for)}); starting the next anyway")
            return
        stop_event.wait(0.05)


def _send_go_when_matched(procs: list[_Running], timeout_s: float, log) -> None:
    """Write the go line to every started process whose ``go_after`` matches have all been
    logged since it started (or that has waited ``timeout_s``)."""
    by_name = {p.spec.name: p for p in procs}
    for p in procs:
        if p.go_sent or p.proc.poll() is not None:
            continue
        missing = [(name, topic) for name, topic in p.spec.go_after
                   if name in by_name and not any(
                       t >= p.started and matched_input(line, topic)
                       for t, line in list(by_name[name].lines))]
        timed_out = time.monotonic() - p.started >= timeout_s
        if missing and not timed_out:
            continue
        if missing:
            log(f"{', '.join(f'{n} on {t}' for n, t in missing)} did not log a matched "
                f"publisher within {timeout_s:g} s; telling {p.spec.name} to go anyway")
        p.go_sent = True
        try:
            assert p.proc.stdin is not None
            p.proc.stdin.write("go\n")
            p.proc.stdin.flush()
        except (OSError, ValueError):     # it exited meanwhile: its status tells
            pass


def run_processes(specs: Sequence[ProcessSpec], *, grace_s: float = GRACE_S,
                  linger_s: float = 0.0, timeout_s: float | None = None,
                  out: TextIO | None = None, stop_event: threading.Event | None = None,
                  start_delay_s: float = 0.0,
                  ready_timeout_s: float = READY_TIMEOUT_S) -> int:
    """Start ``specs`` in order, relay their output, and stop them all; return 0 or 1.

    A spec starts only once every earlier process has printed its ``ready_lines`` (or
    exited), at most ``ready_timeout_s`` later; one with ``waits=False`` starts at once.
    A spec with ``go_after`` gets a go line on its stdin once those processes have logged
    their input's match, at most ``ready_timeout_s`` after it started.

    The launch ends when ``stop_event`` is set (SIGINT/SIGTERM of ``mk_launch``), when an
    essential process exits, when every non-essential process has finished and
    ``linger_s`` has passed, or after ``timeout_s``.
    """
    out = out or sys.stdout
    lock = threading.Lock()
    stop_event = stop_event or threading.Event()

    def log(text: str) -> None:
        with lock:
            out.write(f"[mk_launch] {text}\n")
            out.flush()

    procs: list[_Running] = []
    try:
        for spec in specs:
            if spec.waits:
                _wait_ready(procs, ready_timeout_s, stop_event, log)
            procs.append(_Running(spec, out, lock))
            log(f"started {spec.name} (pid {procs[-1].proc.pid})")
            if start_delay_s and spec is not specs[-1]:
                stop_event.wait(start_delay_s)
        started = time.monotonic()
        optional = [p for p in procs if not p.spec.essential]
        finished_at = None
        while not stop_event.is_set():
            _send_go_when_matched(procs, ready_timeout_s, log)
            dead = [p for p in procs if p.spec.essential and p.proc.poll() is not None]
            if dead:
                log(f"{dead[0].spec.name} exited with status {dead[0].proc.returncode}; "
                    "stopping the others")
                break
            failed = [p for p in optional if p.proc.poll() not in (None, 0)]
            if failed:
                log(f"{failed[0].spec.name} failed with status {failed[0].proc.returncode}")
                break
            if optional and all(p.proc.poll() == 0 for p in optional):
                if finished_at is None:
                    finished_at = time.monotonic()
                    log(f"{', '.join(p.spec.name for p in optional)} finished")
                if time.monotonic() - finished_at >= linger_s:
                    break
            if timeout_s is not None and time.monotonic() - started >= timeout_s:
                log(f"timeout of {timeout_s} s reached")
                break
            stop_event.wait(0.05)
    finally:
        _terminate(procs, grace_s, log)
        for p in procs:
            p.pump.join(timeout=2.0)
    status = 0
    for p in procs:
        if crashed(p.proc.returncode, p.stopped_by_us):
            log(f"{p.spec.name} crashed (status {p.proc.returncode})")
            status = 1
    log("all processes stopped" + (" (with failures)" if status else ""))
    return status


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--bag", help="rosbag2 bag to play (omit to only run the nodes)")
    parser.add_argument("--params-file", action="append", default=[], metavar="YAML",
                        help="ROS 2 parameters file given to both nodes (repeatable; a file "
                             "is keyed by node name, e.g. config/tracker.yaml)")
    parser.add_argument("--remap", action="append", default=[], metavar="FROM:=TO",
                        help="topic remapping applied to the nodes, and to the player "
                             "when the bag has the topic (RGB only: "
                             "thermal/image_raw:=image_raw feeds the RGB camera to the "
                             "detector)")
    parser.add_argument("--thermal-only", action="store_true",
                        help="no RGB camera: the tracker follows the people in the thermal "
                             "image the detector reads (its image_raw is remapped to it)")
    parser.add_argument("--namespace", default="", metavar="NS",
                        help="run both nodes in namespace NS (their relative topics then "
                             "resolve inside it, e.g. /NS/image_raw); the player plays the "
                             "bag's root-level input topics into it")
    parser.add_argument("--rate", type=float, default=1.0, help="playback rate factor")
    parser.add_argument("--clock", action="store_true",
                        help="player publishes /clock and the nodes run on it (use_sim_time)")
    parser.add_argument("--wait-for-subscribers", type=float, default=10.0, metavar="S",
                        help="player waits up to S seconds for the nodes to subscribe")
    parser.add_argument("--record", metavar="OUT", help="record into this new bag")
    parser.add_argument("--record-topics", nargs="+", default=[], metavar="TOPIC")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    parser.add_argument("--no-detector", action="store_true")
    parser.add_argument("--no-tracker", action="store_true")
    parser.add_argument("--no-fastdds-shm", action="store_true",
                        help="do not give the processes config/fastdds_shm.xml (Fast DDS "
                             "shared memory); it is never given when "
                             "FASTRTPS_DEFAULT_PROFILES_FILE or FASTDDS_DEFAULT_PROFILES_FILE "
                             "is already set")
    parser.add_argument("--linger", type=float, default=2.0, metavar="S",
                        help="after the bag is played, keep running S seconds (default 2)")
    parser.add_argument("--timeout", type=float, default=None, metavar="S",
                        help="stop everything after S seconds")
    parser.add_argument("--ready-timeout", type=float, default=READY_TIMEOUT_S, metavar="S",
                        help="the recorder and the player start when the nodes have warmed "
                             "up and subscribed (and the player when the recorder has "
                             "subscribed to the nodes' topics), or after S seconds "
                             f"(default {READY_TIMEOUT_S:g}: a first run compiles the numba "
                             "kernels, 8-35 s)")
    parser.add_argument("--grace", type=float, default=GRACE_S, metavar="S",
                        help="seconds between SIGINT, SIGTERM and SIGKILL on shutdown")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="mk_launch", description=__doc__.splitlines()[0])
    configure_parser(parser)
    args = parser.parse_args(argv)
    try:
        specs = build_specs(args)
    except LaunchError as exc:
        print(f"mk_launch: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()

    def on_signal(signum, _frame) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    return run_processes(specs, grace_s=args.grace, linger_s=args.linger,
                         timeout_s=args.timeout, stop_event=stop,
                         ready_timeout_s=args.ready_timeout)


if __name__ == "__main__":
    sys.exit(main())
