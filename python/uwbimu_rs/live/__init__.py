"""The live node (``uwbimu-live``) and the MCAP player (``uwbimu-play``): docs/live.md.

Importing :mod:`uwbimu_rs` does not import this package, and this package imports its optional
dependencies (the ``live`` extra: ``cyclonedds``, ``foxglove-sdk``, ``pyserial``, ``mcap``) only
when a transport that needs them starts.

- :class:`LiveNode`: the estimator loop without transport (records in, poses out);
  :func:`apply_record` gives one decoded record to a streaming filter.
- :class:`DdsBus`: ROS 2 topics over Cyclone DDS with raw CDR payloads.
- Sources: :class:`DdsSource`, :class:`LinkTrackSource`, :class:`McapSource`.
- Sinks: :class:`RosSink`, :class:`FoxgloveSink`, :class:`McapSink`.
"""

from __future__ import annotations

from uwbimu_rs.live._dds import DdsBus, idl_type, loopback_config
from uwbimu_rs.live._node import LiveNode, Pose, RangeUpdate, Sink, apply_record
from uwbimu_rs.live._sinks import FoxgloveSink, McapSink, RosSink
from uwbimu_rs.live._sources import DdsSource, LinkTrackSource, McapSource, linktrack_frames, linktrack_records

__all__ = [
    "DdsBus",
    "DdsSource",
    "FoxgloveSink",
    "LinkTrackSource",
    "LiveNode",
    "McapSink",
    "McapSource",
    "Pose",
    "RangeUpdate",
    "RosSink",
    "Sink",
    "apply_record",
    "idl_type",
    "linktrack_frames",
    "linktrack_records",
    "loopback_config",
]
