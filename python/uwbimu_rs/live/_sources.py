"""Where the live node's data comes from: ROS 2 topics over DDS, a Nooploop LinkTrack serial
port, or a recorded MCAP played at its recorded pace. Each source has ``poll(timeout_s)``: hand
what has arrived to the node, waiting at most ``timeout_s``; ``finished`` says it will give no
more (the end of a file)."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator, Mapping
from typing import Any

from uwbimu_rs import _native
from uwbimu_rs.live._node import LiveNode

log = logging.getLogger("uwbimu.live")


class DdsSource:
    """The mapped topics of a ROS 2 graph (``live_subscriptions``), decoded by the mapping.

    A topic whose type and ``.msg`` are known is subscribed at once. One whose type is not
    named (a UWB topic without ``live.types``), or whose ``.msg`` is found nowhere, is subscribed
    when its first publisher appears: the type is the publisher's, the definition the bundled
    or ``live.msg_paths`` one, else the one the publisher's type information gives. With
    ``discover`` (the mapping names no UWB or TDoA topic) every other topic that appears is
    offered to the mapping the same way, and taken when it reads it (an IMU, a range message).
    ``reliable`` subscribes reliable, keeping every sample (``live.reliable_inputs``)."""

    finished = False

    def __init__(
        self,
        bus: Any,
        subscriptions: list[tuple[Any, ...]],
        decoder: Any,
        node: LiveNode,
        msg_paths: list[str],
        *,
        discover: bool = False,
        reliable: bool = False,
    ) -> None:
        from uwbimu_rs.live._graph import Graph

        self.bus, self.decoder, self.node, self.msg_paths = bus, decoder, node, msg_paths
        self.discover, self.reliable = discover, reliable
        self.pending: dict[str, tuple[str, str | None]] = {}
        self._seen: set[str] = set()
        for topic, type_name, definition, dds_topic, _ in subscriptions:
            self._seen.add(dds_topic)
            if type_name is not None and definition is not None:
                self._subscribe(topic, type_name, definition, dds_topic)
            else:
                self.pending[dds_topic] = (topic, type_name)
                node.watch(topic, "uwb" if type_name is None else "pending")
                log.info("%s: waiting for a publisher to learn its %s", topic, "definition" if type_name else "type")
        if discover:
            log.info("no UWB topic named: taking every topic on the graph that the mapping reads")
        self.graph = Graph(bus.participant) if self.pending or discover else None

    def _subscribe(self, topic: str, type_name: str, definition: str, dds_topic: str) -> None:
        from uwbimu_rs.live._dds import idl_type

        role = self.decoder.add_topic(topic, type_name, definition)
        if role is None:
            raise ValueError(f"topic {topic} ({type_name}): the mapping takes nothing from it")
        self.node.watch(topic, role)
        node, decoder = self.node, self.decoder

        def on_sample(data: bytes, _stamp_ns: int) -> None:
            node.feed_message(decoder, topic, data)

        self.bus.subscribe(dds_topic, idl_type(type_name, definition), on_sample, reliable=self.reliable)
        log.info("subscribed to %s (%s) as %s", topic, type_name, role)

    def _discover(self) -> None:
        """Subscribe to pending topics whose publishers have appeared, and with ``discover`` to
        new topics the mapping reads; one odd publication is logged, never the end of the node."""
        assert self.graph is not None
        for pub in self.graph.publications():
            if not isinstance(pub.topic_name, str) or not isinstance(pub.type_name, str):
                continue  # a publication that went away
            try:
                self._take(pub)
            except Exception as e:  # noqa: BLE001
                log.warning("%s: not taken: %s", pub.topic_name, e)

    def _take(self, pub: Any) -> None:
        """Subscribe to the publication's topic if it is pending, or new and read by the mapping."""
        from uwbimu_rs.live._graph import ros_type_name

        assert self.graph is not None
        entry = self.pending.get(pub.topic_name)
        required = entry is not None
        if entry is None:
            if not self.discover or pub.topic_name in self._seen or not pub.topic_name.startswith("rt/"):
                return
            self._seen.add(pub.topic_name)
            entry = ("/" + pub.topic_name[3:], None)
        topic, named = entry
        type_name = named or ros_type_name(pub.type_name)
        try:
            definition = _native.ros_definition(type_name, self.msg_paths)
        except ValueError as missing:
            found = self.graph.definition(pub)
            if found is None or (named is not None and found[0] != named):
                self.pending.pop(pub.topic_name, None)
                (log.error if required else log.debug)("%s: %s, and its publisher sends no type information", topic, missing)
                return
            type_name, definition = found
            log.info("%s: learnt %s from its publisher", topic, type_name)
        self.pending.pop(pub.topic_name, None)
        try:
            if required or self.decoder.add_topic(topic, type_name, definition) is not None:
                self._subscribe(topic, type_name, definition, pub.topic_name)
        except ValueError as e:
            (log.error if required else log.warning)("%s (%s): %s", topic, type_name, e)

    def poll(self, timeout_s: float) -> int:
        """Take what the graph delivered (waiting up to ``timeout_s``)."""
        if self.graph is not None:
            self._discover()
        return int(self.bus.spin_once(timeout_s))


