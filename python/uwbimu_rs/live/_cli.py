"""The ``uwbimu-live`` console script: the localisation node (docs/live.md).

Exit status: 0 when the input ended or a signal (Ctrl-C, SIGTERM) stopped it — outputs closed
either way; 2 for a bad command line or configuration (one line on stderr); 1 when the node
failed while running.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import sys
import time
from types import FrameType
from typing import Any

from uwbimu_rs import _native

log = logging.getLogger("uwbimu.live")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="uwbimu-live",
        description="Localise a robot live from IMU and UWB: ROS 2 topics over DDS, a LinkTrack serial port, "
        "or a recorded MCAP played in real time; publishes the pose over DDS (ROS 2), to a Foxglove live view "
        "and/or to an MCAP file. Settings: the replay file (--config) with its [mapping] and [live] tables.",
    )
    p.add_argument("--config", help="replay TOML: method, [config], [initial], [mapping] (topics, anchors), [live]")
    p.add_argument("--method", help="streaming method (default: the file's, else best)")
    p.add_argument("--mapping", help="mapping as JSON, merged into the file's [mapping]")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--linktrack", metavar="PORT", help="read a Nooploop LinkTrack serial port (NodeFrame2/TagFrame0)")
    src.add_argument("--mcap", metavar="FILE", help="play a recorded MCAP in real time instead of listening")
    p.add_argument("--rate", type=float, default=1.0, help="pace of --mcap (2 = twice as fast; 0 = as fast as it goes)")
    p.add_argument("--no-ros", action="store_true", help="do not publish over DDS")
    p.add_argument("--foxglove", metavar="[HOST:]PORT", nargs="?", const="127.0.0.1:8765", help="serve a Foxglove live view")
    p.add_argument("--out", metavar="FILE.mcap", help="also write every step to an MCAP file (as uwbimu-replay --out)")
    p.add_argument("--domain-id", type=int, help="DDS domain (default: [live] domain_id, else 0)")
    p.add_argument("--loopback", action="store_true", help="DDS on 127.0.0.1 only, no multicast (trials on one machine)")
    p.add_argument("--choose-after", type=float, metavar="S", help="seconds of data before the model choice (0: none)")
    p.add_argument("--lag", type=float, metavar="S", help="also publish the pose smoothed over S seconds (fixed lag; [live] lag_s)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (wall clock)")
    p.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    return p


class _Stop:
    """Set by SIGINT/SIGTERM: the loop ends and the outputs are closed."""

    def __init__(self) -> None:
        self.signal: int | None = None
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, self)

    def __call__(self, signum: int, _frame: FrameType | None) -> None:
        self.signal = signum


def _foxglove_address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    return (host or "127.0.0.1", int(port))


def run(argv: list[str]) -> int:
    """Run the node with the command line ``argv`` (without the program name); returns the exit
    status."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s uwbimu-live: %(message)s", stream=sys.stderr)
    from uwbimu_rs.live._node import LiveNode
    from uwbimu_rs.live._sinks import FoxgloveSink, McapSink, RosSink
    from uwbimu_rs.live._sources import DdsSource, LinkTrackSource, McapSource

    stop = _Stop()
    try:
        setup = _native.live_setup(args.config, mapping=args.mapping)
        live = setup["live"]
        if args.choose_after is not None:
            live["choose_after_s"] = args.choose_after
        if args.domain_id is not None:
            live["domain_id"] = args.domain_id
        if args.lag is not None:
            if not (math.isfinite(args.lag) and args.lag >= 0):
                raise ValueError(f"--lag {args.lag}: must be finite and >= 0 s (the [live] lag_s)")
            live["lag_s"] = args.lag
        decoder = _native.MessageDecoder(args.config, mapping=args.mapping, recording=args.mcap)
        subscriptions = None
        if not args.linktrack and not args.mcap:
            subscriptions = _native.live_subscriptions(args.config, mapping=args.mapping)
    except (ValueError, OSError) as e:
        print(f"uwbimu-live: {e}", file=sys.stderr)
        return 2
    bus = None
    sinks: list[Any] = []
    node = None
    try:
        if args.loopback:
            from uwbimu_rs.live._dds import use_loopback_if_unset

            use_loopback_if_unset()
        if subscriptions is not None or not args.no_ros:
            from uwbimu_rs.live._dds import DdsBus

            bus = DdsBus(int(live["domain_id"]))
        if not args.no_ros:
            sinks.append(RosSink(bus, setup))
        if args.foxglove:
            host, port = _foxglove_address(args.foxglove)
            sinks.append(FoxgloveSink(setup, host=host, port=port))
        if args.out:
            sinks.append(McapSink(args.out))
        node = LiveNode(setup, decoder.anchors, method=args.method, sinks=sinks)
        if args.linktrack:
            source: Any = LinkTrackSource(args.linktrack, int(live["linktrack_baud"]), decoder.anchor_ids, node)
        elif args.mcap:
            source = McapSource(args.mcap, decoder, node, rate=args.rate)
        else:
            assert subscriptions is not None
            source = DdsSource(
                bus, subscriptions["topics"], decoder, node, live["msg_paths"],
                discover=subscriptions["discover"], reliable=live["reliable_inputs"],
            )
    except (ValueError, OSError, ImportError) as e:
        print(f"uwbimu-live: {e}", file=sys.stderr)
        for s in sinks:
            s.close()
        return 2
    started, cpu0 = time.monotonic(), time.process_time()
    status = 0
    try:
        while stop.signal is None and not source.finished:
            source.poll(0.05)
            node.tick()
            if args.duration is not None and time.monotonic() - started >= args.duration:
                break
    except Exception as e:  # noqa: BLE001 - the node reports and closes its outputs on any failure
        log.error("stopped by an error: %s", e)
        status = 1
    finally:
        wall, cpu = time.monotonic() - started, time.process_time() - cpu0
        why = {int(signal.SIGINT): "Ctrl-C", int(signal.SIGTERM): "SIGTERM"}.get(stop.signal or 0, "end of input")
        node.close()
        if bus is not None:
            bus.close()
        lat = node.latency_ms()
        log.info(
            "stopped (%s): %d poses published; latency p50 %.1f ms, p99 %.1f ms; CPU %.2f s over %.1f s (%.0f %%)",
            why,
            node.poses_published,
            lat["p50"],
            lat["p99"],
            cpu,
            wall,
            100 * cpu / max(wall, 1e-9),
        )
        for status_line in node.statuses():
            log.info("%s [%s] %s: %s", status_line["name"], status_line["hardware_id"], status_line["message"], status_line["values"])
    return status


def main() -> None:
    """Run ``uwbimu-live`` with the process's arguments and exit with its status."""
    sys.exit(run(sys.argv[1:]))
