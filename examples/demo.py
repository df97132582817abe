"""Demo: UWB-only least squares vs the tightly coupled EKF on the simulated setup of Li & Wang 2020.

Runs both methods on the Li & Wang 2020 preset (figure-8 ×4, 4 anchors, UWB 2 Hz, IMU 100 Hz) with and
without NLOS shielding, prints an accuracy table, writes a plot to out/demo.png and the NLOS run
as an MCAP recording out/demo.mcap (+ its ground truth out/demo_truth.csv) for uwbimu-replay.
The filter gets the configuration matched to the simulated sensors (``run.config``).

    python examples/demo.py [--seed N] [--no-plot]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import uwbimu_rs
from uwbimu_rs import metrics, sim

SCENARIOS = ("hall_vehicle", "hall_vehicle_nlos")
METHODS = ("uwb_ls", "ekf")


def results(seed: int = 0) -> dict:
    """``{(scenario, method): (ErrorStats of the horizontal error, DataFrame, SimResult)}``."""
    out = {}
    for name in SCENARIOS:
        run = sim.preset(name, seed=seed)
        for method in METHODS:
            df = uwbimu_rs.run_filter(method, run.imu, run.ranges, run.anchors, config=run.config)
            out[(name, method)] = (metrics.evaluate(df, run.truth).horizontal, df, run)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="simulator seed")
    parser.add_argument("--no-plot", action="store_true", help="skip the matplotlib figure")
    args = parser.parse_args()
    frames = results(args.seed)
    print(f"{'scenario':<12} {'method':<8} {'RMSE h [m]':>10} {'mean h [m]':>10} {'p95 h [m]':>10} {'max h [m]':>10}")
    for (name, method), (h, _, _) in frames.items():
        print(f"{name:<12} {method:<8} {h.rmse:>10.3f} {h.mean:>10.3f} {h.p95:>10.3f} {h.max:>10.3f}")
    out = Path("out")
    out.mkdir(exist_ok=True)
    run = frames[("hall_vehicle_nlos", "ekf")][2]
    sim.write_mcap(run, out / "demo.mcap", range_std=0.1)
    run.truth.select("t", "x", "y", "z").write_csv(out / "demo_truth.csv")
    print(f"recording written to {out / 'demo.mcap'} (ground truth {out / 'demo_truth.csv'})")
    if args.no_plot:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for ax, name in zip(axes, SCENARIOS):
        run = frames[(name, "ekf")][2]
        ax.plot(run.truth["x"], run.truth["y"], "k-", lw=1, label="truth")
        ls = frames[(name, "uwb_ls")][1]
        ax.plot(ls["x"], ls["y"], ".", ms=3, color="tab:orange", label="uwb_ls")
        ekf = frames[(name, "ekf")][1]
        ax.plot(ekf["x"], ekf["y"], "-", lw=1, color="tab:blue", label="ekf")
        ax.plot(run.anchors[:, 0], run.anchors[:, 1], "s", color="tab:red", label="anchors")
        ax.set_title(name)
        ax.set_xlabel("east [m]")
        ax.set_aspect("equal")
    for ax in axes:
        ax.set_ylabel("north [m]")
    axes[0].legend(loc="center", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "demo.png", dpi=110)
    print(f"plot written to {out / 'demo.png'}")


if __name__ == "__main__":
    main()