def linktrack_records(frame: Mapping[str, Any], anchor_index: Mapping[str, int]) -> list[tuple[Any, ...]]:
    """The records of one LinkTrack frame (a dict of :class:`LinkTrackDecoder`): the module's IMU
    sample and its ranges to the anchors of the mapping (node id as the anchor id), all at the
    module's local time; a ``NodeFrame2`` range carries its first-path and received power (dBm)
    after the tag: ``("range", t, anchor, range, None, fp, rx)``. ``TagFrame0`` distances are
    by anchor slot 0–7 (0 m: no range)."""
    t = frame["local_time_ms"] * 1e-3
    out: list[tuple[Any, ...]] = [("imu", t, frame["accel"], frame["gyro"])]
    if frame["kind"] == "node_frame2":
        for n in frame["nodes"]:
            k = anchor_index.get(str(n["id"]))
            if k is not None:
                out.append(("range", t, k, n["range"], None, n["fp_rssi"], n["rx_rssi"]))
    else:
        for i, d in enumerate(frame["distances"]):
            k = anchor_index.get(str(i))
            if k is not None and d > 0:
                out.append(("range", t, k, d, None))
    return out


def linktrack_frames(imu: Any, ranges: Any, anchor_ids: list[str], *, tag_id: int = 0) -> list[bytes]:
    """The ``NodeFrame2`` frames a LinkTrack tag would send for a run (a simulated module, for
    trials and tests): one per IMU sample (``imu`` (N, 7)), carrying the ranges (``ranges``
    (M, 3), anchor indices into ``anchor_ids``, which must be numbers 0–255) measured since the
    previous sample, all at the sample's time in ms; the inverse of :func:`linktrack_records` up
    to the wire's steps."""
    frames = []
    j = 0
    for row in imu:
        nodes = []
        while j < len(ranges) and ranges[j, 0] <= row[0]:
            nodes.append((int(anchor_ids[int(ranges[j, 1])]), float(ranges[j, 2]), -80.0, -78.0))
            j += 1
        frames.append(_native.encode_linktrack_node_frame2(tag_id, int(round(row[0] * 1000)), row[4:7], row[1:4], nodes))
    return frames


