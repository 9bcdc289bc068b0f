"""``measure``: anthropometric measurements of a body model (rest pose or posed) or of a mesh."""

from __future__ import annotations

from typing import Any

import numpy as np

from smplcore.measure._rig import _rig_of
from smplcore.measure.definitions import DEFAULT_DENSITY, Body, check_names, measure_body

__all__ = ["measure", "measure_mesh", "rest_body", "body_of"]


def _regressor_rows(regressor: np.ndarray, names: tuple[str, ...]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    out = {}
    for name, row in zip(names, regressor):
        cols = np.flatnonzero(np.abs(row) > 1e-12)
        out[name] = (cols, row[cols])
    return out


def _rows_cache(rig: Any) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    key = id(rig)
    hit = _ROWS.get(key)
    if hit is None or hit[0] is not rig:
        hit = (rig, _regressor_rows(np.asarray(rig.joint_regressor, dtype=np.float64), tuple(rig.joint_names)))
        _ROWS.clear()
        _ROWS[key] = hit
    return hit[1]


_ROWS: dict[int, tuple[Any, dict]] = {}


def rest_body(model: Any, betas: np.ndarray | None = None, *, density: float = DEFAULT_DENSITY) -> Body:
    """The model's body in the rest pose for ``betas`` (num_betas,) (zeros if None), ready to measure."""
    rig = _rig_of(model)
    b = np.zeros(rig.num_betas) if betas is None else np.asarray(betas, dtype=np.float64).reshape(-1)
    nb = min(len(b), rig.num_betas)
    if len(b) > rig.num_betas and np.any(b[nb:]):
        raise ValueError(f"betas: the model takes {rig.num_betas} shape coefficients, got {len(b)}")
    v = np.asarray(rig.template, dtype=np.float64) + np.asarray(rig.shapedirs)[:, :, :nb] @ b[:nb]
    reg = np.asarray(rig.joint_regressor, dtype=np.float64)
    joints = dict(zip(rig.joint_names, reg @ v))
    return Body(v, np.asarray(rig.faces), joints, regressor=_rows_cache(rig), density=density)


def body_of(
    vertices: np.ndarray, faces: np.ndarray, joints: np.ndarray | dict, joint_names: Any = None, **kw: Any
) -> Body:
    """A :class:`Body` from vertices (V, 3), faces (F, 3) and joints: a dict name -> (3,) or an array
    (J, 3) in the SMPL order (or ``joint_names``)."""
    if not isinstance(joints, dict):
        from smplcore.family.names import SMPL_JOINTS

        j = np.asarray(joints, dtype=np.float64)
        names = tuple(joint_names) if joint_names is not None else SMPL_JOINTS
        joints = dict(zip(names, j[: len(names)]))
    return Body(np.asarray(vertices, dtype=np.float64), np.asarray(faces), joints, **kw)


def measure_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    joints: np.ndarray | dict,
    *,
    names: Any = None,
    density: float = DEFAULT_DENSITY,
) -> dict[str, float]:
    """Measurements of one mesh: ``vertices`` (V, 3) upright along +Y, ``faces`` (F, 3) and ``joints``
    (J, 3) in SMPL order (the first 22 are used) or a dict name -> (3,). See :data:`UNITS`."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices: expected (V, 3), got shape {v.shape}")
    body = body_of(v, faces, joints, density=density)
    return {k: x.value for k, x in measure_body(body, check_names(names)).items()}


def _posed(model: Any, betas: np.ndarray, pose: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and joints (J, 3) of the model's forward for one body."""
    rig = _rig_of(model)
    if hasattr(model, "parameters") and hasattr(model, "forward"):  # a torch module
        import torch

        dtype = next(iter(model.buffers())).dtype if any(True for _ in model.buffers()) else torch.float32
        kw = {k: torch.as_tensor(np.asarray(v, dtype=np.float64)[None], dtype=dtype) for k, v in pose.items()}
        out = model(betas=torch.as_tensor(betas[None], dtype=dtype), **kw)
        v, j = out.vertices[0].detach().cpu().numpy(), out.joints[0].detach().cpu().numpy()
    else:
        out = model(betas=betas[None], **{k: np.asarray(v)[None] for k, v in pose.items()})
        v, j = out.vertices[0], out.joints[0]
    return np.asarray(v, dtype=np.float64), np.asarray(j, dtype=np.float64)[: len(rig.joint_names)]


def measure(
    model: Any,
    betas: np.ndarray | None = None,
    *,
    names: Any = None,
    density: float = DEFAULT_DENSITY,
    **pose: Any,
) -> dict[str, Any]:
    """Anthropometric measurements of a body model's bodies.

    Parameters
    ----------
    model : a :class:`smplcore.BodyModel` or a torch module from :func:`smplcore.create` (any model of
        the family with the SMPL body joints: SMPL, SMPL+H, SMPL-X, the open model).
    betas : (num_betas,) one body or (B, num_betas) a batch; None for the mean shape.
    names : the measurements to take (default all of :data:`MEASUREMENTS`).
    density : kg/m³ for the mass (default :data:`DEFAULT_DENSITY`).
    **pose : pose keywords of the model's forward (``body_pose=``, ``global_orient=``, ... one body's
        values, unbatched) to measure the posed body; by default the rest pose (shape blend only), where
        the standards' upright, horizontal-plane definitions hold. A posed body keeps the axilla level of
        its rest pose (arms that hang down do not move the trunk's planes); limb girths follow the limbs.

    Returns
    -------
    dict name -> float for one body, or name -> (B,) array for a batch. Units in :data:`UNITS`.
    """
    rig = _rig_of(model)
    chosen = check_names(names)
    b = np.zeros((1, rig.num_betas)) if betas is None else np.asarray(betas, dtype=np.float64)
    single = b.ndim == 1
    b = np.atleast_2d(b)
    if b.ndim != 2:
        raise ValueError(f"betas: expected (num_betas,) or (B, num_betas), got shape {b.shape}")
    if b.shape[1] < rig.num_betas:
        b = np.pad(b, ((0, 0), (0, rig.num_betas - b.shape[1])))
    rows = []
    for one in b:
        if pose:
            v, j = _posed(model, one, pose)
            body = Body(v, np.asarray(rig.faces), dict(zip(rig.joint_names, j)), density=density)
            rest = rest_body(model, one, density=density)
            body.set_armpit(rest.armpit)  # the axilla of the standard posture (arms may hang in the pose)
        else:
            body = rest_body(model, one, density=density)
        rows.append({k: x.value for k, x in measure_body(body, chosen).items()})
    if single or (betas is None):
        return rows[0]
    return {k: np.array([r[k] for r in rows]) for k in chosen}
