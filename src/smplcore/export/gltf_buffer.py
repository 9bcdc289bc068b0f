"""The binary buffer of a glTF file: buffer views and accessors appended to one blob (used by :mod:`.gltf`)."""

from __future__ import annotations

from typing import Any

import numpy as np

FLOAT, UBYTE, USHORT, UINT = 5126, 5121, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}
_DTYPES = {FLOAT: np.float32, UBYTE: np.uint8, USHORT: np.uint16, UINT: np.uint32}


class BufferBuilder:
    """Accumulates one binary buffer and the buffer views and accessors pointing into it."""

    def __init__(self, gltf: Any) -> None:
        self.gltf = gltf
        self.blob = bytearray()

    def raw(self, data: bytes) -> int:
        """A buffer view holding ``data`` (e.g. an image); returns its index."""
        import pygltflib

        while len(self.blob) % 4:
            self.blob.append(0)
        offset = len(self.blob)
        self.blob.extend(data)
        self.gltf.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=offset, byteLength=len(data)))
        return len(self.gltf.bufferViews) - 1

    def accessor(
        self,
        array: np.ndarray,
        component: int,
        *,
        target: int | None = None,
        bounds: bool = False,
        normalized: bool = False,
        name: str | None = None,
    ) -> int:
        import pygltflib

        arr = np.ascontiguousarray(array, dtype=_DTYPES[component])
        count = arr.shape[0]
        width = int(np.prod(arr.shape[1:])) if arr.ndim > 1 else 1
        while len(self.blob) % 4:
            self.blob.append(0)
        offset = len(self.blob)
        data = arr.tobytes()
        self.blob.extend(data)
        self.gltf.bufferViews.append(
            pygltflib.BufferView(buffer=0, byteOffset=offset, byteLength=len(data), target=target)
        )
        flat = arr.reshape(count, width)
        kwargs: dict[str, Any] = {}
        if bounds:
            kind = float if component == FLOAT else int
            kwargs = {"min": [kind(v) for v in flat.min(axis=0)], "max": [kind(v) for v in flat.max(axis=0)]}
        self.gltf.accessors.append(
            pygltflib.Accessor(
                bufferView=len(self.gltf.bufferViews) - 1,
                componentType=component,
                count=count,
                type=_TYPES[width],
                normalized=normalized or None,
                name=name,
                **kwargs,
            )
        )
        return len(self.gltf.accessors) - 1
