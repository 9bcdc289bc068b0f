"""The FBX 7.4 document around the objects: header extension, global settings (axes, unit, time), the object
table with ids, its connections and the definitions that count them, and the take.

Object names in a binary file are ``name + "\\x00\\x01" + class`` (``"Model::name"`` in ASCII files).
Matrices are 16 doubles with the translation in elements 12-14 (the transpose of a column-vector matrix).
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from smplcore.export.fbx.binary import CREATION_TIME, FILE_ID, I32, I64, Node

#: FBX time unit: ticks per second
KTIME_PER_SECOND = 46_186_158_000

#: GlobalSettings TimeMode for the frame rates FBX names; any other rate is "custom" (14) + CustomFrameRate
_TIME_MODES = {120.0: 1, 100.0: 2, 60.0: 3, 50.0: 4, 48.0: 5, 30.0: 6, 25.0: 10, 24.0: 11, 1000.0: 12}
_TIME_MODES |= {96.0: 15, 72.0: 16}

#: (UpAxis, UpAxisSign, FrontAxis, FrontAxisSign, CoordAxis, CoordAxisSign) of the two frames we write
AXES = {"y": (1, 1, 2, 1, 0, 1), "z": (2, 1, 1, -1, 0, 1)}


def object_name(name: str, cls: str) -> str:
    return f"{name}\x00\x01{cls}"


def matrix(m: np.ndarray) -> np.ndarray:
    """(4, 4) column-vector matrix -> the 16 doubles FBX stores."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float64).T).reshape(16)


def ktime(seconds: np.ndarray | float) -> np.ndarray:
    """Seconds -> int64 FBX ticks."""
    return np.round(np.asarray(seconds, dtype=np.float64) * KTIME_PER_SECOND).astype(np.int64)


def properties70(node: Node, *entries: tuple[Any, ...]) -> Node:
    """Add a ``Properties70`` child with one ``P`` per entry ``(name, type, label, flags, *values)``."""
    block = node.add("Properties70")
    for entry in entries:
        block.add("P", *entry)
    return block


@dataclass
class Document:
    """Objects with ids, connections between them, and what the definitions count."""

    objects: list[Node] = field(default_factory=list)
    connections: list[Node] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    _next_id: int = 1_000_000

    def new(self, kind: str, name: str, cls: str, subclass: str) -> tuple[int, Node]:
        """A new object ``kind`` (``Model``, ``Geometry``, ``Deformer``, ...): its id and node."""
        self._next_id += 1
        node = Node(kind, [I64(self._next_id), object_name(name, cls), subclass], scope=True)
        self.objects.append(node)
        self.counts[kind] = self.counts.get(kind, 0) + 1
        return self._next_id, node

    def connect(self, child: int, parent: int, prop: str | None = None) -> None:
        """Connect object ``child`` to object ``parent`` (0: the scene root), or to its property ``prop``."""
        if prop is None:
            self.connections.append(Node("C", ["OO", I64(child), I64(parent)]))
        else:
            self.connections.append(Node("C", ["OP", I64(child), I64(parent), prop]))

    def nodes(
        self, *, creator: str, up_axis: str, unit_scale: float, fps: float, stop: int, take: str | None
    ) -> list[Node]:
        """The top-level nodes of the file. ``unit_scale``: centimetres per file unit; ``stop``: last key
        time in ticks; ``take``: the animation stack's name (None without animation)."""
        now = _dt.datetime.now(_dt.timezone.utc)
        header = Node("FBXHeaderExtension")
        header.add("FBXHeaderVersion", I32(1003))
        header.add("FBXVersion", I32(7400))
        header.add("EncryptionType", I32(0))
        stamp = header.add("CreationTimeStamp")
        stamp.add("Version", I32(1000))
        for key, value in (("Year", now.year), ("Month", now.month), ("Day", now.day), ("Hour", now.hour)):
            stamp.add(key, I32(value))
        for key, value in (("Minute", now.minute), ("Second", now.second), ("Millisecond", now.microsecond // 1000)):
            stamp.add(key, I32(value))
        header.add("Creator", creator)
        info = header.add("SceneInfo", object_name("GlobalInfo", "SceneInfo"), "UserData")
        info.add("Type", "UserData")
        info.add("Version", I32(100))
        meta = info.add("MetaData")
        meta.add("Version", I32(100))
        for key in ("Title", "Subject", "Author", "Keywords", "Revision", "Comment"):
            meta.add(key, "")
        properties70(info, ("Original|ApplicationName", "KString", "", "", "smplcore"))

        up, up_sign, front, front_sign, coord, coord_sign = AXES[up_axis]
        mode = _TIME_MODES.get(float(fps), 14)
        settings = Node("GlobalSettings")
        settings.add("Version", I32(1000))
        properties70(
            settings,
            ("UpAxis", "int", "Integer", "", I32(up)),
            ("UpAxisSign", "int", "Integer", "", I32(up_sign)),
            ("FrontAxis", "int", "Integer", "", I32(front)),
            ("FrontAxisSign", "int", "Integer", "", I32(front_sign)),
            ("CoordAxis", "int", "Integer", "", I32(coord)),
            ("CoordAxisSign", "int", "Integer", "", I32(coord_sign)),
            ("OriginalUpAxis", "int", "Integer", "", I32(up)),
            ("OriginalUpAxisSign", "int", "Integer", "", I32(1)),
            ("UnitScaleFactor", "double", "Number", "", float(unit_scale)),
            ("OriginalUnitScaleFactor", "double", "Number", "", float(unit_scale)),
            ("AmbientColor", "ColorRGB", "Color", "", 0.0, 0.0, 0.0),
            ("DefaultCamera", "KString", "", "", "Producer Perspective"),
            ("TimeMode", "enum", "", "", I32(mode)),
            ("TimeProtocol", "enum", "", "", I32(2)),
            ("SnapOnFrameMode", "enum", "", "", I32(0)),
            ("TimeSpanStart", "KTime", "Time", "", I64(0)),
            ("TimeSpanStop", "KTime", "Time", "", I64(stop)),
            ("CustomFrameRate", "double", "Number", "", float(fps)),
            ("CurrentTimeMarker", "int", "Integer", "", I32(-1)),
        )

        documents = Node("Documents")
        documents.add("Count", I32(1))
        document = documents.add("Document", I64(self._next_id + 1), "Scene", "Scene")
        properties70(
            document,
            ("SourceObject", "object", "", ""),
            ("ActiveAnimStackName", "KString", "", "", take or ""),
        )
        document.add("RootNode", I64(0))

        definitions = Node("Definitions")
        definitions.add("Version", I32(100))
        definitions.add("Count", I32(1 + sum(self.counts.values())))
        definitions.add("ObjectType", "GlobalSettings").add("Count", I32(1))
        for kind, count in self.counts.items():
            definitions.add("ObjectType", kind).add("Count", I32(count))

        objects = Node("Objects", [], self.objects)
        connections = Node("Connections", [], self.connections)
        takes = Node("Takes")
        takes.add("Current", take or "")
        if take is not None:
            entry = takes.add("Take", take)
            entry.add("FileName", f"{take}.tak")
            entry.add("LocalTime", I64(0), I64(stop))
            entry.add("ReferenceTime", I64(0), I64(stop))
        return [
            header,
            Node("FileId", [FILE_ID]),  # with CreationTime and the footer id: the trio FBX SDK readers accept
            Node("CreationTime", [CREATION_TIME]),
            Node("Creator", [creator]),
            settings,
            documents,
            Node("References"),
            definitions,
            objects,
            connections,
            takes,
        ]
