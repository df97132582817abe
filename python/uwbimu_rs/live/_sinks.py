"""Where the live node's estimate goes: ROS 2 topics over DDS, a Foxglove live view, an MCAP
file as the replay writes it. Each is a :class:`uwbimu_rs.live._node.Sink`; the payloads are made
in Rust (``ros_pose_messages``, ``ros_diagnostics_message``, ``TrajectoryWriter``)."""

from __future__ import annotations

import logging
from collections import deque
from typing import Any

import numpy as np

from uwbimu_rs import _native
from uwbimu_rs.live._node import Pose, RangeUpdate

log = logging.getLogger("uwbimu.live")


class _NoSteps:
    """Defaults for the sink methods a sink does not use."""

    def steps(self, rows: dict[str, np.ndarray]) -> None:
        """Ignored."""

    def pose(self, pose: Pose) -> None:
        """Ignored."""

    def smoothed_pose(self, pose: Pose) -> None:
        """Ignored."""

    def diagnostics(self, t: float, statuses: list[dict[str, Any]]) -> None:
        """Ignored."""

    def range_update(self, u: RangeUpdate) -> None:
        """Ignored."""

    def close(self) -> None:
        """Nothing to close."""


class RosSink(_NoSteps):
    """``geometry_msgs/PoseWithCovarianceStamped``, ``nav_msgs/Odometry`` and
    ``diagnostic_msgs/DiagnosticArray`` on the topics of ``[live]``, over a :class:`DdsBus`;
    with ``live.lag_s`` also the fixed-lag smoothed ``PoseWithCovarianceStamped`` on
    ``live.smoothed_pose_topic``."""

    def __init__(self, bus: Any, setup: dict[str, Any]) -> None:
        from uwbimu_rs.live._dds import idl_type

        live = setup["live"]
        self.frames = {"parent": live["map_frame"], "child": live["base_frame"]}
        pose, odom, diag, smoothed = setup["outputs"]
        self._pose = bus.publisher(pose[3], idl_type(pose[1], pose[2]))
        self._odom = bus.publisher(odom[3], idl_type(odom[1], odom[2]))
        self._diag = bus.publisher(diag[3], idl_type(diag[1], diag[2]))
        self._smoothed = None
        if live.get("lag_s") is not None:
            self._smoothed = bus.publisher(smoothed[3], idl_type(smoothed[1], smoothed[2]))
            log.info("publishing the pose smoothed over %g s on %s", live["lag_s"], smoothed[0])
        log.info("publishing %s, %s and %s (frame %s → %s)", pose[0], odom[0], diag[0], live["map_frame"], live["base_frame"])

    def pose(self, pose: Pose) -> None:
        """Publish the pose and the odometry."""
        p, o = _native.ros_pose_messages(
            pose.t, pose.position, pose.velocity, pose.quaternion, pose.angular_rate, pose.covariance, **self.frames
        )
        self._pose(p)
        self._odom(o)

    def smoothed_pose(self, pose: Pose) -> None:
        """Publish the fixed-lag smoothed pose (its odometry is not: the rate is not smoothed)."""
        if self._smoothed is None:
            return
        p, _ = _native.ros_pose_messages(
            pose.t, pose.position, pose.velocity, pose.quaternion, pose.angular_rate, pose.covariance, **self.frames
        )
        self._smoothed(p)

    def diagnostics(self, t: float, statuses: list[dict[str, Any]]) -> None:
        """Publish the diagnostics."""
        self._diag(_native.ros_diagnostics_message(t, statuses))


def _stamp(t: float) -> Any:
    import foxglove.messages as fm

    sec = int(np.floor(t))
    return fm.Timestamp(sec=max(sec, 0), nsec=int(round((t - sec) * 1e9)) % 1_000_000_000)


def _fox_pose(position: np.ndarray, q: np.ndarray) -> Any:
    import foxglove.messages as fm

    return fm.Pose(
        position=fm.Vector3(x=float(position[0]), y=float(position[1]), z=float(position[2])),
        orientation=fm.Quaternion(x=float(q[1]), y=float(q[2]), z=float(q[3]), w=float(q[0])),
    )


