"""The non-quadratic pose priors of a fit as least-squares blocks: anatomical limits, the elbow/knee hinge,
a Gaussian mixture.

:class:`PoseTerms` holds which columns of the solver's pose vector are the body joints' axis-angle values
and the priors' weights; :meth:`PoseTerms.blocks` gives each prior as residuals ``r`` with their Jacobian
(cost ``w |r|²``, the convention of :mod:`smplcore.fit.solver`), and :meth:`PoseTerms.add_system` adds
their share to a Gauss–Newton gradient and matrix over any set of fitted columns. The priors themselves
are :mod:`smplcore.fit.priors`'.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from smplcore.fit.priors import BENDING, GMMPrior, bending_residuals, joint_limits, limit_residuals


def gmm_prior(value: Any) -> GMMPrior | None:
    """``gmm`` as a :class:`GMMPrior`: None, a prior, a path to SMPLify's ``gmm_08.pkl``, or ``"open"``
    (smplcore's open prior trained on motion capture, :meth:`GMMPrior.open`)."""
    if value is None or isinstance(value, GMMPrior):
        return value
    if isinstance(value, str) and value == "open":
        return GMMPrior.open()
    if isinstance(value, (str, os.PathLike)):
        return GMMPrior.load(value)
    raise TypeError(f"gmm: expected a GMMPrior, a path to gmm_08.pkl, or None; got {type(value).__name__}")


@dataclass(frozen=True)
class PoseTerms:
    """Limits, hinge and mixture priors on the body joints.

    Attributes
    ----------
    cols : (D,) columns of the solver's pose vector holding ``body_pose`` (axis-angle, 3 per joint).
    lo, hi : (D,) the limits (radians).
    limits : weight of Σ (distance outside [lo, hi])² (m² per rad² in a 3D fit).
    bend_index, bend_sign : (m,) the hinge components (into ``cols``) and the sign of bending the wrong way.
    bending : weight of Σ max(0, sign θ)².
    gmm : a mixture over the first ``gmm.dim`` body-pose values, or None; ``gmm_weight`` its weight.
    """

    cols: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    limits: float
    bend_index: np.ndarray
    bend_sign: np.ndarray
    bending: float
    gmm: GMMPrior | None = None
    gmm_weight: float = 0.0

    @classmethod
    def of(
        cls, body: Any, limits: float, bending: float, gmm: GMMPrior | None = None, gmm_weight: float = 0.0
    ) -> PoseTerms | None:
        """The terms for a ``FitBody`` (None when every weight is zero or the model has no body joints)."""
        block = next((b for b in body.blocks if b.name == "body_pose"), None)
        if block is None or block.width != 3 * block.num_joints:
            return None
        if gmm is not None:
            dim = min(gmm.dim, block.width)
            gmm = gmm.marginal(dim)
        if not (limits or bending or (gmm is not None and gmm_weight)):
            return None
        names = list(body.output_joint_names[block.first_joint : block.first_joint + block.num_joints])
        lo, hi = joint_limits(names)
        bend = [(names.index(n) * 3 + axis, sign) for n, axis, sign in BENDING if n in names]
        return cls(
            cols=block.start + np.arange(block.width),
            lo=lo.reshape(-1),
            hi=hi.reshape(-1),
            limits=float(limits),
            bend_index=np.array([i for i, _ in bend], np.int64),
            bend_sign=np.array([s for _, s in bend], np.float64),
            bending=float(bending),
            gmm=gmm,
            gmm_weight=float(gmm_weight) if gmm is not None else 0.0,
        )

    def blocks(self, pose: np.ndarray) -> tuple[list[tuple[float, np.ndarray, np.ndarray, np.ndarray]], np.ndarray]:
        """Residual blocks at (B, Q) ``pose``: (weight, residuals (B, m), Jacobian — diagonal (B, m) or full
        (B, m, m') — , pose columns (m,) or (m',)), and the mixture's constant cost (B,)."""
        theta = pose[:, self.cols]
        parts = []
        const = np.zeros(len(pose))
        if self.limits:
            res, diag = limit_residuals(theta, self.lo, self.hi)
            parts.append((self.limits, res, diag, self.cols))
        if self.bending and len(self.bend_index):
            res, diag = bending_residuals(theta, self.bend_index, self.bend_sign)
            parts.append((self.bending, res, diag, self.cols[self.bend_index]))
        if self.gmm is not None and self.gmm_weight:
            dim = self.gmm.dim
            best, res, jac = self.gmm.residuals(theta[:, :dim])
            parts.append((self.gmm_weight, res, jac, self.cols[:dim]))
            const = 2 * self.gmm_weight * self.gmm.penalty[best]
        return parts, const

    def cost(self, pose: np.ndarray) -> np.ndarray:
        """(B,) the priors' cost at (B, Q) ``pose``."""
        parts, const = self.blocks(pose)
        return const + sum((w * np.sum(r * r, axis=1) for w, r, _, _ in parts), np.zeros(len(pose)))

    def add_system(
        self, pose: np.ndarray, fitted: np.ndarray, grad: np.ndarray | None, hess: np.ndarray | None
    ) -> np.ndarray:
        """Add the priors' gradient ``w Jᵀ r`` to (B, P) ``grad`` and their Gauss–Newton matrix ``w JᵀJ`` to
        (B, P, P) ``hess`` (either may be None), whose columns are the pose columns ``fitted`` (P,) (-1 for a
        column that is not a pose column); returns the priors' cost (B,)."""
        where = np.full(pose.shape[1], -1)
        is_pose = fitted >= 0
        where[fitted[is_pose]] = np.flatnonzero(is_pose)
        parts, cost = self.blocks(pose)
        rows = np.arange(len(pose))
        for weight, res, jac, cols in parts:
            cost = cost + weight * np.sum(res * res, axis=1)
            idx = where[cols]
            keep = idx >= 0
            if not keep.any():
                continue
            idx = idx[keep]
            if jac.ndim == 2:  # diagonal
                d = jac[:, keep]
                if grad is not None:
                    grad[:, idx] += weight * d * res[:, keep]
                if hess is not None:
                    hess[:, idx, idx] += weight * d * d
            else:
                m = jac[:, :, keep]
                if grad is not None:
                    grad[:, idx] += weight * np.einsum("bmp,bm->bp", m, res)
                if hess is not None:
                    hess[np.ix_(rows, idx, idx)] += weight * np.einsum("bmp,bmq->bpq", m, m)
        return cost
