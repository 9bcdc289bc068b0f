"""Moving keypoints from one convention to another by name, with a mask of what was available."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from smplcore.errors import ShapeError
from smplcore.keypoints import approximate as approx
from smplcore.keypoints.aliases import canonical
from smplcore.keypoints.conventions import CONVENTIONS, convention_key

#: A point of a layout: (vocabulary name, convention key or None for the vocabulary's own point).
Point = tuple[str, "str | None"]


@dataclass(frozen=True)
class Layout:
    """The ordered points of a convention, a model's outputs or a custom name list."""

    points: tuple[Point, ...]
    label: str

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.points)

    def __len__(self) -> int:
        return len(self.points)


def _split(name: str, default: str | None) -> Point:
    """``"h36m17:pelvis"`` is H36M's pelvis; a plain name is a point of ``default`` (or the vocabulary's)."""
    if ":" in name:
        prefix, _, rest = name.partition(":")
        try:
            key = convention_key(prefix)
        except ValueError:
            return canonical(name, default), default
        return canonical(rest, key), key
    return canonical(name, default), default


def layout(spec: Any, argument: str = "convention") -> Layout:
    """The :class:`Layout` of ``spec``: a convention name, a model (anything with ``joint_names``),
    a :class:`~smplcore.keypoints.readers.KeypointArray`, or a sequence of point names.

    Point names may be qualified by their convention (``"h36m17:pelvis"``) and may use the
    conventions' own spellings (``"LShoulder"``).
    """
    if isinstance(spec, Layout):
        return spec
    if isinstance(spec, str):
        key = convention_key(spec)
        return Layout(tuple((n, key) for n in CONVENTIONS[key]), key)
    convention = getattr(spec, "convention", None)
    if hasattr(spec, "joint_names"):
        model_type = getattr(spec, "model_type", None) or getattr(getattr(spec, "SPEC", None), "model_type", None)
        default = "flame" if model_type == "flame" else None
        names = list(spec.joint_names)
        label = f"{type(spec).__name__}({model_type})" if model_type else type(spec).__name__
        if isinstance(convention, str):
            return (
                layout(convention, argument) if tuple(names) == CONVENTIONS.get(convention) else _custom(names, label)
            )
        return Layout(tuple(_split(str(n), default) for n in names), label)
    if isinstance(spec, Sequence) and all(isinstance(n, str) for n in spec):
        return _custom(list(spec), "names")
    raise TypeError(
        f"{argument}: expected a convention name (e.g. 'coco17'), a model with joint_names or a sequence "
        f"of point names, got {type(spec).__name__}"
    )


def _custom(names: list[str], label: str) -> Layout:
    points = tuple(_split(n, None) for n in names)
    return Layout(points, label)


@dataclass(frozen=True)
class Plan:
    """How each destination point is made from the source points.

    Attributes
    ----------
    first, second : (K_dst,) int source indices; the destination point is the mean of the two (they
        are equal for a point taken as is); ``-1`` for a masked point.
    mask : (K_dst,) bool, the points that are available.
    exact : (K_dst,) bool, available and exact (False for approximate pairs and masked points).
    how : (K_dst,) str, ``"exact"``, ``"synthesised"``, ``"approximate"`` or ``"missing"``.
    """

    first: np.ndarray
    second: np.ndarray
    mask: np.ndarray
    exact: np.ndarray
    how: tuple[str, ...]
    src: Layout
    dst: Layout


def _direct(src: Layout, name: str, conv: str | None, exact: bool) -> int | None:
    want_def, want_like = approx.definition(conv, name), approx.like(conv, name)
    best = None
    for i, (sname, sconv) in enumerate(src.points):
        if exact:
            if sname == name and approx.definition(sconv, sname) == want_def:
                return i
        elif approx.like(sconv, sname) == want_like:
            if sname == name:
                return i
            best = i if best is None else best
    return best


def _direct_any(src: Layout, name: str, conv: str | None) -> int | None:
    i = _direct(src, name, conv, exact=True)
    return _direct(src, name, conv, exact=False) if i is None else i


