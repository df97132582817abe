"""Every list of method names agrees with the one registry (crates/uwbimu-app/src/registry.rs):
``FILTERS`` and ``METHODS`` come from it at run time; the stub's ``_MethodName``, ``MethodName``
(python/uwbimu_rs/_typing.py), the streaming classes (module, ``__all__``, stub) and the method
table of docs/methods-detail.md are checked against it here."""

from __future__ import annotations

import ast
import re
import typing
from pathlib import Path

import pytest

import uwbimu_rs
import uwbimu_rs.sim
from uwbimu_rs import _native

ROOT = Path(__file__).resolve().parents[2]
STUB = ROOT / "python" / "uwbimu_rs" / "_native.pyi"


def stub_tree() -> ast.Module:
    return ast.parse(STUB.read_text())


def test_filters_are_the_registry_rows_in_order() -> None:
    assert uwbimu_rs.FILTERS == list(uwbimu_rs.METHODS)
    assert len(set(uwbimu_rs.FILTERS)) == len(uwbimu_rs.FILTERS)
    for name, row in uwbimu_rs.METHODS.items():
        assert set(row) == {"takes", "smoothing", "streaming_class", "chooses_model", "summary"}, name
        assert "ranges" in row["takes"] and row["smoothing"] in {"never", "on_request", "by_default"}
        assert row["summary"].endswith("."), row["summary"]
    assert [m for m, row in uwbimu_rs.METHODS.items() if row["chooses_model"]] == ["best"]


def test_stub_method_names_are_the_registry() -> None:
    for node in stub_tree().body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_MethodName" for t in node.targets):
            value = node.value
            assert isinstance(value, ast.Subscript) and isinstance(value.slice, ast.Tuple)
            names = [e.value for e in value.slice.elts if isinstance(e, ast.Constant)]
            assert names == uwbimu_rs.FILTERS
            return
    raise AssertionError("no _MethodName in the stub")


def test_typing_method_names_are_the_registry() -> None:
    """``MethodName``, the ``Literal`` type checkers see, is a copy of the registry's names: in
    its order, none missing, none extra."""
    names = typing.get_args(uwbimu_rs.MethodName)
    assert set(names) == set(uwbimu_rs.METHODS)
    assert list(names) == uwbimu_rs.FILTERS


def test_streaming_classes_are_the_registry_rows_that_have_one() -> None:
    declared = {row["streaming_class"] for row in uwbimu_rs.METHODS.values()} - {None}
    assert declared, "no streaming class in the registry"
    for cls in declared:
        assert getattr(_native, cls).__module__ == "uwbimu_rs._native"
        assert getattr(uwbimu_rs, cls) is getattr(_native, cls) and cls in uwbimu_rs.__all__
    in_stub = {
        node.name
        for node in stub_tree().body
        if isinstance(node, ast.ClassDef) and any(getattr(b, "id", None) == "_StreamingFilter" for b in node.bases)
    }
    assert in_stub == declared
    exported = {name for name in uwbimu_rs.__all__ if isinstance(getattr(uwbimu_rs, name), type)}
    streaming = {name for name in exported if hasattr(getattr(uwbimu_rs, name), "add_range")}
    assert streaming == declared
    # A class's docstring is its method's row of the registry.
    for name, row in uwbimu_rs.METHODS.items():
        if row["streaming_class"]:
            doc = getattr(_native, row["streaming_class"]).__doc__
            assert doc.startswith(row["summary"]) and not doc.endswith("\n"), name


def test_methods_detail_table_lists_every_method_once() -> None:
    lines = (ROOT / "docs" / "methods-detail.md").read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if re.match(r"\|\s*method\s*\|", line))
    rows = []
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            break
        rows.append(line.split("|")[1].strip().strip("`"))
    assert sorted(rows) == sorted(uwbimu_rs.FILTERS)


def test_sensor_lists_are_the_sensor_registry() -> None:
    """The sensor registry (crates/uwbimu-vocabulary/src/sensors.rs): ``run_filter``'s keyword
    arguments for sensor arrays (``**sensors``, documented from the rows), the inputs a method
    takes and each streaming class's ``add_sensor`` are its rows."""
    import inspect

    sensors = uwbimu_rs.SENSORS
    keywords = {row["keyword"] for row in sensors.values()}
    assert len(keywords) == len(sensors)
    params = inspect.signature(uwbimu_rs.run_filter).parameters
    assert params["sensors"].kind is inspect.Parameter.VAR_KEYWORD
    doc = uwbimu_rs.run_filter.__doc__ or ""
    for row in sensors.values():
        assert f"``{row['keyword']}`` :" in doc and row["doc"] in doc, f"run_filter's docstring lacks {row['keyword']}"
    # Besides the sensors a method takes ranges, and ranges from several tags: INPUTS, from the
    # registry's Input.
    inputs = uwbimu_rs.INPUTS
    assert set(sensors) <= set(inputs) and len(set(inputs)) == len(inputs)
    for name, row in uwbimu_rs.METHODS.items():
        assert set(row["takes"]) <= set(inputs), name
    assert set(inputs) == {i for row in uwbimu_rs.METHODS.values() for i in row["takes"]}, "an input no method takes"
    r = uwbimu_rs.sim.zoo("agv_loop", seed=0)
    for name in {row["streaming_class"] for row in uwbimu_rs.METHODS.values()} - {None}:
        f = getattr(uwbimu_rs, name)(r.anchors, initial=r.initial)
        for sensor, row in sensors.items():
            # A row of no layout's width: refused for its width (or as not taken), never as unknown.
            with pytest.raises(ValueError) as e:
                f.add_sensor(sensor, [0.0])
            said = str(e.value)
            assert "unknown sensor" not in said and (sensor in said or row["keyword"] in said), f"{name}: {said}"