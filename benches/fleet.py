"""Logs per second: serial ``uwbimu_rs.replay`` in a loop against ``uwbimu_rs.fleet.replay`` on Ray.

    .venv/bin/python benches/fleet.py                      # 24 simulated logs, local Ray on all CPUs
    .venv/bin/python benches/fleet.py --logs 48 --method ekf
    .venv/bin/python benches/fleet.py --address 127.0.0.1:6390   # a running cluster (docs/fleet.md)

Both write every trajectory to Parquet and run the same method on the same logs (simulated
150 s runs of four scenarios, written as MCAP once into a temporary directory). The serial loop
runs in this process; the fleet's time includes starting the local Ray (reported apart) and
every task's scheduling. Prints logs/s of each and their ratio, and checks the outputs agree.
"""

from __future__ import annotations

import argparse
import logging
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl

import uwbimu_rs
from uwbimu_rs import fleet, sim

SCENARIOS = ("hall_vehicle_nlos", "hall_vehicle", "garage_rectangle", "garage_figure8")


def make_logs(folder: Path, count: int) -> list[str]:
    """``count`` simulated recordings (the four scenarios, a seed each) as MCAP files."""
    paths = []
    for k in range(count):
        path = folder / f"log{k:03d}.mcap"
        sim.write_mcap(sim.preset(SCENARIOS[k % len(SCENARIOS)], seed=k), path)  # type: ignore[arg-type]
        paths.append(str(path))
    return paths


def serial(paths: list[str], method: str, out: Path) -> float:
    """Seconds to replay every log in this process, writing each trajectory to Parquet."""
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    for path in paths:
        trajectory, _ = uwbimu_rs.replay(path, method)  # type: ignore[arg-type]
        trajectory.write_parquet(out / (Path(path).stem + ".parquet"))
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--logs", type=int, default=24, help="number of simulated logs")
    parser.add_argument("--method", default="best")
    parser.add_argument("--address", default=None, help="a Ray cluster to join (default: a local Ray)")
    parser.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local Ray (default: all)")
    args = parser.parse_args()
    import ray

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = make_logs(folder, args.logs)
        t_serial = serial(paths, args.method, folder / "serial")
        start = time.perf_counter()
        if args.address is None:
            ray.init(address="local", num_cpus=args.num_cpus, include_dashboard=False, logging_level=logging.ERROR)
        else:
            ray.init(address=args.address, logging_level=logging.ERROR)
        t_init = time.perf_counter() - start
        nodes = [n for n in ray.nodes() if n["Alive"]]
        cpus = int(ray.cluster_resources().get("CPU", 0))
        start = time.perf_counter()
        summary = fleet.replay(paths, args.method, out_dir=folder / "fleet", force=True)
        t_fleet = time.perf_counter() - start
        hosts = sorted({n["NodeManagerAddress"] + ":" + str(n["NodeManagerPort"]) for n in nodes})
        ray.shutdown()
        failed = summary.filter(pl.col("status") != "ok")
        assert failed.is_empty(), failed
        worst = 0.0
        for row in summary.iter_rows(named=True):
            a = pl.read_parquet(row["output"]).select("x", "y", "z").to_numpy()
            b = pl.read_parquet(folder / "serial" / (Path(row["path"]).stem + ".parquet")).select("x", "y", "z").to_numpy()
            worst = max(worst, float(np.abs(a - b).max()))
    n = len(paths)
    print(f"machine: {os.cpu_count()} CPUs here; Ray: {len(nodes)} node(s) {', '.join(hosts)}, {cpus} CPUs")
    print(f"{n} logs, method {args.method}, {int(summary['n_imu'].sum())} IMU samples in all")
    print(f"serial replay        {n / t_serial:8.2f} logs/s  ({t_serial:.2f} s)")
    print(f"fleet.replay on Ray  {n / t_fleet:8.2f} logs/s  ({t_fleet:.2f} s; Ray start {t_init:.2f} s apart)")
    print(f"speed-up             {t_serial / t_fleet:8.2f}x  (with the Ray start: {t_serial / (t_fleet + t_init):.2f}x)")
    print(f"fleet vs serial outputs: max |Δposition| = {worst:.2e} m")


if __name__ == "__main__":
    main()
