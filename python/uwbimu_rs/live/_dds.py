"""ROS 2 over DDS without ROS 2: Cyclone DDS (the ``live`` extra) with ROS 2's names and payloads.

A ROS 2 topic ``/imu`` of type ``sensor_msgs/msg/Imu`` is the DDS topic ``rt/imu`` of type
``sensor_msgs::msg::dds_::Imu_``, with XCDR1 payloads. The DDS types are built from the ``.msg``
definitions (:func:`uwbimu_rs._native.ros_fields`); payloads cross as bytes in both directions,
so the decoding (the mapping) and the encoding (the estimate) stay in Rust: a reader hands the
raw CDR of each sample to the caller, a writer sends the bytes it is given.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from uwbimu_rs import _native


def _import_cyclonedds() -> Any:
    try:
        import cyclonedds  # noqa: F401
        import cyclonedds.idl
    except ImportError as e:  # pragma: no cover - depends on the extra
        raise ImportError("ROS 2 over DDS needs Cyclone DDS: pip install 'uwbimu_rs[live]'") from e
    return cyclonedds


_PRIMITIVES = {
    "bool": "bool",
    "int8": "int8",
    "uint8": "uint8",
    "int16": "int16",
    "uint16": "uint16",
    "int32": "int32",
    "uint32": "uint32",
    "int64": "int64",
    "uint64": "uint64",
    "float32": "float32",
    "float64": "float64",
    "string": "str",
    "wstring": "str",
}


def idl_type(type_name: str, definition: str) -> type:
    """The Cyclone DDS type of the ROS 2 type ``type_name`` with its full ``.msg`` definition
    (nested types built as its dependencies); its DDS name is the one ROS 2 gives it."""
    _import_cyclonedds()
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.idl import types as idl_types

    t: Any = idl_types  # its array and sequence are subscripted at run time

    layout = {name: fields for name, fields in _native.ros_fields(type_name, definition)}
    built: dict[str, type] = {}

    def element(name: str) -> Any:
        if name in _PRIMITIVES:
            p = _PRIMITIVES[name]
            return {"bool": bool, "str": str}.get(p) or getattr(t, p)
        return build(name)

    def build(name: str) -> type:
        if name in built:
            return built[name]
        fields: dict[str, Any] = {}
        for field, elem, array, n in layout[name]:
            ty = element(elem)
            if array == "fixed":
                ty = t.array[ty, n]
            elif array == "sequence":
                ty = t.sequence[ty]
            elif array == "bounded":
                ty = t.sequence[ty, n]
            fields[field] = ty
        pkg, _, short = name.partition("/")
        dds_name = f"{pkg}::msg::dds_::{short}_"
        built[name] = make_idl_struct(short + "_", dds_name, fields)
        return built[name]

    root = next(iter(layout))
    return build(root)


def _qos(reliable: bool, depth: int) -> Any:
    """Reliable or best effort, keeping the last ``depth`` samples (0: all of them)."""
    from cyclonedds.core import Policy
    from cyclonedds.qos import Qos
    from cyclonedds.util import duration

    kind = Policy.Reliability.Reliable(duration(milliseconds=100)) if reliable else Policy.Reliability.BestEffort
    return Qos(kind, Policy.History.KeepLast(depth) if depth > 0 else Policy.History.KeepAll)


class DdsBus:
    """One DDS participant in ``domain_id`` with raw-payload readers and writers.

    ``CYCLONEDDS_URI`` configures Cyclone as usual (interfaces, peers, multicast); the ROS 2
    graph must be on the same domain (``ROS_DOMAIN_ID``).
    """

    def __init__(self, domain_id: int = 0) -> None:
        _import_cyclonedds()
        from cyclonedds.core import WaitSet
        from cyclonedds.domain import DomainParticipant

        self.participant = DomainParticipant(domain_id)
        self.waitset = WaitSet(self.participant)
        self._readers: list[tuple[Any, Callable[[bytes, int], None], Any]] = []
        self._topics: dict[str, Any] = {}

    def _topic(self, dds_topic: str, idl: type) -> Any:
        from cyclonedds.topic import Topic

        if dds_topic not in self._topics:
            self._topics[dds_topic] = Topic(self.participant, dds_topic, idl)
        return self._topics[dds_topic]

    def subscribe(
        self, dds_topic: str, idl: type, on_sample: Callable[[bytes, int], None], *, depth: int = 1000, reliable: bool = False
    ) -> None:
        """Call ``on_sample(payload, source_timestamp_ns)`` for each sample of ``dds_topic``
        from :meth:`spin_once`. The reader is best effort (keep last ``depth``), so it matches
        both reliable publishers and the best-effort ones of ROS 2's sensor-data profile; with
        ``reliable`` it is reliable and keeps every sample until taken (``live.reliable_inputs``:
        nothing a reliable publisher sent is lost, best-effort publishers are not matched)."""
        from cyclonedds.core import ReadCondition, SampleState, ViewState, InstanceState
        from cyclonedds.sub import DataReader

        reader = DataReader(self.participant, self._topic(dds_topic, idl), qos=_qos(reliable, 0 if reliable else depth))
        cond = ReadCondition(reader, SampleState.Any | ViewState.Any | InstanceState.Any)
        self.waitset.attach(cond)
        self._readers.append((reader, on_sample, cond))

    def publisher(self, dds_topic: str, idl: type, *, depth: int = 100) -> Callable[[bytes], None]:
        """A function that publishes a payload (XCDR1 with its header) on ``dds_topic``
        (reliable, keep last ``depth``: it reaches reliable and best-effort readers)."""
        from cyclonedds._clayer import ddspy_write  # type: ignore[import-not-found]
        from cyclonedds.pub import DataWriter

        writer = DataWriter(self.participant, self._topic(dds_topic, idl), qos=_qos(True, depth))

        def write(payload: bytes) -> None:
            pad = -len(payload) % 4
            ret = ddspy_write(writer._ref, payload + b"\0" * pad)
            if ret < 0:
                raise OSError(f"DDS write on {dds_topic} failed ({ret})")

        write.writer = writer  # type: ignore[attr-defined]
        return write

    def spin_once(self, timeout_s: float) -> int:
        """Wait up to ``timeout_s`` for samples and hand each to its callback, across readers in
        the order they were written (source timestamp; each reader's own order kept); returns how
        many. Reader by reader, a backlog (the node busy deciding its start) gave one topic's
        seconds before another's, and the later topic's data fell behind the reorder window."""
        from cyclonedds._clayer import ddspy_take  # type: ignore[import-not-found]
        from cyclonedds.core import InstanceState, SampleState, ViewState
        from cyclonedds.util import duration

        self.waitset.wait(duration(microseconds=max(int(timeout_s * 1e6), 0)))
        mask = SampleState.Any | ViewState.Any | InstanceState.Any
        taken: list[tuple[int, int, Callable[[bytes, int], None], bytes]] = []
        for reader, on_sample, _ in self._readers:
            while True:
                got = ddspy_take(reader._ref, mask, 256)
                if isinstance(got, int):
                    raise OSError(f"DDS take failed ({got})")
                if not got:
                    break
                for data, info in got:
                    if info.valid_data:
                        taken.append((int(info.source_timestamp), len(taken), on_sample, bytes(data)))
        taken.sort(key=lambda s: (s[0], s[1]))
        for stamp, _, on_sample, data in taken:
            on_sample(data, stamp)
        return len(taken)

    def delivered(self, write: Callable[[bytes], None], timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` until every reliable reader acknowledged what a publisher of
        :meth:`publisher` wrote; whether they all did (best-effort readers acknowledge nothing)."""
        from cyclonedds.util import duration

        return bool(write.writer.wait_for_acks(duration(microseconds=int(timeout_s * 1e6))))  # type: ignore[attr-defined]

    def matched_subscribers(self, write: Callable[[bytes], None]) -> int:
        """How many readers a publisher of :meth:`publisher` reaches."""
        return int(write.writer.get_publication_matched_status().current_count)  # type: ignore[attr-defined]

    def close(self) -> None:
        """Leave the domain."""
        self._readers.clear()
        self._topics.clear()
        del self.waitset
        del self.participant


def loopback_config() -> str:
    """A ``CYCLONEDDS_URI`` for tests and trials on one machine: loopback only, no multicast."""
    return (
        "<CycloneDDS><Domain Id='any'><General><Interfaces><NetworkInterface address='127.0.0.1'/></Interfaces>"
        "<AllowMulticast>false</AllowMulticast></General><Discovery><Peers><Peer address='127.0.0.1'/></Peers>"
        "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>50</MaxAutoParticipantIndex>"
        "</Discovery></Domain></CycloneDDS>"
    )


def use_loopback_if_unset() -> None:
    """Point Cyclone at loopback unless the user configured it (``CYCLONEDDS_URI``)."""
    os.environ.setdefault("CYCLONEDDS_URI", loopback_config())
