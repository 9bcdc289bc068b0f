"""Sequences: the temporal smoothness term, its coupled Levenberg–Marquardt step, and one-person detection.

The term is ``Σ_t Σ_c w_c (x_t,c − x_{t−1},c)²`` over the pose and translation columns of consecutive bodies
(each difference charged to the later body), the weight of each column the fit's smoothness times the data's
stiffness on it (:meth:`Temporal.relative`). It couples every body to its neighbours, so the Gauss–Newton system
of a sequence is block tridiagonal (plus a border when shape is shared): :func:`temporal_step` solves it
exactly, by block elimination along the sequence (the Schur complement of the shared columns last), in
time linear in the number of frames. Solving the coupled system at once is what makes the term smooth:
rounds of per-frame fits, each pulled towards its neighbours' last poses, oscillate between frames (the
sequence's highest-frequency mode is amplified, not damped, when the coupling outweighs the data).

Axis-angle rotations are made continuous along the sequence first (:func:`unwrap_rotations`): a rotation
near 180° has two axis-angle vectors, and a fit per frame picks either, so that differences of consecutive
parameters would be differences of representations, not of rotations.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: Targets whose bones differ between bodies by less than this (metres, or this fraction of the bone) come
#: from one person: :func:`one_person` shares their shape.
SAME_BONE = 0.01
SAME_BONE_FRACTION = 0.02


@dataclass(frozen=True)
class Temporal:
    """``Σ_t Σ_c w_c (x_t,c − x_{t−1},c)²`` over the columns ``cols`` (S,) of the flat parameters [pose, coeffs,
    transl], with weights ``weights`` (S,)."""

    weights: np.ndarray
    cols: np.ndarray

    @classmethod
    def relative(cls, smoothness: float, stiffness: np.ndarray, cols: np.ndarray) -> Temporal:
        """Weights ``smoothness`` times the data's stiffness (S,) on each column (the diagonal of its
        Gauss–Newton matrix, m² per unit of the parameter): a parameter's change between frames then costs
        ``smoothness`` times what moving the targets' points by that change costs, so one number smooths
        rotations (radians) and translations (metres) alike, as a weight on the points' velocities would."""
        return cls(smoothness * np.asarray(stiffness, np.float64), np.asarray(cols))

    def scaled(self, factor: float) -> Temporal:
        return Temporal(self.weights * factor, self.cols)

    def cost_gradient(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(B,) cost (each difference charged to the later body) and (B, P) half-gradient at flat ``x``."""
        cost = np.zeros(len(x))
        grad = np.zeros_like(x)
        if len(x) < 2:
            return cost, grad
        d = self.weights * np.diff(x[:, self.cols], axis=0)  # (B - 1, S)
        cost[1:] = np.sum(d * np.diff(x[:, self.cols], axis=0), axis=1)
        g = np.zeros((len(x), len(self.cols)))
        g[1:] += d
        g[:-1] -= d
        grad[:, self.cols] = g
        return cost, grad

    def cost(self, x: np.ndarray) -> np.ndarray:
        return self.cost_gradient(x)[0]


def temporal_step(
    hess: np.ndarray, grad: np.ndarray, damping: np.ndarray, shared_cols: np.ndarray, coupling: np.ndarray
) -> np.ndarray:
    """The damped Gauss–Newton step (B, P) of a sequence: per-body matrices (B, P, P) (damped as
    :func:`smplcore.fit.solver._step` does, in place and restored), gradients (B, P), the columns
    ``shared_cols`` (P,) one value for the whole batch, and consecutive bodies coupled by ``coupling`` (P,)
    (the temporal weight on each column, 0 for the others)."""
    diag = np.einsum("bii->bi", hess)
    saved = diag.copy()
    diag += damping[:, None] * (saved + 1e-9)
    try:
        return -_coupled_solve(hess, grad, shared_cols, coupling)
    finally:
        diag[...] = saved


def _coupled_solve(hess: np.ndarray, grad: np.ndarray, shared_cols: np.ndarray, coupling: np.ndarray) -> np.ndarray:
    """Solve the coupled system ``H δ = g`` (see :func:`temporal_step`)."""
    batch = len(grad)
    loc, sh = np.flatnonzero(~shared_cols), np.flatnonzero(shared_cols)
    c = coupling[loc]
    neighbours = np.full(batch, 2.0)
    neighbours[[0, -1]] = 1.0 if batch > 1 else 0.0
    blocks = hess[:, loc[:, None], loc].copy()
    blocks[:, np.arange(len(loc)), np.arange(len(loc))] += neighbours[:, None] * c
    rhs = np.concatenate([hess[:, loc[:, None], sh], grad[:, loc, None]], axis=2)  # [E_t | g_t]
    solved = _block_tridiagonal(blocks, c, rhs)  # T⁻¹ [E | g]
    out = np.empty_like(grad)
    if not len(sh):
        out[:, loc] = solved[..., -1]
        return out
    edge = hess[:, loc[:, None], sh]  # (B, L, K)
    schur = hess[:, sh[:, None], sh].sum(0) - np.einsum("blk,blm->km", edge, solved[..., :-1])
    shared_rhs = grad[:, sh].sum(0) - np.einsum("blk,bl->k", edge, solved[..., -1])
    ds = np.linalg.solve(schur, shared_rhs)
    out[:, sh] = ds
    out[:, loc] = solved[..., -1] - solved[..., :-1] @ ds
    return out


def _block_tridiagonal(blocks: np.ndarray, c: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """X (B, L, R) solving ``A_t X_t − diag(c) (X_{t−1} + X_{t+1}) = R_t`` (block Thomas elimination):
    ``blocks`` (B, L, L) the A_t, ``rhs`` (B, L, R)."""
    batch = len(blocks)
    inverses = np.empty_like(blocks)
    y = rhs.copy()
    cc = c[:, None] * c[None, :]
    for t in range(batch):
        if t:
            blocks[t] -= cc * inverses[t - 1]
            y[t] += c[:, None] * (inverses[t - 1] @ y[t - 1])
        inverses[t] = np.linalg.inv(blocks[t])
    x = np.empty_like(y)
    x[-1] = inverses[-1] @ y[-1]
    for t in range(batch - 2, -1, -1):
        x[t] = inverses[t] @ (y[t] + c[:, None] * x[t + 1])
    return x


def unwrap_rotations(body: Any, pose: np.ndarray) -> np.ndarray:
    """(B, Q) ``pose`` with each joint's axis-angle vector replaced, frame by frame, by the equivalent one
    (``θ − 2π θ/|θ|`` or ``θ + 2π θ/|θ|``) nearest the previous frame's: the same rotations, continuous
    parameters. PCA blocks are left as they are."""
    pose = pose.copy()
    for block in body.blocks:
        if block.components is not None:
            continue
        for j in range(block.width // 3):
            cols = block.start + 3 * j + np.arange(3)
            v = pose[:, cols]
            for t in range(1, len(v)):
                angle = np.linalg.norm(v[t])
                if angle < 1e-9:
                    continue
                unit = v[t] / angle
                # the representatives θ + 2πk θ/|θ| for k = -1, 0, 1 (and ±2 for long turns)
                candidates = v[t] + 2 * np.pi * np.arange(-2, 3)[:, None] * unit
                v[t] = candidates[np.argmin(np.linalg.norm(candidates - v[t - 1], axis=1))]
            pose[:, cols] = v
    return pose


def one_person(targets: np.ndarray, present: np.ndarray, pairs: list[tuple[int, int]]) -> bool:
    """Whether (B, n, 3) ``targets`` come from one person: every bone ``pairs`` (into n; rigid in the model, a
    joint and its parent) keeps its length over the bodies (5th to 95th percentile) within :data:`SAME_BONE`
    metres or :data:`SAME_BONE_FRACTION` of it (``present`` (B, n) marks the joints given)."""
    if len(targets) < 2 or not pairs:
        return False
    a = np.array([p for p, _ in pairs])
    b = np.array([q for _, q in pairs])
    length = np.linalg.norm(targets[:, a] - targets[:, b], axis=-1)
    given = present[:, a] & present[:, b]
    for i in range(len(pairs)):
        values = length[given[:, i], i]
        if len(values) < 2:
            continue
        spread = np.percentile(values, 95) - np.percentile(values, 5)  # a glitch in a frame or two is no person
        if spread > max(SAME_BONE, SAME_BONE_FRACTION * float(np.median(values))):
            return False
    return True
