"""Names the public API accepts, as ``Literal`` types for type checkers.

Each list mirrors one native registry and is held to it by a test (``tests/python/test_registry.py``):
the registry stays the one place a name is declared.
"""

from __future__ import annotations

from typing import Literal

MethodName = Literal[
    "uwb_ls", "ekf", "iekf", "rekf", "riekf", "criekf", "ckf", "arckf", "ackf", "eskf", "shaf", "shfaf", "ukf",
    "rukf", "ekf2d", "ukf2d", "cekf2d", "best",
]
"""A method name: the rows of the registry (``crates/uwbimu-app/src/registry.rs``) in its order, as
:data:`uwbimu_rs.FILTERS` lists them at run time."""
