"""Keyword parameters of a forward call, checked and laid out as the engine takes them.

Accepted layouts, and nothing else (a wrong layout is an error naming the argument):

* coefficients (``betas``, ``expression``, PCA hand poses): (B, n), or (n,) for one body;
* axis-angle pose blocks: (B, 3 n), (B, n, 3), or (3 n,) for one body;
* rotation matrices (``pose2rot=False``, Layer classes): (B, n, 3, 3), (B, 9 n), and (B, 3, 3) for a
  one-joint block;
* ``transl``: (B, 3) or (3,).

Batch 1 broadcasts to the batch of the other parameters; batch 0 gives empty outputs.

Values are checked to be finite (the first bad index is named) unless ``check_finite=False``; the check
is skipped where it would cost a device round trip or cannot be traced (non-CPU tensors, ``torch.compile``).
Rotation matrices can be checked to be rotations (``check_rotations``).
"""

from __future__ import annotations

import sys
from typing import Any

from smplcore.engine.backend import is_torch, namespace
from smplcore.errors import ShapeError


def batch_of(params: dict[str, Any]) -> int:
    """The batch size of a call: the largest leading size among the given (batched) parameters, or 0
    when one of them is empty."""
    batch = 1
    for value in params.values():
        if value is not None and value.ndim > 1 and value.shape[0] > batch:
            batch = value.shape[0]
    if any(v is not None and v.ndim > 1 and v.shape[0] == 0 for v in params.values()):
        batch = 0
    for name, value in params.items():
        if value is not None and value.ndim > 1 and value.shape[0] not in (1, batch):
            sizes = {k: v.shape[0] for k, v in params.items() if v is not None and v.ndim > 1}
            raise ShapeError(
                f"{name}: batch size {value.shape[0]} does not match the batch size {batch} of the other "
                f"parameters (sizes: {sizes}); give 1 or {batch}"
            )
    return batch


def rows(name: str, value: Any, batch: int, width: int, *, allow_narrower: bool = False, joints: int = 0) -> Any:
    """``value`` as (batch, width): 1-D is one body, batch 1 broadcasts, narrower coefficients are zero-padded.

    ``joints`` > 0 marks an axis-angle block of that many joints, which may also be given as (B, joints, 3).
    """
    xp = namespace(value)
    if value.ndim == 0:
        raise ShapeError(f"{name}: expected shape {_layouts(width, allow_narrower, joints)}, got a scalar")
    if value.ndim == 1:
        value = value[None]
    if value.ndim == 3 and joints and tuple(value.shape[1:]) == (joints, 3):
        value = value.reshape(value.shape[0], 3 * joints)
    if value.ndim != 2:
        raise ShapeError(f"{name}: expected shape {_layouts(width, allow_narrower, joints)}, got {tuple(value.shape)}")
    n = value.shape[1]
    if n != width and not (allow_narrower and n < width):
        hint = ""
        if name == "body_pose" and n == width + 3:
            hint = (
                f"; {n} = global_orient (3) + body_pose ({width}): "
                "pass global_orient=pose[:, :3], body_pose=pose[:, 3:]"
            )
        elif name.endswith("hand_pose") and n == 45 and width < 45:
            hint = " (PCA coefficients; use_pca=False for 45 axis-angle values)"
        elif name.endswith("hand_pose") and width == 45 and n < 45:
            hint = " (axis-angle; use_pca=True takes PCA coefficients)"
        elif name == "body_pose" and (n, width) == (63, 69):
            hint = (
                "; 63 values are 21 body joints (SMPL+H / SMPL-X); this model has 23 (SMPL's, the last two the "
                "hands): append 6 zeros, or use a model with 21 body joints (model_type='smplh' or 'smplx')"
            )
        elif name == "body_pose" and (n, width) == (69, 63):
            hint = (
                "; 69 values are SMPL's 23 body joints; this model has 21 (its hands are separate blocks): "
                "body_pose=pose[:, :63] drops SMPL's two hand joints"
            )
        elif name in ("betas", "expression") and allow_narrower and n > width:
            option = "num_betas" if name == "betas" else "num_expression_coeffs"
            hint = (
                f"; the model was made with {option}={width}: make it with {option}={n} (e.g. "
                f"BodyModel(..., {option}={n})) if its file holds that many"
            )
        raise ShapeError(
            f"{name}: expected shape {_layouts(width, allow_narrower, joints)}, got {tuple(value.shape)}{hint}"
        )
    if n < width:  # narrower coefficients: the one rule of smplcore.model.params (zero-padded)
        from smplcore.model.params import fit_width

        value = fit_width(name, value, width, from_file=False)
    if value.shape[0] != batch:
        value = xp.broadcast_to(value, (batch, width))
    return value


