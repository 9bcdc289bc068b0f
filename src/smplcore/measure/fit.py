"""``fit_shape``: shape coefficients from measurements by a bounded, regularised Gauss-Newton solve."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear

from smplcore.io import age_for_stature
from smplcore.measure._aging import AgeAxis
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
    (measured − target) per measurement, floats or (B,) arrays; ``iterations`` run per body; ``age`` the
    fitted age in years (float or (B,)) with ``fit_age=True``, else None."""

    betas: np.ndarray
    measured: dict[str, Any]
    residual: dict[str, Any]
    iterations: Any
    age: Any = None


def _jacobian_row(lin: Linear, shapedirs: np.ndarray) -> np.ndarray:
    """d value / d betas (B,) of a measurement linear in the vertices."""
    if len(lin.rows) == 0:
        return np.zeros(shapedirs.shape[2])
    return np.einsum("kc,kcb->b", lin.weights, shapedirs[lin.rows])


#: Finite-difference step (years) of the age column of the Jacobian, and the largest age step per iteration.
AGE_STEP = 0.1
AGE_TRUST = 3.0
#: Gauss-Newton stops once no beta moves by more than this (nor the age by ten times it) in a step.
STEP_STOP = 1e-3


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
    axis: AgeAxis | None = None,
    age: float = 25.0,
) -> tuple[np.ndarray, dict[str, float], int, float]:
    rig = _rig_of(model)
    names = tuple(targets)
    scale = np.array([TOLERANCES[n] / np.sqrt(weights.get(n, 1.0)) for n in names])
    goal = np.array([targets[n] for n in names])
    nb = len(start)
    sq = np.sqrt(prior)

    def evaluate(beta: np.ndarray, years: float) -> tuple[dict, np.ndarray, float]:
        here = rig if axis is None else axis.at(years)
        lins = measure_body(rest_body(here, beta, density=density), names)
        r = (np.array([lins[n].value for n in names]) - goal) / scale
        return lins, r, float(r @ r + prior * (beta @ beta))

    beta = np.clip(start.copy(), lower, upper)
    lins, r, cost = evaluate(beta, age)
    done = 0
    for it in range(iterations):
        if np.all(np.abs(r) < 0.05):
            break
        here = rig if axis is None else axis.at(age)
        shapedirs = np.asarray(here.shapedirs, dtype=np.float64)[:, :, :nb]
        jac = np.stack([_jacobian_row(lins[n], shapedirs) for n in names]) / scale[:, None]
        # minimise |r + J d|^2 + prior |beta + d|^2 over the step d, with lower <= beta + d <= upper
        a = np.vstack([jac, sq * np.eye(nb)])
        rhs = np.concatenate([-r, -sq * beta])
        lo, hi = lower - beta, upper - beta + 1e-12
        if axis is not None:  # one more unknown, the age: its column by a finite difference, no prior
            other = age + AGE_STEP if age + AGE_STEP <= axis.bounds[1] else age - AGE_STEP
            _, r_other, _ = evaluate(beta, other)
            col = (r_other - r) / (other - age)
            a = np.hstack([a, np.concatenate([col, np.zeros(nb)])[:, None]])
            lo = np.append(lo, max(axis.bounds[0], age - AGE_TRUST) - age)
            hi = np.append(hi, min(axis.bounds[1], age + AGE_TRUST) - age + 1e-12)
        step = lsq_linear(a, rhs, bounds=(lo, hi), method="bvls").x
        # the full step, or half of it, or a quarter: the first that lowers the cost (a girth's plane can
        # jump between iterations, where the linear model overshoots)
        accepted = False
        for fraction in (1.0, 0.5, 0.25):
            new_beta = np.clip(beta + fraction * step[:nb], lower, upper)
            new_age = age if axis is None else float(np.clip(age + fraction * step[nb], *axis.bounds))
            new_lins, new_r, new_cost = evaluate(new_beta, new_age)
            if new_cost < cost:
                accepted = True
                break
        done = it + 1
        if not accepted:  # no descent along the step: a minimum of what the targets allow
            break
        moved = max(float(np.max(np.abs(new_beta - beta), initial=0.0)), abs(new_age - age) / 10.0)
        beta, age, lins, r, cost = new_beta, new_age, new_lins, new_r, new_cost
        if moved < STEP_STOP:
            break
    return beta, {n: lins[n].value for n in names}, done, age


def fit_shape(
    model: Any,
    *,
    weights: dict[str, float] | None = None,
    bounds: tuple[Any, Any] | float = 3.0,
    prior: float = 0.01,
    iterations: int = 12,
    num_betas: int | None = None,
    density: float = DEFAULT_DENSITY,
    betas0: np.ndarray | None = None,
    fit_age: bool = False,
    age0: float | None = None,
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
    iterations : Gauss-Newton iterations at most (default 12; stops early when every residual is within
        5 % of its tolerance, or when no beta moves by more than 0.001 in a step). A step that does not
        lower the cost is halved, then quartered; when neither does, the fit stops there.
    num_betas : fit only the first ``num_betas`` coefficients (default all the model takes).
    density : kg/m³ for mass and BMI.
    betas0 : (num_betas,) or (B, num_betas) starting point (default the mean shape).
    fit_age : the open model only: solve the age (years, 1-90) with the betas. The age is one more unknown
        of each Gauss-Newton step (its column of the Jacobian by a finite difference of 0.1 year, a step of
        at most 3 years, no prior), the body at each age built as ``BodyModel(model_type="open",
        age=years)`` builds it, whatever age ``model`` was made at.
    age0 : the starting age with ``fit_age`` (default: the age whose mean body has the target stature,
        :func:`smplcore.io.age_for_stature`, or 25 without a stature target).

    Returns
    -------
    :class:`ShapeFit` with ``betas`` (num_betas,) or (B, num_betas), the residual per measurement and,
    with ``fit_age``, ``age``.
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

    axis = AgeAxis(rig) if fit_age else None
    if age0 is not None and not (np.isfinite(age0) and 1.0 <= float(age0) <= 90.0):
        raise ValueError(f"age0: expected years in [1, 90], got {age0}")
    out_b, out_m, out_it, out_a = [], [], [], []
    for i in range(count):
        t = {k: float(a if a.ndim == 0 else a.reshape(-1)[i]) for k, a in arrays.items()}
        a0 = 25.0
        if age0 is not None:
            a0 = float(age0)
        elif axis is not None and "stature" in t:
            a0 = age_for_stature(t["stature"], axis.gender)
        beta, measured, its, age = _fit_one(model, t, w, lower, upper, prior, iterations, density, start[i], axis, a0)
        full = np.zeros(rig.num_betas)
        full[:nb] = beta
        out_b.append(full)
        out_m.append(measured)
        out_it.append(its)
        out_a.append(age)
    names = list(arrays)
    measured_d = {n: np.array([m[n] for m in out_m]) for n in names}
    residual = {n: measured_d[n] - np.broadcast_to(arrays[n], (count,)) for n in names}
    if single:
        return ShapeFit(
            out_b[0],
            {n: float(v[0]) for n, v in measured_d.items()},
            {n: float(v[0]) for n, v in residual.items()},
            out_it[0],
            out_a[0] if fit_age else None,
        )
    return ShapeFit(np.stack(out_b), measured_d, residual, np.array(out_it), np.array(out_a) if fit_age else None)
