"""The fast implementations of the forward pass, and the one place that chooses among them.

* ``blocked`` — inference: blend shapes and skinning fused over blocks of vertices (NumPy, torch).
* ``autograd`` — torch training on the CPU: the blend product and the skinning as single autograd nodes.
* ``reference`` — :mod:`smplcore.engine.reference`, the plain forward: runs under ``torch.compile`` /
  ``torch.export``, ``torch.func`` transforms and on GPUs, and wherever the others do not apply.

:func:`select` decides; a caller may force a kernel (``kernel=``), which then runs or raises.
"""

from smplcore.engine.kernels.select import KERNELS, select

__all__ = ["KERNELS", "select"]