def _layouts(width: int, allow_narrower: bool, joints: int) -> str:
    text = f"(B, {'<=' if allow_narrower else ''}{width})"
    return f"{text} or (B, {joints}, 3)" if joints else text


def rotmat_rows(name: str, value: Any, batch: int, joints: int) -> Any:
    """``value`` as (batch, joints, 3, 3) from (B, n, 3, 3), (B, 9 n) or, for one joint, (B, 3, 3)."""
    xp = namespace(value)
    if value.ndim == 3 and joints == 1 and tuple(value.shape[1:]) == (3, 3):
        value = value[:, None]
    elif value.ndim == 2 and value.shape[1] == 9 * joints:
        value = value.reshape(value.shape[0], joints, 3, 3)
    if value.ndim < 2 or value.ndim != 4 or tuple(value.shape[1:]) != (joints, 3, 3):
        raise ShapeError(f"{name}: expected rotation matrices of shape (B, {joints}, 3, 3), got {tuple(value.shape)}")
    if value.shape[0] != batch:
        value = xp.broadcast_to(value, (batch, joints, 3, 3))
    return value


def _NUMPY_FLOATS() -> tuple:  # noqa: N802
    torch = sys.modules["torch"]
    return (torch.float32, torch.float64)


def check_finite(params: dict[str, Any]) -> None:
    """A ValueError naming the first parameter holding NaN or inf, and the first such index."""
    for name, value in params.items():
        if value is None or value.ndim == 0 or value.shape[0] == 0:
            continue
        host = value
        if is_torch(value) and value.device.type == "cpu" and value.dtype in _NUMPY_FLOATS():
            host = value.detach().numpy()  # NumPy: a fraction of torch's per-call overhead
        xp = namespace(host)
        finite = xp.isfinite(host)  # (NumPy for CPU tensors: a fraction of torch's per-call overhead)
        if not bool(finite.all()):
            bad = tuple(int(i) for i in xp.argwhere(~finite)[0])
            raise ValueError(
                f"{name}: non-finite value {host[bad]} at index {bad}; the outputs would be NaN "
                f"(check_finite=False skips this check)"
            )


def check_rotations(name: str, rotmats: Any, tol: float = 1e-3) -> None:
    """A ValueError unless every (..., 3, 3) matrix is a rotation: orthonormal with determinant +1 (within ``tol``)."""
    if rotmats.shape[0] == 0:
        return
    xp = namespace(rotmats)
    eye = (
        xp.eye(3, dtype=rotmats.dtype)
        if xp.__name__ == "numpy"
        else xp.eye(3, dtype=rotmats.dtype, device=rotmats.device)
    )
    err = xp.abs(rotmats.mT @ rotmats - eye).reshape(*rotmats.shape[:-2], 9).max(axis=-1)
    if xp.__name__ == "torch":
        err = err.values if hasattr(err, "values") else err
    det = xp.linalg.det(rotmats)
    bad = (err > tol) | (xp.abs(det - 1) > tol)
    if bool(bad.any()):
        index = tuple(int(i) for i in xp.argwhere(bad)[0])
        raise ValueError(
            f"{name}: the matrix at index {index} is not a rotation (|RᵀR - I| = {float(err[index]):.3g}, "
            f"det = {float(det[index]):.3g}); pose2rot=False takes rotation matrices"
        )
