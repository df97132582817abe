"""End-to-end figures of the live node (docs/live.md): a recording played over DDS on loopback
(``uwbimu-play`` → ``uwbimu-live``) and a simulated LinkTrack module through a pseudo-terminal,
at the recording's pace. For each run: the steps the node wrote against the forward replay of the
same input (largest position difference), the latency from a message's arrival at the node to
the first pose that includes it (p50, p99, max; the node measures it), and the CPU the node used
(its process time over its wall time, % of one core).

    python benches/live_latency.py                     # isas-walk1 (when ../shared has it) and a simulated walk
    python benches/live_latency.py --rate 10 --windows 0.1 --no-isas   # a quick look (10× the pace)
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import tty
from pathlib import Path

import numpy as np

import uwbimu_rs
from uwbimu_rs import sim
from uwbimu_rs.live import apply_record, linktrack_frames, linktrack_records, loopback_config

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
STATS = re.compile(r"latency p50 ([\d.na]+) ms, p99 ([\d.na]+) ms; CPU ([\d.]+) s over ([\d.]+) s")
MAX = re.compile(r"'latency_max_ms': ([\d.na]+)")
LATE = re.compile(r"'late_dropped': (\d+)")


def node_figures(err: str) -> tuple[float, float, float, float, int]:
    """p50, p99, max latency (ms), CPU (% of one core) and the inputs dropped as later than the
    reorder window, from the node's closing log lines."""
    m, mx, late = STATS.search(err), MAX.search(err), LATE.search(err)
    if m is None or mx is None or late is None:
        raise RuntimeError(f"no figures in the node's log:\n{err[-2000:]}")
    return float(m[1]), float(m[2]), float(mx[1]), 100 * float(m[3]) / float(m[4]), int(late[1])