class FoxgloveSink(_NoSteps):
    """A Foxglove WebSocket server (``foxglove-sdk``): ``/uwbimu/pose`` (PoseInFrame),
    ``/uwbimu/path`` (PosesInFrame, the last ``path_length`` poses 0.2 s apart), ``/tf``
    (FrameTransform map → base_link), ``/uwbimu/nis`` (per range update: anchor, NIS,
    accepted, and the range's first-path and received power when the source gives them) and,
    with ``live.lag_s``, ``/uwbimu/pose_smoothed`` (PoseInFrame, the fixed-lag smoothed pose)."""

    PATH_SPACING_S = 0.2

    def __init__(self, setup: dict[str, Any], *, host: str = "127.0.0.1", port: int = 8765, path_length: int = 3000) -> None:
        try:
            import foxglove
            import foxglove.channels as fc
        except ImportError as e:  # pragma: no cover - depends on the extra
            raise ImportError("the Foxglove view needs foxglove-sdk: pip install 'uwbimu_rs[live]'") from e
        live = setup["live"]
        self.frame = live["map_frame"]
        self.child = live["base_frame"]
        self.server = foxglove.start_server(name="uwbimu-live", host=host, port=port)
        self._pose = fc.PoseInFrameChannel("/uwbimu/pose")
        self._path = fc.PosesInFrameChannel("/uwbimu/path")
        self._tf = fc.FrameTransformChannel("/tf")
        nis_schema = {
            "type": "object",
            "properties": {
                "t": {"type": "number"},
                "anchor": {"type": "integer"},
                "nis": {"type": "number"},
                "accepted": {"type": "boolean"},
                "fp_power_dbm": {"type": ["number", "null"]},
                "rx_power_dbm": {"type": ["number", "null"]},
                "power_gap_db": {"type": ["number", "null"]},
            },
        }
        self._nis = foxglove.Channel("/uwbimu/nis", schema=nis_schema)
        self._smoothed = fc.PoseInFrameChannel("/uwbimu/pose_smoothed") if live.get("lag_s") is not None else None
        self._path_poses: deque[Any] = deque(maxlen=path_length)
        self._last_path_t = -np.inf
        log.info("Foxglove live view on ws://%s:%d (open it in Foxglove: Open connection)", host, self.server.port)

    def pose(self, pose: Pose) -> None:
        """Log the pose, the transform and (every 0.2 s) the path."""
        import foxglove.messages as fm

        stamp = _stamp(pose.t)
        fp = _fox_pose(pose.position, pose.quaternion)
        self._pose.log(fm.PoseInFrame(timestamp=stamp, frame_id=self.frame, pose=fp))
        q = pose.quaternion
        self._tf.log(
            fm.FrameTransform(
                timestamp=stamp,
                parent_frame_id=self.frame,
                child_frame_id=self.child,
                translation=fm.Vector3(x=float(pose.position[0]), y=float(pose.position[1]), z=float(pose.position[2])),
                rotation=fm.Quaternion(x=float(q[1]), y=float(q[2]), z=float(q[3]), w=float(q[0])),
            )
        )
        if pose.t - self._last_path_t >= self.PATH_SPACING_S:
            self._last_path_t = pose.t
            self._path_poses.append(fp)
            self._path.log(fm.PosesInFrame(timestamp=stamp, frame_id=self.frame, poses=list(self._path_poses)))

    def smoothed_pose(self, pose: Pose) -> None:
        """Log the fixed-lag smoothed pose (with ``live.lag_s``)."""
        import foxglove.messages as fm

        if self._smoothed is not None:
            fp = _fox_pose(pose.position, pose.quaternion)
            self._smoothed.log(fm.PoseInFrame(timestamp=_stamp(pose.t), frame_id=self.frame, pose=fp))

    def range_update(self, u: RangeUpdate) -> None:
        """Log one range update: NIS, accepted, and the signal powers when known."""
        gap = None if u.fp_power_dbm is None or u.rx_power_dbm is None else u.rx_power_dbm - u.fp_power_dbm
        self._nis.log(
            {
                "t": u.t,
                "anchor": u.anchor,
                "nis": u.nis,
                "accepted": u.accepted,
                "fp_power_dbm": u.fp_power_dbm,
                "rx_power_dbm": u.rx_power_dbm,
                "power_gap_db": gap,
            }
        )

    def close(self) -> None:
        """Stop the server."""
        self.server.stop()


class McapSink(_NoSteps):
    """Every step to an MCAP file with the replay's Foxglove channels (``--out`` of
    ``uwbimu-replay``); closed with its summary when the node stops."""

    def __init__(self, path: str) -> None:
        self.path = path
        self._writer = _native.TrajectoryWriter(path)
        log.info("writing the trajectory to %s", path)

    def steps(self, rows: dict[str, np.ndarray]) -> None:
        """Write each step's pose."""
        pos = np.column_stack([rows["x"], rows["y"], rows["z"]])
        quat = np.column_stack([rows["qw"], rows["qx"], rows["qy"], rows["qz"]])
        for t, p, q in zip(rows["t"], pos, quat):
            self._writer.push(float(t), p, q)

    def close(self) -> None:
        """Write the summary and close the file."""
        self._writer.close()
        log.info("closed %s", self.path)
