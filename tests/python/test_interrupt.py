"""Ctrl-C during a long native call: a clean KeyboardInterrupt within a second (the call checks
Python's signals every 0.1 s and cancels the run), in a fresh process too, and the module works
afterwards."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent(
    """
    import os, signal, threading, time
    import numpy as np
    import uwbimu_rs

    anchors = np.array([[0.0, 0.0, 2.0], [8.0, 0.0, 1.0], [8.0, 6.0, 2.0], [0.0, 6.0, 1.0]])
    at_rest = {"position": [4.0, 3.0, 0.3], "velocity": [0, 0, 0], "orientation": [1, 0, 0, 0]}
    rng = np.random.default_rng(1)
    # 40 min still at 500 Hz, ranges at 10 Hz: several seconds of smoothed EKF.
    t = np.arange(0.0, 2400.0, 0.002)
    imu = np.zeros((t.size, 7))
    imu[:, 0] = t
    imu[:, 3] = 9.80665
    imu[:, 1:] += rng.normal(0.0, 0.01, (t.size, 6))
    tr = np.arange(0.05, 2400.0, 0.1)
    a = np.arange(tr.size) % 4
    r = np.linalg.norm(anchors[a] - np.array([4.0, 3.0, 0.35]), axis=1) + rng.normal(0.0, 0.1, tr.size)
    ranges = np.column_stack([tr, a, r])
    signalled = []
    def interrupt():
        signalled.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)
    threading.Timer(0.5, interrupt).start()
    started = time.perf_counter()
    try:
        uwbimu_rs.run_filter("METHOD", imu, ranges, anchors, initial=at_rest, smooth=True)
        print("finished", time.perf_counter() - started)
    except KeyboardInterrupt:
        print("interrupted", time.perf_counter() - signalled[0])
    # The module still works.
    frame = uwbimu_rs.run_filter("ekf", imu[:2000], ranges[:40], anchors, initial=at_rest)
    print("after", frame.height)
    """
)


@pytest.mark.parametrize("method", ["ekf", "best"])
def test_ctrl_c_interrupts_a_long_call_within_a_second(method):
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT.replace("METHOD", method)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert "PanicException" not in done.stderr, done.stderr
    lines = dict(line.split(" ", 1) for line in done.stdout.splitlines())
    assert "interrupted" in lines, done.stdout
    assert float(lines["interrupted"]) < 1.0, done.stdout
    assert lines["after"] == "2000"
