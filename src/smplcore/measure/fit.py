"""``fit_shape``: shape coefficients from measurements by a bounded, regularised Gauss-Newton solve."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear

from smplcore.measure._rig import _rig_of
from smplcore.measure.api import rest_body
from smplcore.measure.definitions import DEFAULT_DENSITY, MEASUREMENTS, measure_body
from smplcore.measure.geometry import Linear

__all__ = ["ShapeFit", "fit_shape", "TOLERANCES"]

#: The scale each residual is divided by before squaring (a measuring tape's tolerance): metres for
#: lengths, kg for mass, kg/m² for BMI, m³ for volume.
TOLERANCES: dict[str, float] = {n: 0.005 for n in MEASUREMENTS} | {"mass": 0.5, "bmi": 0.2, "volume": 5e-4}

_ALIASES = {"height": "stature"}


@dataclass
class ShapeFit:
    """Result of :func:`fit_shape`: ``betas`` (num_betas,) or (B, num_betas); ``measured`` and ``residual``
    (measured − target) per measurement, floats or (B,) arrays; ``iterations`` run per body."""

    betas: np.ndarray
    measured: dict[str, Any]
    residual: dict[str, Any]
    iterations: Any


def _jacobian_row(lin: Linear, shapedirs: np.ndarray) -> np.ndarray:
    """d value / d betas (B,) of a measurement linear in the vertices."""
    if len(lin.rows) == 0:
        return np.zeros(shapedirs.shape[2])
    return np.einsum("kc,kcb->b", lin.weights, shapedirs[lin.rows])


def _fit_one(
    model: Any,
    targets: dict[str, float],
    weights: dict[str, float],
    lower: np.ndarray,
    upper: np.ndarray,
    prior: float,
    iterations: int,
    density: float,
    start: np.ndarray,
) -> tuple[np.ndarray, dict[str, float], int]:
    rig = _rig_of(model)
    shapedirs = np.asarray(rig.shapedirs, dtype=np.float64)[:, :, : len(start)]
    names = tuple(targets)
    scale = np.array([TOLERANCES[n] / np.sqrt(weights.get(n, 1.0)) for n in names])
    goal = np.array([targets[n] for n in names])
    beta = np.clip(start.copy(), lower, upper)
    nb = len(beta)
    sq = np.sqrt(prior)
    done = 0
    measured = {}
    for it in range(iterations + 1):
        lins = measure_body(rest_body(model, beta, density=density), names)
        measured = {n: lins[n].value for n in names}
        r = (np.array([measured[n] for n in names]) - goal) / scale
        if it == iterations or np.all(np.abs(r) < 0.05):
            break
        jac = np.stack([_jacobian_row(lins[n], shapedirs) for n in names]) / scale[:, None]
        # minimise |r + J d|^2 + prior |beta + d|^2 over the step d, with lower <= beta + d <= upper
        a = np.vstack([jac, sq * np.eye(nb)])
        rhs = np.concatenate([-r, -sq * beta])
        step = lsq_linear(a, rhs, bounds=(lower - beta, upper - beta + 1e-12), method="bvls").x
        beta = np.clip(beta + step, lower, upper)
        done = it + 1
    return beta, measured, done


def fit_shape(
    model: Any,
    *,
    weights: dict[str, float] | None = None,
    bounds: tuple[Any, Any] | float = 3.0,
    prior: float = 0.01,
    iterations: int = 6,
    num_betas: int | None = None,
    density: float = DEFAULT_DENSITY,
    betas0: np.ndarray | None = None,
    **targets: Any,
) -> ShapeFit:
    """Shape coefficients whose rest-pose body has the given measurements.

    Each Gauss-Newton iteration measures the body (:func:`smplcore.measure.measure`'s definitions), takes
    every measurement's first-order dependence on the shape coefficients (the cut edges, extreme vertices
    and joints held fixed: exact for heights and volume, close for girths) and solves one bounded linear
    least-squares problem (``scipy.optimize.lsq_linear``) for the step::

        min_b  Σ_m w_m ((m(b) − target_m) / tol_m)²  +  prior · |b|²    subject to  lower <= b <= upper

    ``tol_m`` are :data:`TOLERANCES` (5 mm for lengths, 0.5 kg for mass). The Gaussian prior ``|b|²`` is
    the shape space's own (betas are unit-variance PCA coefficients), so bodies stay plausible and
    directions the measurements do not fix stay at the mean.

    Parameters
    ----------
    model : a :class:`smplcore.BodyModel` or a torch module from :func:`smplcore.create`.
    **targets : measurement name (see :data:`smplcore.measure.MEASUREMENTS`; ``height`` = ``stature``) ->
        target value (float) or (B,) values for a batch of bodies, in metres / kg / kg/m².
    weights : name -> weight of that measurement (default 1 each).
    bounds : ``(lower, upper)`` per coefficient (floats or (num_betas,) arrays), or one float ``c`` for
        ``(-c, c)`` (default 3: within three standard deviations).
    prior : weight of the Gaussian prior on the betas (default 0.01).
    iterations : Gauss-Newton iterations at most (default 6; stops early when every residual is within
        5 % of its tolerance).
    num_betas : fit only the first ``num_betas`` coefficients (default all the model takes).
    density : kg/m³ for mass and BMI.
    betas0 : (num_betas,) or (B, num_betas) starting point (default the mean shape).

    Returns
    -------
    :class:`ShapeFit` with ``betas`` (num_betas,) or (B, num_betas) and the residual per measurement.
    """
    rig = _rig_of(model)
    if "height" in targets and "stature" in targets:
        raise ValueError("fit_shape: give height or stature (the same measurement), not both")
    goals = {_ALIASES.get(k, k): v for k, v in targets.items() if v is not None}
    unknown = sorted(set(goals) - set(MEASUREMENTS))
    if unknown:
        raise ValueError(f"fit_shape: unknown measurements {unknown}; expected some of {list(MEASUREMENTS)}")
    if not goals:
        raise ValueError("fit_shape: give at least one target measurement, e.g. height=1.75")
    w = {_ALIASES.get(k, k): float(v) for k, v in (weights or {}).items()}
    nb = rig.num_betas if num_betas is None else int(num_betas)
    if not 1 <= nb <= rig.num_betas:
        raise ValueError(f"num_betas: expected 1..{rig.num_betas}, got {num_betas}")
    if isinstance(bounds, (int, float)):
        lo, hi = -float(bounds), float(bounds)
    else:
        lo, hi = bounds
    lower = np.broadcast_to(np.asarray(lo, dtype=np.float64), (nb,)).copy()
    upper = np.broadcast_to(np.asarray(hi, dtype=np.float64), (nb,)).copy()
    if np.any(lower > upper):
        raise ValueError(f"bounds: lower bound above upper bound ({lower} > {upper})")
    arrays = {k: np.asarray(v, dtype=np.float64) for k, v in goals.items()}
    batch = max((a.size if a.ndim else 0) for a in arrays.values())
    single = all(a.ndim == 0 for a in arrays.values())
    count = 1 if single else batch
    sizes = {k: a.shape for k, a in arrays.items() if a.ndim}
    if len({a.size for a in arrays.values() if a.ndim}) > 1 or any(a.ndim > 1 for a in arrays.values()):
        raise ValueError(f"targets: expected floats or (B,) arrays of one length B, got shapes {sizes}")
    for k, a in arrays.items():
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{k}: the target must be finite, got {a}")
    start = (
        np.zeros((count, nb)) if betas0 is None else np.broadcast_to(np.asarray(betas0, float)[..., :nb], (count, nb))
    )

    out_b, out_m, out_it = [], [], []
    for i in range(count):
        t = {k: float(a if a.ndim == 0 else a.reshape(-1)[i]) for k, a in arrays.items()}
        beta, measured, its = _fit_one(model, t, w, lower, upper, prior, iterations, density, start[i])
        full = np.zeros(rig.num_betas)
        full[:nb] = beta
        out_b.append(full)
        out_m.append(measured)
        out_it.append(its)
    names = list(arrays)
    measured_d = {n: np.array([m[n] for m in out_m]) for n in names}
    residual = {n: measured_d[n] - np.broadcast_to(arrays[n], (count,)) for n in names}
    if single:
        return ShapeFit(
            out_b[0],
            {n: float(v[0]) for n, v in measured_d.items()},
            {n: float(v[0]) for n, v in residual.items()},
            out_it[0],
        )
    return ShapeFit(np.stack(out_b), measured_d, residual, np.array(out_it))
