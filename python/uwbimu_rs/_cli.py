"""The ``uwbimu-replay`` console script (``[project.scripts]`` in pyproject.toml): the Rust
command line (``uwbimu_rs._native.replay_main``) run with ``sys.argv``."""

from __future__ import annotations

import signal
import sys
from typing import NoReturn

from uwbimu_rs import _native


def main() -> NoReturn:
    """Run ``uwbimu-replay`` with the process's arguments and exit with its status.

    Ctrl-C ends the run at once, as it does the compiled binary: Python's own SIGINT handler
    would only raise ``KeyboardInterrupt`` once the native call returns.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    sys.exit(_native.replay_main(sys.argv))
