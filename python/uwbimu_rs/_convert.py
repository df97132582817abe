"""Conversions between the native layer's plain values and the public types (no maths)."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import polars as pl


def frame(cols: dict[str, np.ndarray]) -> pl.DataFrame:
    """A result frame from native columns (``still`` as a boolean, ``status`` as UInt8 bits)."""
    frame = pl.DataFrame(cols)
    if "still" in frame.columns:
        frame = frame.with_columns(pl.col("still").cast(pl.Boolean))
    if "status" in frame.columns:
        frame = frame.with_columns(pl.col("status").cast(pl.UInt8))
    return frame


def plain(value: Any) -> Any:
    """A plain dict for any mapping (the native layer reads dicts); other values unchanged."""
    return dict(value) if isinstance(value, Mapping) else value


def model_choice(choice: dict[str, Any]) -> dict[str, Any]:
    """A native model choice (``choose_model``, ``info["model"]`` of a batch run) with its
    ``candidates`` as a polars DataFrame: ``label``, ``score`` (m), ``per_anchor`` (list of m)."""
    rows = choice.pop("candidates")
    choice["candidates"] = pl.DataFrame(
        {"label": [r["label"] for r in rows], "score": [r["score"] for r in rows], "per_anchor": [r["per_anchor"] for r in rows]},
        schema={"label": pl.String, "score": pl.Float64, "per_anchor": pl.List(pl.Float64)},
    )
    return choice
