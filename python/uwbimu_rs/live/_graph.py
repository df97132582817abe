"""What the DDS graph says about its topics: the publications (DDS built-in topic
``DCPSPublication``) with their type names, and — where the publisher sends XTypes type
information, as Cyclone DDS does — the types themselves, written back as ROS 2 ``.msg`` text.
The node uses it for a topic whose type is not named, or whose ``.msg`` it cannot find."""

from __future__ import annotations

import typing
from typing import Any

_PLAIN = {bool: "bool", str: "string", float: "float64", int: "int64"}
_ANNOTATED = {"char": "uint8", "byte": "uint8", "wchar": "uint16"}


def ros_type_name(dds_type_name: str) -> str:
    """``pkg::msg::dds_::Name_`` (or with dots) → ``pkg/msg/Name``."""
    parts = dds_type_name.replace("::", ".").split(".")
    name = parts[-1][:-1] if parts[-1].endswith("_") else parts[-1]
    return f"{parts[0]}/msg/{name}"


def _is_struct(t: Any) -> bool:
    from cyclonedds.idl import IdlStruct

    return isinstance(t, type) and issubclass(t, IdlStruct)


def _field(t: Any, structs: dict[str, Any]) -> str:
    """The ``.msg`` type of a field annotation (``float64``, ``pkg/Type[]``, …); nested
    structs are added to ``structs``."""
    from cyclonedds.idl import types as idl

    if _is_struct(t):
        name = ros_type_name(t.__idl_typename__)
        structs.setdefault(name, t)
        return name.replace("/msg/", "/")
    if t in _PLAIN:
        return _PLAIN[t]
    if typing.get_origin(t) is typing.Annotated:
        meta = t.__metadata__[0]
        if isinstance(meta, str):
            return _ANNOTATED.get(meta, meta)
        if isinstance(meta, idl.sequence):
            bound = f"<={meta.max_length}" if meta.max_length else ""
            return f"{_field(meta.subtype, structs)}[{bound}]"
        if isinstance(meta, idl.array):
            return f"{_field(meta.subtype, structs)}[{meta.length}]"
        if isinstance(meta, idl.bounded_str):
            return "string"
    raise ValueError(f"a field type with no ROS 2 .msg equivalent: {t!r}")


def msg_definition(root: Any) -> tuple[str, str]:
    """The ROS 2 name and full ``.msg`` definition (with its dependencies, as an MCAP
    ``ros2msg`` schema carries them) of a discovered Cyclone DDS struct type."""
    name = ros_type_name(root.__idl_typename__)
    structs: dict[str, Any] = {name: root}
    sections: list[str] = []
    done: set[str] = set()
    while len(done) < len(structs):
        current = next(n for n in structs if n not in done)
        done.add(current)
        body = "".join(f"{_field(t, structs)} {f}\n" for f, t in structs[current].__annotations__.items())
        sections.append(body if current == name else f"{'=' * 80}\nMSG: {current}\n{body}")
    return name, "".join(sections)


class Graph:
    """The publications of a DDS domain, read as they are discovered."""

    def __init__(self, participant: Any) -> None:
        from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication

        self.participant = participant
        self._reader = BuiltinDataReader(participant, BuiltinTopicDcpsPublication)

    def publications(self) -> list[Any]:
        """The publications discovered since the last call (``topic_name``, ``type_name``,
        ``type_id``)."""
        return list(self._reader.take(N=256))

    def definition(self, publication: Any, timeout_s: float = 3.0) -> tuple[str, str] | None:
        """The ROS 2 name and ``.msg`` definition of a publication's type, from the type
        information its publisher sends (None without any)."""
        if publication.type_id is None:
            return None
        from cyclonedds.dynamic import get_types_for_typeid
        from cyclonedds.util import duration

        root, _ = get_types_for_typeid(self.participant, publication.type_id, duration(seconds=timeout_s))
        return msg_definition(root)
