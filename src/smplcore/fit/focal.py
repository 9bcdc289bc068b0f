"""Estimating the focal length of :func:`smplcore.fit.fit_keypoints` (``estimate_focal=True``).

One focal length for the batch (every body is seen by the same camera), fitted with the bodies:

1. **Hypotheses.** The whole fit (stages 1 and 2) runs for each focal length ``f₀ × FOCAL_GRID``
   (``f₀`` the given camera's, e.g. ``Camera.from_image_size``'s guess): from 0.5 f₀ to 2 f₀ in steps of
   √2. Each is a fit from scratch: a body fitted with one focal length sits in a local minimum that a
   gradient method does not leave for a quite different one (measured: a joint Levenberg–Marquardt from
   1414 px, sixteen people 2–3 m away seen with 1000 px, moved the focal length by under 1 % in 25
   iterations). The hypotheses are compared by the bodies' costs, all with the same metres-per-pixel
   scale, combined robustly: each body's excess over its own best hypothesis, truncated at the median
   excess, summed (a body that fell into a poor local minimum under one hypothesis then cannot veto it
   alone; on 18 scenes of six people this lowered the mean ``|log(f / f_true)|`` from 0.27 to 0.19),
   plus the prior ``w (log f/f₀)²``.
2. **Refinement.** Bodies that did better under another hypothesis restart from that fit (moved to keep
   their place and size in the image) and keep it if it is better under the chosen one. A parabola
   through the best hypothesis and its two neighbours (in log f) gives the start, and
   Levenberg–Marquardt refines every body and ``log f`` jointly (:mod:`smplcore.fit.reprojection`, where
   the bodies' depths move with the focal length so that the focal column changes only the perspective).

Focal length and depth are nearly interchangeable for a person far from the camera (a body twice as
far seen with twice the focal length looks the same up to perspective, which is a few pixels over a
body's depth at 4 m); the prior decides there. See docs/fit.md for the measured recovery.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from smplcore.fit.camera import Camera
from smplcore.fit.reprojection import Terms, evaluate, flat, focal_translation, levenberg_marquardt, solve_flat, unflat
from smplcore.fit.solver import State

#: focal lengths tried, as multiples of the given camera's
FOCAL_GRID = 2.0 ** (np.arange(-2, 3) / 2.0)
#: default weight of the focal length's prior ``(log f/f₀)²`` (m², as the other priors' weights)
FOCAL_PRIOR = 1e-5


def with_focal(camera: Camera, log_scale: float) -> Camera:
    """``camera`` with its focal length(s) multiplied by ``exp(log_scale)``."""
    return camera.replace(focal=camera.focal * np.exp(log_scale))


def _vertex(s: np.ndarray, cost: np.ndarray, i: int) -> float:
    """The minimum of the parabola through the hypotheses around ``i`` (log focal ``s``), kept between
    ``i``'s neighbours; ``s[i]`` at the ends of the grid or where the parabola opens downwards."""
    if i == 0 or i == len(s) - 1:
        return float(s[i])
    a, b, c = np.polyfit(s[i - 1 : i + 2], cost[i - 1 : i + 2], 2)
    if a <= 0:
        return float(s[i])
    return float(np.clip(-b / (2 * a), s[i - 1], s[i + 1]))


def _reseed(setup: Any, terms: Terms, state: State, lagging: np.ndarray, costs, fits, logs, best: int):
    """Bodies that did worse under the chosen focal length than under another (``lagging``) start again
    from their best hypothesis' fit, moved to keep their place and size in the image; kept if better."""
    if not lagging.any():
        return state, 0
    trial = state.copy()
    for b in np.flatnonzero(lagging):
        j = int(np.argmin(costs[:, b]))
        other = fits[j][0]
        trial.pose[b], trial.coeffs[b] = other.pose[b], other.coeffs[b]
        moved = np.concatenate([flat(other)[b : b + 1], [[logs[best] - logs[j]]]], axis=1)
        trial.transl[b] = focal_translation(setup.body, terms.camera, moved)[0]
    trial, cost, _, used = levenberg_marquardt(setup.body, terms, trial, max_iter=setup.max_iter, tol=setup.tol)
    before = evaluate(setup.body, terms, flat(state), system=False)[0]
    keep = (cost < before)[:, None]
    return State(*(np.where(keep, getattr(trial, f), getattr(state, f)) for f in ("pose", "coeffs", "transl"))), used


def estimate_focal_length(
    setup: Any, stages: Callable[..., tuple], camera: Camera, prior: float
) -> tuple[State, np.ndarray, int, Terms]:
    """Fit the bodies of ``setup`` and one focal length (see the module docstring).

    ``stages(setup, camera, scale)`` runs stages 1 and 2 and returns (state, costs (B,), converged (B,),
    iterations, terms, scale (B,)). Returns the state (translations in the world, as usual), converged
    flags, the iterations run, and the final terms, whose ``camera`` has the estimated focal length.
    """
    if not prior >= 0:
        raise ValueError(f"focal_prior: expected a non-negative weight, got {prior}")
    logs = np.log(FOCAL_GRID)
    order = np.argsort(np.abs(logs), kind="stable")  # f₀ first: its placement fixes the common scale
    fits: dict[int, tuple] = {}
    scale = None
    iterations = 0
    for i in order:
        fit = stages(setup, with_focal(camera, float(logs[i])), scale)
        scale = fit[5] if scale is None else scale
        iterations += fit[3]
        fits[int(i)] = fit
    costs = np.stack([fits[i][1] for i in range(len(logs))])  # (G, B)
    excess = costs - costs.min(axis=0)
    totals = np.minimum(excess, np.median(excess)).sum(axis=1) + prior * logs**2
    best = int(np.argmin(totals))
    state, _, _, _, terms, _ = fits[best]
    coupled = bool(terms.shared.any() or terms.smooth) and len(state.pose) > 1
    if not coupled:
        state, used = _reseed(setup, terms, state, excess[best] > np.median(excess), costs, fits, logs, best)
        iterations += used
    start = _vertex(logs, totals, best) - logs[best]
    # the joint refinement: log(f / f_best) a shared column, the prior centred on f₀
    terms.free = np.append(terms.free, True)
    terms.shared = np.append(terms.shared, True)
    terms.estimate_focal, terms.focal_prior, terms.focal_centre = True, prior, float(-logs[best])
    x = np.concatenate([flat(state), np.full((len(state.pose), 1), start)], axis=1)
    x, _, converged, used = solve_flat(setup.body, terms, x, max_iter=setup.max_iter, tol=setup.tol)
    state = unflat(setup.body, x)
    state.transl = focal_translation(setup.body, terms.camera, x)
    terms.camera = with_focal(terms.camera, float(x[0, -1]))
    terms.estimate_focal = False
    return state, converged, iterations + used, terms
