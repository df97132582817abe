"""Where the tests find the workplace's shared data: ``../shared`` beside the clone, or the
directory ``UWBIMU_SHARED`` names. A test that reads it carries the marker ``needs_isas`` and is
skipped, with the reason, when the recording is not there (a user's clone has no ``../shared``).
``scripts/test.sh`` runs every other test with ``UWBIMU_SHARED`` naming a directory that does
not exist, so that a test reading the shared data without the marker fails there."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("UWBIMU_SHARED", ROOT.parent / "shared"))
ISAS = SHARED / "data" / "isas-walk1"
"""The real recording isas-walk1 (its MCAP, anchors and ground truth)."""

needs_isas = pytest.mark.needs_isas
"""Marks a test that reads isas-walk1 (skipped without it, see :func:`skip_reason`)."""


def skip_reason() -> str | None:
    """Why a ``needs_isas`` test is skipped here, or None when the recording is present."""
    if (ISAS / "isas-walk1.mcap").exists():
        return None
    return f"{ISAS} is not present (real-log tests need ../shared/data beside the clone)"
