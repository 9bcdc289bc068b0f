"""The array namespace the engine runs on: NumPy or PyTorch, told from the arrays themselves.

The engine uses only what both namespaces spell the same way (``einsum``, ``concat``, ``stack``,
``where``, ``sqrt``, ``sin``, ``cos``, ``clip``, ``round``, ``@``, ``.reshape``, ``.mT``, ``axis=`` and
``keepdims=``), plus the few helpers below for the rest. Torch is never imported here.
"""

from __future__ import annotations

import sys
from contextlib import nullcontext
from typing import Any

import numpy as np


def is_torch(x: Any) -> bool:
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(x, torch.Tensor)


def namespace(x: Any) -> Any:
    """``torch`` for a torch tensor, else ``numpy``."""
    return sys.modules["torch"] if is_torch(x) else np


def eye(n: int, like: Any) -> Any:
    """An ``n`` × ``n`` identity with the dtype (and device) of ``like``."""
    if is_torch(like):
        return sys.modules["torch"].eye(n, dtype=like.dtype, device=like.device)
    return np.eye(n, dtype=like.dtype)


def atan2(y: Any, x: Any) -> Any:
    return sys.modules["torch"].atan2(y, x) if is_torch(y) else np.arctan2(y, x)


def index(idx: Any, like: Any) -> Any:
    """Integer index array in the namespace (and on the device) of ``like``."""
    if is_torch(like):
        torch = sys.modules["torch"]
        return torch.as_tensor(np.asarray(idx, dtype=np.int64), device=like.device)
    return np.asarray(idx, dtype=np.int64)


# Up to this batch, per-joint math (Rodrigues, the kinematic chain: dozens of tiny products) runs
# 2-4x faster in NumPy than in torch, whose per-operation overhead dominates at that size.
SMALL_BATCH = 64


def host_numpy(x: Any, max_batch: int | None = SMALL_BATCH) -> np.ndarray | None:
    """A NumPy view of a small torch CPU float tensor that autograd is not recording, else None.

    ``max_batch`` bounds the leading dimension (None: any size). NumPy arrays are returned as they are.
    """
    if isinstance(x, np.ndarray):
        return x
    if not is_torch(x) or x.device.type != "cpu" or (max_batch is not None and x.shape[0] > max_batch):
        return None
    torch = sys.modules["torch"]
    if x.dtype not in (torch.float32, torch.float64) or (x.requires_grad and torch.is_grad_enabled()):
        return None
    return x.detach().numpy()


def array_identity(x: Any) -> tuple:
    """Where an array's data lives (address, dtype, device): a cache key that changes when it moves."""
    if is_torch(x):
        return x.data_ptr(), str(x.dtype), str(x.device)
    return x.__array_interface__["data"][0], x.dtype.str


def from_numpy(x: np.ndarray) -> Any:
    """A torch tensor sharing the memory of ``x``."""
    return sys.modules["torch"].from_numpy(x)


def for_cache() -> Any:
    """A context for creating tensors that are cached across calls: outside torch's inference mode,
    so that a constant first built under ``torch.inference_mode()`` still works in autograd later."""
    torch = sys.modules.get("torch")
    return torch.inference_mode(False) if torch is not None else nullcontext()
