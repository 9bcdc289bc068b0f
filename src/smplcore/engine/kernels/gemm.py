"""Products with a constant right operand (a model's bases and skinning weights), prepared once.

Where PyTorch has oneDNN (x86 CPU builds), a float32 CPU matrix is repacked once into oneDNN's
blocked layout, and every later ``a @ matrix`` runs oneDNN's kernels on it. ``torch.mm`` calls MKL,
which runs its AVX2 kernels on AMD CPUs: on an AMD EPYC with AVX-512 (bench/RESULTS.md), oneDNN is
2-3x faster for the SMPL-X blend product at B = 512 and up to 4x for a few bodies (Intel CPUs, where
MKL runs its AVX-512 kernels, were not measured against it). Elsewhere (NumPy, float64, GPUs, torch
without oneDNN) there is nothing to pack and callers use a plain product.

The packed products are for inference: they record no autograd graph (see
:func:`product_with_gradients` for the node that does).

oneDNN allocates each product's output (there is no ``out=``): 1-16 MB per vertex block. glibc serves
such a request with a fresh ``mmap`` (page-faulted 4 KiB at a time: up to a third of a forward pass)
unless a larger block was freed before, which raises its dynamic mmap threshold; the first
:func:`pack` therefore allocates and frees one untouched 24 MiB block, as any program with a large
temporary would (no memory is touched or kept; a threshold set with ``mallopt`` or
``MALLOC_MMAP_THRESHOLD_`` disables the dynamic one and is left as it is).
"""

from __future__ import annotations

import os
import sys
from typing import Any

from smplcore.engine.backend import is_torch
from smplcore.errors import warn

# SMPLCORE_ONEDNN=0 turns packing off (plain torch.mm everywhere), e.g. to compare the two.
_ENV = "SMPLCORE_ONEDNN"
# Above the products' outputs, below glibc's cap on the dynamic threshold (32 MiB on 64-bit).
_NUDGE_BYTES = 24 << 20
_malloc_nudged = False
_checked: dict[str, bool] = {}


def available(like: Any) -> bool:
    """Whether :func:`pack` applies to matrices like ``like`` (a float32 CPU torch tensor, oneDNN present
    and checked to work)."""
    if not is_torch(like) or os.environ.get(_ENV, "1") == "0":
        return False
    torch = sys.modules["torch"]
    return like.device.type == "cpu" and like.dtype == torch.float32 and _onednn_works()


def _onednn_works() -> bool:
    """Whether torch's private oneDNN ops exist and compute a product right: checked once per process on a
    small matrix; where they fail, one warning and the plain products from then on."""
    if "onednn" not in _checked:
        torch = sys.modules["torch"]
        ops = getattr(torch.ops, "mkldnn", None)
        ok = False
        reason = None  # a build without oneDNN: nothing to warn about
        if (
            torch.backends.mkldnn.is_available()
            and ops is not None
            and hasattr(ops, "_linear_pointwise")
            and hasattr(ops, "_reorder_linear_weight")
        ):
            try:
                a = torch.arange(12, dtype=torch.float32).reshape(3, 4) / 7
                b = torch.arange(20, dtype=torch.float32).reshape(4, 5) / 3
                with torch.no_grad():
                    packed = ops._reorder_linear_weight(b.T.contiguous())
                    ok = bool(
                        torch.allclose(
                            ops._linear_pointwise(a, packed, None, "none", [], ""), a @ b, rtol=1e-5, atol=1e-5
                        )
                    )
                reason = "torch's oneDNN packed product gave a wrong result on a check"
            except Exception as exc:  # any failure of a private op means: don't use it
                reason = f"torch's oneDNN packed product failed on a check ({type(exc).__name__}: {exc})"
        if not ok and reason is not None:
            warn(f"smplcore: {reason}; using plain torch.mm products ({_ENV}=0 skips the check)", RuntimeWarning)
        _checked["onednn"] = ok
    return _checked["onednn"]


def pack(matrix: Any) -> Any | None:
    """``matrix`` (K, N), packed for :func:`product`; None where packing does not apply."""
    if not available(matrix):
        return None
    torch = sys.modules["torch"]
    global _malloc_nudged
    if not _malloc_nudged:
        torch.empty(_NUDGE_BYTES // 4, dtype=torch.float32)  # allocated and freed at once, never touched
        _malloc_nudged = True
    with torch.no_grad():
        return torch.ops.mkldnn._reorder_linear_weight(matrix.detach().T.contiguous())


def product(a: Any, packed: Any) -> Any:
    """(M, N) ``a @ matrix`` for (M, K) ``a`` (float32, CPU) and ``packed = pack(matrix)``: a new tensor."""
    return sys.modules["torch"].ops.mkldnn._linear_pointwise(a, packed, None, "none", [], "")


def product_with_gradients(a: Any, packed: Any, packed_t: Any) -> Any:
    """:func:`product` as an autograd node, differentiable in ``a``: ``packed_t`` is the matrix's
    transpose, packed (the backward is ``grad @ matrix.T``)."""
    from smplcore.engine.kernels.gemm_autograd import packed_product

    return packed_product(a, packed, packed_t)
