#!/usr/bin/env bash
# Creates .venv (if missing), installs the Python dependencies and builds the extension into it.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
.venv/bin/python -m pip install -q --disable-pip-version-check "numpy>=1.24" "polars>=1.0" "matplotlib>=3.7" "pytest>=7" "pytest-xdist>=3" "maturin>=1.9.4,<2" "mypy>=1.10" "mcap>=1.2" "mcap-ros2-support>=0.5" "hypothesis>=6.100" "ray>=2.9" "cyclonedds>=11,<12" "foxglove-sdk>=0.30" "pyserial>=3.5"
VIRTUAL_ENV="$PWD/.venv" PATH="$PWD/.venv/bin:$PATH" .venv/bin/maturin develop -q