def written_steps(path: Path) -> np.ndarray:
    """t, x, y, z of every pose in the node's MCAP output."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        poses = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/uwbimu/pose"])]
    return np.array(
        [(p["timestamp"]["sec"] + p["timestamp"]["nsec"] * 1e-9, *(p["pose"]["position"][k] for k in "xyz")) for p in poses]
    )


def largest_difference(live: np.ndarray, t: np.ndarray, ref: np.ndarray) -> float:
    """Largest position difference of the live steps from the reference steps of the same time."""
    nearest = np.abs(t[None, :] - live[:, :1]).argmin(axis=1)
    if np.abs(t[nearest] - live[:, 0]).max() > 1e-6:
        raise RuntimeError("a live step has no reference step at its time")
    return float(np.abs(live[:, 1:] - ref[nearest]).max())


def over_dds(mcap: Path, cfg: Path, rate: float, topics: list[str] | None, work: Path, domain: int) -> tuple[int, float, tuple]:
    env = {**os.environ, "CYCLONEDDS_URI": loopback_config()}
    out = work / f"live-{domain}.mcap"
    node = subprocess.Popen(
        [PY, "-m", "uwbimu_rs.live", "--config", str(cfg), "--out", str(out), "--domain-id", str(domain), "--no-ros"],
        env=env, stderr=subprocess.PIPE, text=True,
    )
    play = [PY, "-m", "uwbimu_rs.live._player", str(mcap), "--rate", str(rate), "--domain-id", str(domain), "--wait-subscribers", "10"]
    subprocess.run(play + (["--topics", *topics] if topics else []), env=env, check=True, capture_output=True)
    time.sleep(1.0)
    node.send_signal(signal.SIGTERM)
    _, err = node.communicate(timeout=60)
    replay, _ = uwbimu_rs.replay(mcap, config_file=cfg, smooth=False)
    ref = np.column_stack([replay[c].to_numpy() for c in "xyz"])
    live = written_steps(out)
    return len(live), largest_difference(live, replay["t"].to_numpy(), ref), node_figures(err)


def through_a_pty(window: float, rate: float, work: Path) -> tuple[int, float, tuple]:
    run = sim.zoo("handheld_walk", seed=0)
    ids = [str(10 + k) for k in range(len(run.anchors))]
    frames = linktrack_frames(run.imu, run.ranges, ids)
    cfg = work / "linktrack.toml"
    anchors = "\n".join(f'"{i}" = [{a[0]}, {a[1]}, {a[2]}]' for i, a in zip(ids, run.anchors))
    cfg.write_text(f"[mapping]\nreorder_window_s = {window}\n[mapping.anchors.positions]\n{anchors}\n[live]\nchoose_after_s = 0\n")
    master, slave = os.openpty()
    tty.setraw(slave)
    out = work / "linktrack.mcap"
    node = subprocess.Popen(
        [PY, "-m", "uwbimu_rs.live", "--config", str(cfg), "--linktrack", os.ttyname(slave), "--no-ros", "--out", str(out)],
        stderr=subprocess.PIPE, text=True,
    )
    time.sleep(1.5)
    due = time.monotonic()
    for f, d in zip(frames, np.diff(run.imu[:, 0], prepend=run.imu[0, 0]) / rate):  # at the run's pace
        due += d
        time.sleep(max(due - time.monotonic(), 0.0))
        os.write(master, f)
    time.sleep(1.0)
    node.send_signal(signal.SIGTERM)
    _, err = node.communicate(timeout=60)
    os.close(master)
    os.close(slave)
    ref_filter = uwbimu_rs.Best(run.anchors, reorder_window_s=window)
    index = {a: k for k, a in enumerate(ids)}
    for frame in uwbimu_rs._native.LinkTrackDecoder().feed(b"".join(frames)):
        for r in linktrack_records(frame, index):
            apply_record(ref_filter, r)
    ref_filter.flush()
    steps = ref_filter.steps()
    live = written_steps(out)
    ref = np.column_stack([steps[c].to_numpy() for c in "xyz"])
    return len(live), largest_difference(live, steps["t"].to_numpy(), ref), node_figures(err)


def isas_config(isas: Path, work: Path, window: float) -> Path:
    msgs = work / "msgs"
    subprocess.run([PY, "-m", "uwbimu_rs.live._player", str(isas / "isas-walk1.mcap"), "--export-msgs", str(msgs)], check=True, capture_output=True)
    base = (ROOT / "examples" / "isas-walk1.toml").read_text().replace('anchor_position = "ranges[].pos"\n', "")
    base = base.replace('time_source = "header"', f'time_source = "header"\nreorder_window_s = {window}')
    cfg = work / f"isas-{window}.toml"
    cfg.write_text(
        base
        + "\n[config.model_selection]\nenabled = false\n"
        + f'\n[mapping.anchors]\nfile = "{isas / "anchors.csv"}"\n'
        + f'\n[live]\nchoose_after_s = 0\nmsg_paths = ["{msgs}"]\n[live.types]\n"/rtls_flares" = "fraunhofer_rtls_flare/msg/RTLSStick"\n'
    )
    return cfg


def sim_recording(work: Path, window: float) -> tuple[Path, Path]:
    run = sim.zoo("handheld_walk", seed=1, stagger_s=0.02, jitter_s=0.005)
    mcap = work / "sim.mcap"
    sim.write_mcap(run, mcap)
    anchors = "\n".join(f"A{k} = [{a[0]}, {a[1]}, {a[2]}]" for k, a in enumerate(run.anchors))
    cfg = work / f"sim-{window}.toml"
    cfg.write_text(
        f'[config.model_selection]\nenabled = false\n[mapping]\nimu_topic = "/imu"\nreorder_window_s = {window}\n'
        f'[mapping.uwb]\ntopics = ["/uwb"]\n[mapping.anchors.positions]\n{anchors}\n[live]\nchoose_after_s = 0\n'
    )
    return mcap, cfg


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rate", type=float, default=1.0, help="pace of the input (1: as recorded)")
    p.add_argument("--windows", type=float, nargs="+", default=[0.5, 0.1], help="reorder windows, s")
    p.add_argument("--isas", type=Path, default=ROOT.parent / "shared" / "data" / "isas-walk1")
    p.add_argument("--no-isas", action="store_true")
    args = p.parse_args()
    print("| input | path | window s | steps | late | max \\|Δ position\\| vs replay, m | latency p50 / p99 / max, ms | CPU, % of a core |")
    print("|---|---|---|---|---|---|---|---|")
    domain = 40
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for window in args.windows:
            rows = []
            if not args.no_isas and args.isas.is_dir():
                cfg = isas_config(args.isas, work, window)
                rows.append(("isas-walk1", "DDS", over_dds(args.isas / "isas-walk1.mcap", cfg, args.rate, ["/waveshare_sense_hat_b", "/rtls_flares"], work, domain)))
                domain += 1
            mcap, cfg = sim_recording(work, window)
            rows.append(("handheld_walk (sim)", "DDS", over_dds(mcap, cfg, args.rate, None, work, domain)))
            domain += 1
            rows.append(("handheld_walk (sim)", "LinkTrack pty", through_a_pty(window, args.rate, work)))
            for name, path, (n, diff, (p50, p99, mx, cpu, late)) in rows:
                print(f"| {name} | {path} | {window:g} | {n} | {late} | {diff:.1e} | {p50:.1f} / {p99:.1f} / {mx:.1f} | {cpu:.0f} |")
    print(f"\n(input at {args.rate:g}× its recorded pace; python benches/live_latency.py)")


if __name__ == "__main__":
    main()
