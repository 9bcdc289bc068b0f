"""Which kernel runs a forward call: decided here, once per call, from the arrays and the caller's request.

:func:`plan` returns a :class:`Plan` that the forward follows; nothing below it decides again.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

from smplcore.engine.backend import SMALL_BATCH, is_torch

#: The kernels a caller may ask for (``"auto"`` lets :func:`select` choose).
KERNELS = ("auto", "blocked", "autograd", "reference")


def check_kernel(kernel: str) -> str:
    """``kernel`` if it names a kernel, else a ValueError naming the choices."""
    if kernel not in KERNELS:
        raise ValueError(f"kernel: expected one of {', '.join(map(repr, KERNELS))}, got {kernel!r}")
    return kernel


def traced() -> bool:
    """Whether torch is tracing the call (``torch.compile``, ``torch.export``) or running it under a
    ``torch.func`` transform (``vmap``, ``grad``, ``jacrev``, ...): then only plain tensor code may run."""
    torch = sys.modules.get("torch")
    if torch is None:
        return False
    compiler = getattr(torch, "compiler", None)
    if compiler is not None and (compiler.is_compiling() or getattr(compiler, "is_exporting", lambda: False)()):
        return True
    functorch_active = getattr(torch._C, "_are_functorch_transforms_active", None)
    return bool(functorch_active is not None and functorch_active())


def compiling_only() -> bool:
    """Whether ``torch.compile`` traces the call, outside ``torch.export`` and ``torch.func``: the fast
    kernels then run as custom operators (:mod:`smplcore.engine.kernels.ops`)."""
    torch = sys.modules.get("torch")
    if torch is None or not torch.compiler.is_compiling():
        return False
    if getattr(torch.compiler, "is_exporting", lambda: False)():
        return False
    functorch_active = getattr(torch._C, "_are_functorch_transforms_active", None)
    return not (functorch_active is not None and functorch_active())


def select(kernel: str, like: Any, *, gradients: bool, trainable_model: bool = False) -> str:
    """The kernel to run.

    Parameters
    ----------
    kernel : ``"auto"`` or a forced kernel from :data:`KERNELS`.
    like : an input array (its namespace, device and dtype decide).
    gradients : whether autograd records this call.
    trainable_model : whether the model's own arrays require gradients (only the reference
        kernel differentiates with respect to them).

    A forced kernel that cannot compute what was asked raises instead of running another one.
    """
    check_kernel(kernel)
    plain_only = is_torch(like) and (
        (traced() and not compiling_only()) or like.device.type != "cpu" or not _cpu_float(like)
    )
    if kernel == "auto":
        if plain_only or trainable_model:
            return "reference"
        return "autograd" if gradients else "blocked"
    if kernel == "blocked" and gradients:
        raise ValueError(
            "kernel='blocked' records no gradients, but this call needs them; use kernel='autograd' "
            "or 'auto', or call under torch.no_grad()"
        )
    if kernel == "autograd" and not is_torch(like):
        raise ValueError("kernel='autograd' is for torch tensors; NumPy inputs run kernel='blocked' or 'reference'")
    if kernel in ("blocked", "autograd") and plain_only:
        raise ValueError(
            f"kernel={kernel!r} runs on CPU float32/float64 tensors outside torch.export and "
            f"torch.func; this call needs kernel='reference' (or 'auto')"
        )
    if kernel != "reference" and trainable_model:
        raise ValueError(
            f"kernel={kernel!r} does not differentiate with respect to the model's own arrays "
            "(some require gradients); use kernel='reference' or 'auto'"
        )
    return kernel


@dataclass(frozen=True)
class Plan:
    """How one forward call runs, decided once by :func:`plan`.

    Attributes
    ----------
    kernel : ``"blocked"``, ``"autograd"`` or ``"reference"`` (see :data:`KERNELS`).
    operators : under ``torch.compile``: the fast kernels run as custom torch operators
        (:mod:`smplcore.engine.kernels.ops`).
    host_skeleton : a small CPU torch batch that autograd does not record: the per-joint math (Rodrigues, the
        kinematic chain) runs in NumPy on the same memory (a quarter of torch's per-operation overhead).
    """

    kernel: str
    operators: bool = False
    host_skeleton: bool = False


def plan(
    kernel: str,
    like: Any,
    *,
    gradients: bool,
    trainable_model: bool = False,
    batch: int = 1,
    operator_arrays: bool = True,
    skinning: str = "lbs",
) -> Plan:
    """The :class:`Plan` of one call: :func:`select`'s kernel, and how it runs.

    ``operator_arrays``: the model's arrays are known to the custom operators (torch modules); without them, or
    with dual-quaternion skinning (no operator), a compiled call runs the plain pass (the same numbers).
    """
    chosen = select(kernel, like, gradients=gradients, trainable_model=trainable_model)
    operators = chosen != "reference" and traced()
    if operators and (not operator_arrays or skinning != "lbs"):
        chosen, operators = "reference", False
    host = (
        chosen != "reference"
        and not operators
        and not gradients
        and is_torch(like)
        and like.device.type == "cpu"
        and _cpu_float(like)
        and batch <= SMALL_BATCH
    )
    return Plan(chosen, operators, bool(host))


def _cpu_float(x: Any) -> bool:
    torch = sys.modules["torch"]
    return x.dtype in (torch.float32, torch.float64)
