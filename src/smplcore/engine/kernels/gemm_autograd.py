"""A packed product (:mod:`smplcore.engine.kernels.gemm`) as an autograd node (torch only; imported when
gradients are recorded)."""

from __future__ import annotations

import torch

from smplcore.engine.kernels.gemm import product


class _PackedProduct(torch.autograd.Function):
    @staticmethod
    def forward(ctx, a: torch.Tensor, packed: torch.Tensor, packed_t: torch.Tensor) -> torch.Tensor:
        ctx.packed_t = packed_t
        return product(a, packed)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        return product(grad.contiguous(), ctx.packed_t), None, None


def packed_product(a: torch.Tensor, packed: torch.Tensor, packed_t: torch.Tensor) -> torch.Tensor:
    """``a @ matrix`` for ``packed = pack(matrix)``, ``packed_t = pack(matrix.T)``; differentiable in ``a``."""
    return _PackedProduct.apply(a, packed, packed_t)
