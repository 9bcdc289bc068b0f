"""The FBX binary container (version 7.4): a tree of node records, written from the public description of
the layout (Blender Foundation's "FBX binary file format specification", 2013, public domain; fbxcel's
and the fbx-book's notes on the footer; the known-working id trio documented by other writers).

File = 27-byte header (``b"Kaydara FBX Binary  \\x00\\x1a\\x00"`` + uint32 version) | top-level node records |
a 13-byte null record | footer. A node record (versions < 7500) is::

    uint32 end_offset       absolute file offset just past this record (its children included)
    uint32 num_properties
    uint32 property_bytes   length of the property list
    uint8  name_length, name
    properties              each: a one-letter type code, then the value
    children                node records, then a 13-byte null record (also written for a node that has
                            neither properties nor children, and for an empty ``{}`` scope)

Property codes: ``Y`` int16, ``C`` bool (1 byte), ``I`` int32, ``F`` float32, ``D`` float64, ``L`` int64,
``S`` string and ``R`` raw bytes (uint32 length + bytes); arrays ``b i l f d`` (uint32 count, uint32
encoding 0 raw / 1 zlib, uint32 stored bytes, data). Everything is little-endian.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Node", "I16", "I32", "I64", "F32", "encode_file", "write_file", "HEADER_MAGIC", "FOOTER_MAGIC", "FILE_ID"]

VERSION = 7400
HEADER_MAGIC = b"Kaydara FBX Binary  \x00\x1a\x00"
#: the fixed last 16 bytes of the footer
FOOTER_MAGIC = bytes.fromhex("f85a8c6adef5d97eece90ce3758f290b")
#: The first 16 bytes of the footer. The FBX SDK derives them (and the header's ``FileId``) from the file's
#: ``CreationTime``, and its readers can refuse a file whose three disagree; nobody outside Autodesk knows the
#: derivation, so independent writers use one known-working trio: this id, :data:`FILE_ID` and
#: :data:`CREATION_TIME`.
FOOTER_ID = bytes.fromhex("fabcab09d0c8d466b176fb831cf7267e")
FILE_ID = bytes.fromhex("28b32aebb624ccc2bfc8b02aa92bfcf1")
CREATION_TIME = "1970-01-01 10:00:00:000"
_NULL_RECORD = b"\x00" * 13
#: arrays at least this long (in bytes) are stored zlib-compressed
_COMPRESS_FROM = 128

_ARRAY_CODES = {np.dtype(np.bool_): b"b", np.dtype(np.int32): b"i", np.dtype(np.int64): b"l"}
_ARRAY_CODES |= {np.dtype(np.float32): b"f", np.dtype(np.float64): b"d"}


@dataclass(frozen=True)
class _Typed:
    value: Any


class I16(_Typed):
    """An int16 property (``Y``)."""


class I32(_Typed):
    """An int32 property (``I``); a plain Python ``int`` is written as one too."""


class I64(_Typed):
    """An int64 property (``L``): object ids, times."""


class F32(_Typed):
    """A float32 property (``F``); a plain Python ``float`` is written as float64 (``D``)."""


@dataclass
class Node:
    """One node record: a name, its properties and its children. ``scope``: write the (possibly empty) nested
    list even without children -- objects need one (``AnimationLayer: id, name, "" {}``); readers such as
    Assimp refuse an object without it."""

    name: str
    props: list[Any] = field(default_factory=list)
    children: list[Node] = field(default_factory=list)
    scope: bool = False

    def add(self, name: str, *props: Any) -> Node:
        """Append a child ``name`` with ``props`` and return it."""
        child = Node(name, list(props))
        self.children.append(child)
        return child

    def find(self, name: str) -> Node | None:
        """The first child called ``name``."""
        return next((c for c in self.children if c.name == name), None)


def _encode_property(value: Any) -> bytes:
    if isinstance(value, (bool, np.bool_)):
        return b"C" + struct.pack("<?", bool(value))
    if isinstance(value, I16):
        return b"Y" + struct.pack("<h", value.value)
    if isinstance(value, I64):
        return b"L" + struct.pack("<q", value.value)
    if isinstance(value, (I32, int, np.integer)):
        number = value.value if isinstance(value, I32) else int(value)
        return b"I" + struct.pack("<i", number)
    if isinstance(value, F32):
        return b"F" + struct.pack("<f", value.value)
    if isinstance(value, (float, np.floating)):
        return b"D" + struct.pack("<d", float(value))
    if isinstance(value, str):
        data = value.encode("utf-8")
        return b"S" + struct.pack("<I", len(data)) + data
    if isinstance(value, (bytes, bytearray)):
        return b"R" + struct.pack("<I", len(value)) + bytes(value)
    if isinstance(value, np.ndarray):
        code = _ARRAY_CODES.get(value.dtype)
        if code is None:
            raise TypeError(f"FBX arrays hold bool, int32, int64, float32 or float64, got {value.dtype}")
        raw = np.ascontiguousarray(value.reshape(-1)).astype(value.dtype.newbyteorder("<"), copy=False).tobytes()
        encoding, data = (1, zlib.compress(raw, 6)) if len(raw) >= _COMPRESS_FROM else (0, raw)
        return code + struct.pack("<III", value.size, encoding, len(data)) + data
    raise TypeError(f"no FBX property type for {type(value).__name__}")


def _encode_node(node: Node, out: bytearray) -> None:
    """Append ``node`` to ``out``, the file so far (offsets are positions in it)."""
    name = node.name.encode("ascii")
    if len(name) > 255:
        raise ValueError(f"FBX node names are at most 255 bytes, got {node.name!r}")
    props = b"".join(_encode_property(p) for p in node.props)
    start = len(out)
    out += b"\x00" * 12  # end offset, property count, property bytes: patched below
    out += struct.pack("<B", len(name)) + name + props
    if node.children or node.scope or not node.props:
        for child in node.children:
            _encode_node(child, out)
        out += _NULL_RECORD
    end = len(out)
    if end >= 2**32:
        raise ValueError("the FBX 7.4 file would exceed 4 GB (32-bit offsets)")
    out[start : start + 12] = struct.pack("<III", end, len(node.props), len(props))


def encode_file(nodes: Iterable[Node], version: int = VERSION) -> bytes:
    """The bytes of an FBX binary file holding the top-level ``nodes``."""
    out = bytearray(HEADER_MAGIC + struct.pack("<I", version))
    for node in nodes:
        _encode_node(node, out)
    out += _NULL_RECORD
    out += FOOTER_ID
    out += b"\x00" * (16 - len(out) % 16)  # pad to a 16-byte boundary, at least one byte (as the SDK does)
    out += b"\x00" * 4 + struct.pack("<I", version) + b"\x00" * 120 + FOOTER_MAGIC
    return bytes(out)


def write_file(path: str | Path, nodes: Iterable[Node], version: int = VERSION) -> Path:
    """Write ``nodes`` as an FBX binary file at ``path`` (parent folders are created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(encode_file(nodes, version))
    return path