class LinkTrackSource:
    """A LinkTrack serial port (``pyserial``), frames decoded in Rust (:class:`LinkTrackDecoder`):
    each frame's IMU sample and ranges go to the node at the module's clock. Anchor ids in the
    mapping are the LinkTrack node ids (``"0"``, ``"1"``, …)."""

    finished = False

    def __init__(self, port: str, baud: int, anchor_ids: list[str], node: LiveNode) -> None:
        try:
            import serial  # type: ignore[import-untyped]
        except ImportError as e:  # pragma: no cover - depends on the extra
            raise ImportError("a LinkTrack port needs pyserial: pip install 'uwbimu_rs[live]'") from e
        self.port = port
        self.serial = serial.Serial(port, baudrate=baud, timeout=0)
        self.decoder = _native.LinkTrackDecoder()
        self.anchor_index = {a: k for k, a in enumerate(anchor_ids)}
        self.node = node
        self.name = f"linktrack:{port}"
        node.watch(self.name, "linktrack")
        log.info("reading LinkTrack frames from %s at %d baud", port, baud)

    def poll(self, timeout_s: float) -> int:
        """Read what the port has (waiting up to ``timeout_s`` for the first byte)."""
        self.serial.timeout = timeout_s
        data = self.serial.read(max(self.serial.in_waiting, 1))
        if not data:
            return 0
        frames = self.decoder.feed(data)
        for frame in frames:
            self.node.feed(self.name, linktrack_records(frame, self.anchor_index))
        # The decoder's counts (frames, checksum errors, bytes skipped) go into the diagnostics.
        self.node.watch(self.name, "linktrack").extra = {k: v for k, v in self.decoder.counts.items() if k != "bytes_received"}
        return len(frames)



def mcap_messages(path: str, topics: set[str] | None = None) -> Iterator[tuple[Any, Any, Any]]:
    """``(schema, channel, message)`` of an MCAP file in log-time order (the ``mcap`` package)."""
    try:
        from mcap.reader import make_reader
    except ImportError as e:  # pragma: no cover - depends on the extra
        raise ImportError("reading MCAP in Python needs mcap: pip install 'uwbimu_rs[live]'") from e
    with open(path, "rb") as f:
        reader = make_reader(f)
        yield from reader.iter_messages(topics=list(topics) if topics else None, log_time_order=True)


def mcap_summary_schemas(path: str) -> list[tuple[str, str]]:
    """``(name, text)`` of the ``ros2msg`` schemas of an MCAP file (from its summary)."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    if summary is None:
        raise ValueError(f"{path}: no summary section (an unfinished recording?)")
    return [(s.name, s.data.decode()) for s in summary.schemas.values() if s.encoding == "ros2msg"]


class McapSource:
    """A recorded MCAP played in real time (``rate`` × its pace; 0: as fast as it goes), through
    the mapping, as a trial of the node without a robot."""

    finished = False

    def __init__(self, path: str, decoder: Any, node: LiveNode, *, rate: float = 1.0) -> None:
        self.decoder = decoder
        self.node = node
        self.rate = rate
        self.roles: dict[str, str | None] = {}
        self._messages = mcap_messages(path)
        self._next: tuple[Any, Any, Any] | None = None
        self._t0: tuple[float, int] | None = None
        log.info("playing %s at %g× its pace", path, rate)

    def _role(self, schema: Any, channel: Any) -> str | None:
        if channel.topic not in self.roles:
            text = schema.data.decode() if schema is not None else ""
            name = schema.name if schema is not None else ""
            role = self.roles[channel.topic] = self.decoder.add_topic(channel.topic, name, text, channel.message_encoding)
            if role is not None:
                self.node.watch(channel.topic, role)
        return self.roles[channel.topic]

    def poll(self, timeout_s: float) -> int:
        """Feed every message due by now; wait up to ``timeout_s`` for the next one."""
        n = 0
        deadline = time.monotonic() + timeout_s
        while True:
            if self._next is None:
                self._next = next(self._messages, None)
                if self._next is None:
                    self.finished = True
                    return n
            schema, channel, message = self._next
            now = time.monotonic()
            if self._t0 is None:
                self._t0 = (now, message.log_time)
            due = self._t0[0] + (message.log_time - self._t0[1]) * 1e-9 / self.rate if self.rate > 0 else now
            if due > now:
                if due > deadline:
                    time.sleep(max(deadline - now, 0.0))
                    return n
                time.sleep(due - now)
            self._next = None
            if self._role(schema, channel) is not None:
                self.node.feed_message(self.decoder, channel.topic, message.data, log_time_s=message.log_time * 1e-9)
                n += 1
