"""The ``uwbimu-play`` console script: publish a recorded MCAP's ROS 2 messages over DDS at their
recorded pace or faster, as ``ros2 bag play`` would (docs/live.md). Each CDR channel with a
``ros2msg`` schema becomes the DDS topic ROS 2 gives it (``/imu`` → ``rt/imu``), its type built
from the schema the file carries; payloads are sent as recorded. The JSON ranges our recordings
write (``uwbimu.UwbRange``) are sent as ``uwbimu_msgs/msg/UwbRange``. ``--export-msgs DIR`` writes
those schemas as ``.msg`` files in a ROS 2 workspace layout, for the node's ``live.msg_paths``.

Exit status: 0 when the file was played (or a signal stopped it), 2 for a bad command line or
file.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import time
from pathlib import Path
from types import FrameType
from collections.abc import Callable
from typing import Any

from uwbimu_rs import _native

log = logging.getLogger("uwbimu.play")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="uwbimu-play",
        description="Publish a recorded MCAP's ROS 2 messages over DDS at their recorded pace or faster, as "
        "ros2 bag play would; our JSON ranges go out as uwbimu_msgs/msg/UwbRange (docs/live.md).",
    )
    p.add_argument("file", help="MCAP recording with ROS 2 (CDR) messages")
    p.add_argument("--rate", type=float, default=1.0, help="pace (2 = twice as fast; 0 = as fast as possible)")
    p.add_argument("--topics", nargs="+", help="play only these topics")
    p.add_argument("--domain-id", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "0")), help="DDS domain")
    p.add_argument("--loopback", action="store_true", help="DDS on 127.0.0.1 only, no multicast")
    p.add_argument(
        "--wait-subscribers", type=float, default=0.0, metavar="S", help="wait up to S s for a reader of every topic"
    )
    p.add_argument("--start-delay", type=float, default=0.0, metavar="S", help="wait S s after discovery before playing")
    p.add_argument("--export-msgs", metavar="DIR", help="write the file's message definitions as DIR/<pkg>/msg/<Type>.msg and exit")
    p.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    return p


def export_msgs(path: str, out_dir: str) -> list[Path]:
    """Write every ``ros2msg`` schema of the MCAP file ``path`` (and each dependency section it
    carries) as ``out_dir/<pkg>/msg/<Type>.msg``; returns the files written."""
    from uwbimu_rs.live._sources import mcap_summary_schemas

    written: list[Path] = []
    for name, text in mcap_summary_schemas(path):
        sections = [(name, [])]  # type: list[tuple[str, list[str]]]
        for line in text.splitlines():
            if line.strip() and set(line.strip()) == {"="}:
                sections.append(("", []))
            elif not sections[-1][0] and line.startswith("MSG:"):
                sections[-1] = (line[4:].strip(), [])
            else:
                sections[-1][1].append(line)
        for type_name, lines in sections:
            if not type_name:
                continue
            parts = type_name.split("/")
            pkg, short = parts[0], parts[-1]
            target = Path(out_dir) / pkg / "msg" / f"{short}.msg"
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text("\n".join(lines).strip("\n") + "\n")
            written.append(target)
    return written


class _Stop:
    def __init__(self) -> None:
        self.stopped = False
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, self)

    def __call__(self, _signum: int, _frame: FrameType | None) -> None:
        self.stopped = True


def run(argv: list[str]) -> int:
    """Play with the command line ``argv`` (without the program name); returns the exit status."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s uwbimu-play: %(message)s", stream=sys.stderr)
    if not Path(args.file).is_file():
        print(f"uwbimu-play: {args.file}: no such file", file=sys.stderr)
        return 2
    try:
        if args.export_msgs:
            files = export_msgs(args.file, args.export_msgs)
            log.info("wrote %d message definitions under %s", len(files), args.export_msgs)
            return 0
        return _play(args)
    except (ValueError, OSError, ImportError) as e:
        print(f"uwbimu-play: {e}", file=sys.stderr)
        return 2


def _play(args: argparse.Namespace) -> int:
    from uwbimu_rs.live._dds import DdsBus, idl_type, use_loopback_if_unset
    from uwbimu_rs.live._sources import mcap_messages, mcap_summary_schemas

    if args.loopback:
        use_loopback_if_unset()
    stop = _Stop()
    bus = DdsBus(args.domain_id)
    wanted = set(args.topics) if args.topics else None
    schemas = dict(mcap_summary_schemas(args.file))
    writers: dict[str, Any] = {}
    converters: dict[str, Callable[[bytes], bytes]] = {}
    for topic, (name, encoding) in _channels(args.file).items():
        if wanted is not None and topic not in wanted:
            continue
        if encoding == "json" and name == _native.UWB_RANGE_JSON:
            # The recordings' JSON ranges travel as our CDR range message.
            converters[topic] = _native.ros_uwb_range_from_json
            name, schemas[name] = _native.UWB_RANGE_MSG, _native.ros_definition(_native.UWB_RANGE_MSG)
        elif encoding != "cdr" or name not in schemas:
            log.warning("%s: %s messages (%s) are not ROS 2 CDR: not played", topic, encoding, name or "no schema")
            continue
        writers[topic] = bus.publisher("rt/" + topic.lstrip("/"), idl_type(name, schemas[name]), depth=1000)
        log.info("publishing %s (%s)", topic, name)
    if args.wait_subscribers > 0:
        deadline = time.monotonic() + args.wait_subscribers
        while time.monotonic() < deadline and not all(bus.matched_subscribers(w) for w in writers.values()):
            time.sleep(0.05)
        waiting = [t for t, w in writers.items() if not bus.matched_subscribers(w)]
        if waiting:
            log.warning("no reader yet for %s", ", ".join(waiting))
    time.sleep(args.start_delay)
    t0: tuple[float, int] | None = None
    n = 0
    for _, channel, message in mcap_messages(args.file, wanted):
        if stop.stopped:
            break
        write = writers.get(channel.topic)
        if write is None:
            continue
        if t0 is None:
            t0 = (time.monotonic(), message.log_time)
        if args.rate > 0:
            due = t0[0] + (message.log_time - t0[1]) * 1e-9 / args.rate
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        convert = converters.get(channel.topic)
        write(convert(message.data) if convert else message.data)
        n += 1
    log.info("played %d messages%s", n, " (stopped)" if stop.stopped else "")
    time.sleep(0.2)  # let what is queued reach best-effort readers
    late = [t for t, w in writers.items() if not bus.delivered(w, 30.0)]
    if late:
        log.warning("%s: not acknowledged by every reliable reader within 30 s", ", ".join(late))
    bus.close()
    return 0


def _channels(path: str) -> dict[str, tuple[str, str]]:
    """Topic → (schema name, message encoding) of an MCAP file's channels."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    if summary is None:
        raise ValueError(f"{path}: no summary section (an unfinished recording?)")
    out = {}
    for c in summary.channels.values():
        s = summary.schemas.get(c.schema_id)
        out[c.topic] = (s.name if s else "", c.message_encoding)
    return out


def main() -> None:
    """Run ``uwbimu-play`` with the process's arguments and exit with its status."""
    sys.exit(run(sys.argv[1:]))


if __name__ == "__main__":
    main()
