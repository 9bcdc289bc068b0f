"""Output dataclasses of the torch modules, field for field as smplx's (they also behave like dicts)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, fields
from typing import Any

Tensor = Any


class Deferred:
    """A field value computed on first access (e.g. ``v_shaped``, which few callers read but
    costs a whole mesh to build)."""

    __slots__ = ("compute",)

    def __init__(self, compute: Callable[[], Any]) -> None:
        self.compute = compute


@dataclass
class ModelOutput:
    vertices: Tensor | None = None
    joints: Tensor | None = None
    full_pose: Tensor | None = None
    global_orient: Tensor | None = None
    transl: Tensor | None = None
    v_shaped: Tensor | None = None

    def __getitem__(self, key: str) -> Any:
        return getattr(self, key)

    def get(self, key: str, default: Any = None) -> Any:
        return getattr(self, key, default)

    def __iter__(self) -> Iterator[str]:
        return self.keys()

    def keys(self) -> Iterator[str]:
        return iter([f.name for f in fields(self)])

    def values(self) -> Iterator[Any]:
        return iter([getattr(self, f.name) for f in fields(self)])

    def items(self) -> Iterator[tuple[str, Any]]:
        return iter([(f.name, getattr(self, f.name)) for f in fields(self)])


@dataclass
class SMPLOutput(ModelOutput):
    betas: Tensor | None = None
    body_pose: Tensor | None = None


@dataclass
class SMPLHOutput(SMPLOutput):
    left_hand_pose: Tensor | None = None
    right_hand_pose: Tensor | None = None
    transl: Tensor | None = None


@dataclass
class SMPLXOutput(SMPLHOutput):
    expression: Tensor | None = None
    jaw_pose: Tensor | None = None


@dataclass
class MANOOutput(ModelOutput):
    betas: Tensor | None = None
    hand_pose: Tensor | None = None


@dataclass
class FLAMEOutput(ModelOutput):
    betas: Tensor | None = None
    expression: Tensor | None = None
    jaw_pose: Tensor | None = None
    neck_pose: Tensor | None = None


class _Lazy:
    """Mixed into an output class: a :class:`Deferred` field is computed on first read."""

    def __getattribute__(self, name: str) -> Any:
        value = object.__getattribute__(self, name)
        if type(value) is Deferred:
            value = value.compute()
            object.__setattr__(self, name, value)
        return value


_LAZY: dict[type, type] = {}


def lazy(cls: type) -> type:
    """``cls`` with :class:`Deferred` fields computed on first read (a subclass; eager mode only, since
    ``torch.compile`` cannot trace a custom ``__getattribute__``)."""
    if cls not in _LAZY:
        _LAZY[cls] = type(cls.__name__, (_Lazy, cls), {"__module__": cls.__module__, "__qualname__": cls.__qualname__})
    return _LAZY[cls]