@lru_cache(maxsize=256)
def _plan_cached(src: Layout, dst: Layout, exact_only: bool) -> Plan:
    n = len(dst)
    first, second = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)
    exact, how = np.zeros(n, dtype=bool), ["missing"] * n
    for k, (name, conv) in enumerate(dst.points):
        parts = approx.SYNTHESIS.get((conv, name)) if conv else None
        i = _direct(src, name, conv, exact=True)
        if i is not None:
            first[k] = second[k] = i
            exact[k], how[k] = True, "exact"
            continue
        if parts is not None:
            a, b = (_direct(src, p, conv, exact=True) for p in parts)
            if a is not None and b is not None:
                first[k], second[k], exact[k], how[k] = a, b, True, "synthesised"
                continue
        if exact_only:
            continue
        if parts is not None:
            a, b = (_direct_any(src, p, conv) for p in parts)
            if a is not None and b is not None:
                first[k], second[k], how[k] = a, b, "approximate"
                continue
        i = _direct(src, name, conv, exact=False)
        if i is not None:
            first[k] = second[k] = i
            how[k] = "approximate"
    return Plan(first, second, first >= 0, exact, tuple(how), src, dst)


def plan(src: Any, dst: Any, exact_only: bool = False) -> Plan:
    """The :class:`Plan` that :func:`convert` follows from ``src`` to ``dst`` (see there)."""
    return _plan_cached(layout(src, "src"), layout(dst, "dst"), bool(exact_only))


def _is_torch(x: Any) -> bool:
    return type(x).__module__.split(".")[0] == "torch"


def convert(points: Any, src: Any, dst: Any, exact_only: bool = False) -> tuple[Any, Any]:
    """Keypoints ``points`` of convention ``src`` rearranged into convention ``dst``, by name.

    Each destination point is taken from the source point of the same name when both conventions
    define it the same way. Where the destination defines a point exactly as the midpoint of two
    others (OpenPose's ``neck`` of the shoulders, ``mid_hip`` of the hips) and the source has those,
    it is synthesised. Otherwise, unless ``exact_only``, a source point that approximates the same
    vocabulary point is used (COCO hips from SMPL hips, SMPL's pelvis from OpenPose's mid-hip; see
    :mod:`smplcore.keypoints.approximate`). Anything else is zero and masked.

    Parameters
    ----------
    points : (..., K_src, D) NumPy array or torch tensor, any D (x, y, confidence; x, y, z; ...).
        Synthesised points average all D channels of the two inputs (a confidence too).
    src, dst : convention names (``"coco17"``), models (their ``joint_names``: a smplcore torch
        module or :class:`smplcore.BodyModel`), or sequences of point names.
    exact_only : mask approximate pairs too.

    Returns
    -------
    out : (..., K_dst, D), same type, dtype and device as ``points`` (NumPy integers become float64 when a
        point is synthesised); masked points are zero.
    mask : (K_dst,) bool (a NumPy array, or a torch tensor on the points' device), True where a
        point was available.
    """
    p = plan(src, dst, exact_only)
    shape = tuple(points.shape)
    if len(shape) < 2 or shape[-2] != len(p.src):
        raise ShapeError(
            f"points: expected shape (..., {len(p.src)}, D) for src {p.src.label} with {len(p.src)} points, got {shape}"
        )
    first = np.where(p.mask, p.first, 0)
    synth = np.flatnonzero(p.mask & (p.first != p.second))
    missing = not bool(p.mask.all())
    if _is_torch(points):
        import torch

        def take(rows: np.ndarray) -> Any:
            return points.index_select(-2, torch.as_tensor(rows, dtype=torch.long, device=points.device))

        out = take(first)
        if synth.size:
            half = 0.5 * (out + take(np.where(p.mask, p.second, 0)))
            is_synth = np.zeros(len(first), dtype=bool)
            is_synth[synth] = True
            out = torch.where(torch.as_tensor(is_synth, device=points.device)[:, None], half, out)
        mask = torch.as_tensor(p.mask, device=points.device)
        if missing:
            out = out.masked_fill(~mask[:, None], 0)
        return out, mask
    arr = np.asarray(points)
    out = np.take(arr, first, axis=-2)
    if synth.size:
        if out.dtype.kind != "f":
            out = out.astype(np.float64)
        out[..., synth, :] = 0.5 * (np.take(arr, p.first[synth], axis=-2) + np.take(arr, p.second[synth], axis=-2))
    if missing:
        out[..., ~p.mask, :] = 0
    return out, p.mask.copy()
