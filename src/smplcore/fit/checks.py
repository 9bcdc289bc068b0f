"""Checks of the fitting functions' options and results, so that a fit never returns what it did not find.

* Option values: weights are finite and non-negative, scales positive, counts integers in range, ``anneal``
  a non-empty sequence of such weights; errors name the argument, the expectation and the value.
* Units: targets whose size is far from the model's (joints in millimetres, a scene in centimetres) are
  refused before fitting (:func:`check_scale`): a fit would "converge" to a giant, or a dot, far away.
* Results: a fit whose parameters or errors are not finite raises :class:`FitError` (never returned);
  bodies left far from their targets (an error of the order of their own size) are flagged not converged,
  with one warning (:func:`flag_gross`), whatever the solver's stopping test said.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

from smplcore.errors import warn

#: Targets spanning more than this factor times the model's size (or less than its inverse) are refused.
SCALE_FACTOR = 10.0
#: A body whose mean error exceeds this fraction of its targets' spread is flagged not converged.
GROSS_FRACTION = 0.5


class FitError(ValueError):
    """A fit produced non-finite parameters or errors (the inputs are beyond what the solver handles)."""


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__} ({value!r})")
    return float(value)


def weight(name: str, value: Any) -> float:
    """``value`` as a finite non-negative float (a prior or term weight)."""
    out = _number(name, value)
    if not np.isfinite(out) or out < 0:
        raise ValueError(f"{name}: expected a finite non-negative weight, got {value!r}")
    return out


def positive(name: str, value: Any) -> float:
    """``value`` as a finite positive float (a scale, a tolerance)."""
    out = _number(name, value)
    if not np.isfinite(out) or out <= 0:
        raise ValueError(f"{name}: expected a finite positive number, got {value!r}")
    return out


def count(name: str, value: Any, minimum: int = 0, maximum: int | None = None) -> int:
    """``value`` as an int in ``[minimum, maximum]``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__} ({value!r})")
    out = int(value)
    if out < minimum or (maximum is not None and out > maximum):
        bound = f">= {minimum}" if maximum is None else f"in {minimum}..{maximum}"
        raise ValueError(f"{name}: expected an integer {bound}, got {out}")
    return out


def workers(value: Any) -> int | None:
    """None (one thread per core) or a positive thread count."""
    return None if value is None else count("workers", value, 1, 4096)


def factors(name: str, value: Any) -> tuple[float, ...]:
    """A non-empty sequence of finite non-negative multipliers (``anneal``)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence | np.ndarray):
        raise TypeError(f"{name}: expected a sequence of numbers such as (3.0, 1.0), got {type(value).__name__}")
    out = tuple(weight(f"{name}[{i}]", v.item() if isinstance(v, np.generic) else v) for i, v in enumerate(value))
    if not out:
        raise ValueError(f"{name}: expected at least one multiplier, such as (3.0, 1.0); got an empty sequence")
    return out


def options(kind: str, values: dict[str, Any]) -> dict[str, Any]:
    """``values`` checked as ``kind`` (``"weight"``, ``"positive"``, ``"iterations"``), each named by its key."""
    check = {"weight": weight, "positive": positive, "iterations": lambda n, v: count(n, v, 0, 100_000)}[kind]
    return {k: check(k, v) for k, v in values.items()}


def init_params(init: Any, body: Any) -> dict[str, Any] | None:
    """``init`` (None or a dict of forward keywords of the fitted model), checked: unknown keys are refused."""
    if init is None:
        return None
    if not isinstance(init, dict):
        raise TypeError(f"init: expected a dict of forward keywords (or None), got {type(init).__name__}")
    known = {b.name for b in body.blocks} | {"betas", "expression", "transl"}
    unknown = sorted(str(k) for k in init if k not in known)
    if unknown:
        raise ValueError(f"init: {unknown} are not parameters of this model (expected some of {sorted(known)})")
    return init


def nonempty_batch(name: str, batch: int) -> None:
    if batch == 0:
        raise ValueError(f"{name}: an empty batch (0 bodies); give at least one body")


def _spread(points: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(B,) RMS distance of the points with ``mask`` from their centroid."""
    m = mask[..., None].astype(np.float64)
    n = np.maximum(m.sum(1), 1)
    centre = (points * m).sum(1) / n
    return np.sqrt((((points - centre[:, None]) ** 2).sum(-1) * mask).sum(1) / n[:, 0])


def check_scale(name: str, targets: np.ndarray, rest: np.ndarray, mask: np.ndarray, unit: str = "m") -> None:
    """Refuse (B, n, 3) ``targets`` whose spread is over :data:`SCALE_FACTOR` times (or under its inverse)
    the spread of the model's (n, 3) ``rest`` points (the same points of the rest body), over ``mask``."""
    if targets.size == 0 or not mask.any():
        return
    model = float(_spread(rest[None], mask[:1] if mask.shape[0] else mask)[0])
    if model <= 0:
        return
    spread = _spread(targets, mask)
    ratio = spread / model
    bad = np.flatnonzero((ratio > SCALE_FACTOR) | (ratio < 1 / SCALE_FACTOR))
    if bad.size:
        b = int(bad[0])
        hint = (
            " (millimetres? the fit expects metres)"
            if ratio[b] > 300
            else " (centimetres? the fit expects metres)"
            if ratio[b] > 30
            else " (all at one place?)"
            if ratio[b] < 1e-6
            else ""
        )
        raise ValueError(
            f"{name}: body {b} spans {spread[b]:.4g} {unit} around its centre, {ratio[b]:.3g} times the model's "
            f"{model:.3g} {unit}{hint}; {len(bad)} of {len(ratio)} bodies are off by more than {SCALE_FACTOR:g}x"
        )


def flag_gross(converged: np.ndarray, error: np.ndarray, spread: np.ndarray, what: str, unit: str) -> np.ndarray:
    """``converged`` with the bodies whose ``error`` exceeds :data:`GROSS_FRACTION` of their targets'
    ``spread`` set to False, and one warning naming them."""
    gross = error > GROSS_FRACTION * spread
    if not gross.any():
        return converged
    bad = np.flatnonzero(gross)
    b = int(bad[0])
    warn(
        f"{what}: {len(bad)} of {len(error)} bodies stay far from their targets (body {b}: mean error "
        f"{error[b]:.4g} {unit} for targets spanning {spread[b]:.4g} {unit}); they are flagged not converged "
        "(wrong units, camera or convention?)"
    )
    out = np.asarray(converged, bool).copy()
    out[gross] = False
    return out


def spread_of(targets: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(B,) RMS distance of each body's masked (B, n, d) targets from their centroid."""
    return _spread(targets, mask)


def finite_result(result: Any, what: str) -> Any:
    """``result`` (a FitResult) if its parameters and errors are finite, else :class:`FitError` naming the
    bodies."""
    bad = np.zeros(0, bool)
    arrays = [np.asarray(v.detach().cpu().numpy() if hasattr(v, "detach") else v) for v in result.params.values()]
    for name in ("vertex_error", "joint_error", "reprojection_error"):
        value = getattr(result, f"_{name}", None) if name != "reprojection_error" else result.reprojection_error
        if value is not None:
            arrays.append(np.asarray(value))
    for a in arrays:
        if a.ndim == 0 or a.shape[0] == 0:
            continue
        rows = ~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
        bad = rows if bad.size == 0 else bad | rows
    if bad.any():
        which = np.flatnonzero(bad)
        raise FitError(
            f"{what}: the fit of bodies {which.tolist()[:10]} ({len(which)} of {len(bad)}) came out non-finite; "
            "check the targets' units and size, the camera and the option values"
        )
    return result
