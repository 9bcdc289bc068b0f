"""The parameter layout of a model, and the one rule for coefficients whose count differs from the model's.

**The coefficient rule** (``betas``, ``expression``, ``dmpls``), stated once and used by every caller:

* fewer coefficients than the model takes: the missing ones are zero (exact: a component left out is zero);
* more than the model takes: in a forward call (``from_file=False``) an error naming the argument (the caller
  asked for components the model does not have); read from a file (a motion, parameters to export) the extra
  ones are dropped, with a warning (and a note, when the caller collects notes) if any dropped value is non-zero,
  naming the argument, both counts and the largest dropped value.

The forward's own checks (batch, finite values, rotations) are in :mod:`smplcore.frontend.inputs`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.engine.backend import namespace
from smplcore.errors import ShapeError, warn

__all__ = ["COEFFICIENTS", "fit_width", "option_of"]

#: The coefficient parameters and the model option that sets their count.
COEFFICIENTS = {"betas": "num_betas", "expression": "num_expression_coeffs", "dmpls": "num_dmpls"}


def option_of(name: str) -> str:
    """The constructor option that sets the count of coefficient ``name`` (``num_betas`` for ``betas``)."""
    return COEFFICIENTS.get(name, f"num_{name}")


def fit_width(name: str, value: Any, width: int, *, from_file: bool = True, notes: list[str] | None = None) -> Any:
    """``value`` (..., n) as (..., ``width``) by the coefficient rule of this module (NumPy or torch).

    Parameters
    ----------
    name : the argument (``betas``, ``expression``, ``dmpls``), for messages.
    value : (..., n) coefficients.
    width : the model's count.
    from_file : the values were read from a file (extra ones dropped) rather than passed to a call (an error).
    notes : a list the warning is also appended to (the exporters' notes), or None.
    """
    n = int(value.shape[-1])
    if n > width:
        if not from_file:
            raise ShapeError(
                f"{name}: expected shape (B, <={width}), got {tuple(value.shape)}; the model takes {width} "
                f"(create it with {option_of(name)}={n} to use them all)"
            )
        dropped = value[..., width:]
        largest = float(abs(np.asarray(dropped, np.float64)).max()) if dropped.size else 0.0
        if largest != 0.0 and not (name == "betas" and width == 0):  # num_betas=0: dropped on purpose
            message = (
                f"{name}: the input has {n} coefficients but the model takes {width}; dropping the last "
                f"{n - width} (largest |value| {largest:.3g}) -- create the model with {option_of(name)}={n} to "
                "keep them"
            )
            if notes is not None:
                notes.append(message)
            warn(message)
        return value[..., :width]
    if n < width:
        xp = namespace(value)
        pad = xp.zeros_like(value[..., :1])
        return xp.concat([value, *([pad] * (width - n))], axis=-1)
    return value
