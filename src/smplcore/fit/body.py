"""A model's arrays in float64 NumPy, laid out for fitting: posed points and their exact Jacobians.

The fitting code sees a model as a set of *points*: the mesh vertices followed by the skeleton joints.
A joint is a point at its rest position, skinned rigidly to itself, with no pose correctives; its posed
position is then exactly the kinematic chain's. Every point is posed as

    x_i = Σ_m w_im (G_{l_m} (v̄_i − j̄_{l_m}) + p_{l_m}) + t,   v̄_i = template_i + S_i c + P_i f(R)

with ``G``, ``p`` the world rotations and positions of the joints, ``c`` the shape (and expression)
coefficients, ``f`` the pose-corrective features and ``t`` the translation. The Jacobian with respect
to a local rotation increment ``ω_k`` (``R_k ← R_k exp(ω_k)``) is ``−[u_ik]× G_k`` with
``u_ik = Σ_{m: l_m below k} w_im (x_im − p_k)`` plus the pose-corrective term, and with respect to the
shape coefficients ``A_i S_i + Σ_m w_im T_{l_m}``, ``A_i = Σ_m w_im G_{l_m}``,
``T_j = Σ_{a on the chain of j} (G_{parent(a)} − G_a) J̄S_a``.
"""

from __future__ import annotations

import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from smplcore.engine import KinematicTree, rodrigues, world_transforms
from smplcore.model.rig import Rig

# Point sets and their arrays kept per model (the fitting stages of a call use a handful).
_CACHE_SIZE = 48

# The fitting arrays of each rig, kept while the rig (held by its model) lives; nothing is stored on the model.
_BODIES: weakref.WeakKeyDictionary[Rig, FitBody] = weakref.WeakKeyDictionary()
_BODIES_LOCK = threading.Lock()


@dataclass(frozen=True)
class PoseBlock:
    """One forward keyword of the model's pose: its columns in the parameter vector and its joints."""

    name: str
    start: int  # first column in the pose-parameter vector
    width: int  # columns (3 n, or the PCA coefficient count)
    first_joint: int
    num_joints: int
    components: np.ndarray | None  # (C, 3 n) PCA basis or None


@dataclass(frozen=True)
class Points:
    """Rows of :class:`FitBody` for a chosen set of points (vertex ids, then joint ids offset by V)."""

    ids: np.ndarray  # (n,) into the extended point set
    template: np.ndarray  # (n, 3)
    shape: np.ndarray  # (n, 3, K)
    posedirs: np.ndarray | None  # (n, 3, J - 1, 9) or None
    joints: np.ndarray  # (n, m) influencing joints (padded with joint 0 at weight 0)
    weights: np.ndarray  # (n, m)
    ancestors: np.ndarray  # (n, a) joints whose rotation moves the point (padded with J)
    below: np.ndarray  # (n, a, m) w_im if joint l_m is at or below ancestor a, else 0


@dataclass(eq=False)
class FitBody:
    """The arrays of one model for fitting, float64 (see the module docstring).

    Build with :meth:`from_rig` from a :class:`smplcore.model.Rig`, or with :meth:`from_model` from a torch
    module of :func:`smplcore.create` or a NumPy :class:`smplcore.BodyModel` (their ``rig``).
    """

    model_type: str
    num_vertices: int
    num_betas: int
    num_expression: int
    parents: np.ndarray  # (J,)
    tree: KinematicTree
    template: np.ndarray  # (V + J, 3)
    shape: np.ndarray  # (V + J, 3, K)
    posedirs: np.ndarray | None  # (V, 3, J - 1, 9)
    joints: np.ndarray  # (V + J, m)
    weights: np.ndarray  # (V + J, m)
    joint_template: np.ndarray  # (J, 3)
    joint_shape: np.ndarray  # (J, 3, K)
    regressor: sp.csr_matrix  # (J, V) the joint regressor
    blocks: tuple[PoseBlock, ...]
    pose_mean: np.ndarray  # (3 J,)
    pose_map: np.ndarray | None  # (Q, 3 J) full pose = pose_mean + q @ pose_map; None: identity
    output_joint_names: list[str]
    output_rows: np.ndarray  # (J', V + J) output joints as combinations of points (dynamic contour: zero)
    faces: np.ndarray
    dynamic_joints: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _cache: OrderedDict = field(default_factory=OrderedDict, repr=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def num_joints(self) -> int:
        return len(self.parents)

    @property
    def num_coeffs(self) -> int:
        return self.shape.shape[-1]

    @property
    def num_pose(self) -> int:
        return sum(b.width for b in self.blocks)

    @classmethod
    def from_model(cls, model: Any) -> FitBody:
        """The fitting arrays of ``model``: a torch module of :func:`smplcore.create`, a
        :class:`smplcore.BodyModel` or a :class:`smplcore.model.Rig` (see :meth:`from_rig`)."""
        rig = model if isinstance(model, Rig) else getattr(model, "rig", None)
        if not isinstance(rig, Rig):
            raise TypeError(
                f"model: expected a model of smplcore.create(), a smplcore.BodyModel or a smplcore.model.Rig, "
                f"got {type(model).__name__}"
            )
        return cls.from_rig(rig)

    @classmethod
    def from_rig(cls, rig: Rig) -> FitBody:
        """The fitting arrays of ``rig`` (built once per rig, kept as long as the rig lives)."""
        if rig.skinning != "lbs":
            raise ValueError(
                f"model: fitting solves the model's linear blend skinning, this model was made with "
                f"skinning={rig.skinning!r}; fit a model made with skinning='lbs' (the default) and pose the "
                "result with either"
            )
        with _BODIES_LOCK:
            body = _BODIES.get(rig)
        if body is None:
            body = cls._build(rig)
            with _BODIES_LOCK:
                body = _BODIES.setdefault(rig, body)
        return body

    @classmethod
    def _build(cls, rig: Rig) -> FitBody:
        f64 = np.float64
        v_template = rig.template
        dirs = np.concatenate([rig.shapedirs, rig.exprdirs], axis=-1)
        regressor = rig.joint_regressor
        parents = np.array(rig.parents, np.int64)
        num_verts, num_joints = rig.num_vertices, rig.num_joints
        joint_template = np.asarray(rig.template_joints)
        joint_shape = np.concatenate([rig.joint_shapedirs, rig.joint_exprdirs], axis=-1)
        template = np.concatenate([v_template, joint_template])
        shape = np.concatenate([dirs, joint_shape])
        weights = rig.weights
        width = max(1, int((weights > 0).sum(1).max()))
        order = np.argsort(-weights, axis=1, kind="stable")[:, :width]
        w = np.take_along_axis(weights, order, axis=1)
        order = np.where(w > 0, order, 0)
        joints = np.concatenate([order, np.zeros((num_joints, width), np.int64)])
        joints[num_verts:, 0] = np.arange(num_joints)
        point_w = np.concatenate([w, np.zeros((num_joints, width))])
        point_w[num_verts:, 0] = 1.0
        posedirs = None
        if rig.has_pose_correctives:  # (9 (J - 1), V, 3) -> (V, 3, J - 1, 9)
            posedirs = np.ascontiguousarray(rig.posedirs.transpose(1, 2, 0)).reshape(num_verts, 3, num_joints - 1, 9)
        blocks = tuple(
            PoseBlock(
                b.name,
                b.offset,
                b.width,
                b.first_joint,
                b.num_joints,
                np.asarray(rig.hand_components[b.name], f64) if b.pca else None,
            )
            for b in rig.pose_blocks
        )
        pose_map = rig.pose_map() if any(b.pca for b in rig.pose_blocks) else None
        rows = rig.output_rows().toarray()
        body = cls(
            model_type=rig.model_type,
            num_vertices=num_verts,
            num_betas=rig.num_betas,
            num_expression=rig.num_expression_coeffs,
            parents=parents,
            tree=KinematicTree.from_parents(parents),
            template=template,
            shape=shape,
            posedirs=posedirs,
            joints=joints,
            weights=point_w,
            joint_template=joint_template,
            joint_shape=joint_shape,
            regressor=sp.csr_matrix(regressor),
            blocks=blocks,
            pose_mean=np.array(rig.pose_mean, f64),
            pose_map=pose_map,
            output_joint_names=list(rig.output_joint_names),
            output_rows=rows,
            faces=np.asarray(rig.faces),
        )
        body.dynamic_joints = np.asarray(rig.dynamic_output_rows)
        return body

    # -- point sets ---------------------------------------------------------------------------------

    def cached(self, key: Any, build: Callable[[], Any]) -> Any:
        """``build()``, remembered under ``key`` (the most recently used few dozen are kept)."""
        cache = self._cache
        with self._lock:
            if key in cache:
                cache.move_to_end(key)
                return cache[key]
        value = build()
        with self._lock:
            cache[key] = value
            if len(cache) > _CACHE_SIZE:
                cache.popitem(last=False)
        return value

    def points(self, ids: np.ndarray) -> Points:
        """The rows of the points ``ids`` (cached per id set)."""
        ids = np.asarray(ids, np.int64)
        return self.cached(("points", ids.tobytes()), lambda: self._points(ids))

    def below_of(self) -> np.ndarray:
        """(J, J) bool: ``[k, j]`` when joint ``j`` is at or below joint ``k``."""

        def build() -> np.ndarray:
            below = np.zeros((self.num_joints, self.num_joints), bool)
            for j in range(self.num_joints):
                below[self.tree.chain_to_root(j), j] = True
            return below

        return self.cached("below_of", build)

    def _points(self, ids: np.ndarray) -> Points:
        joints, weights = self.joints[ids], self.weights[ids]
        num_joints = self.num_joints
        below_of = self.below_of()
        # ancestors of each point: every joint on the chains of its influencing joints
        influence = np.zeros((len(ids), num_joints), bool)
        for m in range(joints.shape[1]):
            influence[np.arange(len(ids)), joints[:, m]] |= weights[:, m] > 0
        moved = (influence.astype(np.int64) @ below_of.T.astype(np.int64)) > 0  # (n, J)
        width = max(1, int(moved.sum(1).max()))
        first = np.argsort(~moved, axis=1, kind="stable")[:, :width]  # the moving joints first, ascending
        ancestors = np.where(np.take_along_axis(moved, first, axis=1), first, num_joints)
        valid = ancestors < num_joints
        safe = np.where(valid, ancestors, 0)
        below = below_of[safe[:, :, None], joints[:, None, :]] * valid[:, :, None] * weights[:, None, :]
        posedirs = None
        if self.posedirs is not None:
            posedirs = np.zeros((len(ids), 3, num_joints - 1, 9))
            mesh = ids < self.num_vertices
            posedirs[mesh] = self.posedirs[ids[mesh]]
        return Points(ids, self.template[ids], self.shape[ids], posedirs, joints, weights, ancestors, below)

    def pose_prior_weights(self, weight: float) -> np.ndarray | None:
        """(Q,) pose-prior weights: ``weight`` on every block but the global orientation (None for 0)."""
        if not weight:
            return None
        w = np.full(self.num_pose, float(weight))
        for b in self.blocks:
            if b.name == "global_orient":
                w[b.start : b.start + b.width] = 0.0
        return w

    def full_pose(self, pose: np.ndarray) -> np.ndarray:
        """(B, J, 3) axis-angle of every joint from (B, Q) pose parameters."""
        full = pose if self.pose_map is None else pose @ self.pose_map
        return (full + self.pose_mean).reshape(len(pose), self.num_joints, 3)

    def pose_from_full(self, full: np.ndarray) -> np.ndarray:
        """(B, Q) pose parameters closest (least squares) to a (B, J, 3) full pose."""
        flat = full.reshape(len(full), -1) - self.pose_mean
        if self.pose_map is None:
            return flat
        return np.linalg.lstsq(self.pose_map.T, flat.T, rcond=None)[0].T


def skew(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrices of (..., 3) vectors."""
    z = np.zeros_like(v[..., 0])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([z, -w, y, w, z, -x, -y, x, z], axis=-1).reshape(*v.shape, 3)


def right_jacobian(theta: np.ndarray) -> np.ndarray:
    """(..., 3, 3) right Jacobian of SO(3): ``R(θ + dθ) ≈ R(θ) exp([J_r(θ) dθ]×)``.

    ``J_r = I − a [θ]× + b [θ]×² = (1 − b t²) I − a [θ]× + b θ θᵀ`` with ``t = |θ|``, ``a = (1 − cos t) / t²``,
    ``b = (t − sin t) / t³`` (Taylor series near zero), written out entry by entry.
    """
    x, y, z = theta[..., 0], theta[..., 1], theta[..., 2]
    t2 = x * x + y * y + z * z
    small = t2 < 1e-6
    safe = np.where(small, 1.0, t2)
    t = np.sqrt(safe)
    a = np.where(small, 0.5 - t2 / 24, (1 - np.cos(t)) / safe)
    b = np.where(small, 1 / 6 - t2 / 120, (t - np.sin(t)) / (safe * t))
    c = 1 - b * t2
    bx, by, bz = b * x, b * y, b * z
    ax, ay, az = a * x, a * y, a * z
    rows = (
        c + bx * x,
        az + bx * y,
        bx * z - ay,
        by * x - az,
        c + by * y,
        ax + by * z,
        ay + bz * x,
        bz * y - ax,
        c + bz * z,
    )
    return np.stack(rows, axis=-1).reshape(*theta.shape, 3)


@dataclass
class Linearization:
    """Posed points and, when asked, their Jacobian (B, n, 3, P) over [pose θ (3 J), coeffs (K), transl (3)]."""

    points: np.ndarray
    jacobian: np.ndarray | None = None


def pose_points(
    body: FitBody, pts: Points, theta: np.ndarray, coeffs: np.ndarray, transl: np.ndarray, jacobian: bool = False
) -> Linearization:
    """Pose the points ``pts`` of bodies (B, J, 3) ``theta``, (B, K) ``coeffs``, (B, 3) ``transl``.

    With ``jacobian`` the derivatives with respect to the full axis-angle pose (3 J columns, joint-major),
    the coefficients and the translation are returned too (exact, not finite differences).
    """
    batch, num_joints = theta.shape[:2]
    rot = rodrigues(theta)
    jrest = body.joint_template + np.einsum("jck,bk->bjc", body.joint_shape, coeffs)
    world, pos = world_transforms(rot, jrest, body.tree)
    shift = pos - (world @ jrest[..., None])[..., 0]
    rest = pts.template + np.einsum("nck,bk->bnc", pts.shape, coeffs)
    if pts.posedirs is not None:
        feats = (rot[:, 1:] - np.eye(3)).reshape(batch, num_joints - 1, 9)
        rest = rest + np.einsum("ncjf,bjf->bnc", pts.posedirs, feats)
    g = world[:, pts.joints]  # (B, n, m, 3, 3)
    x = (g @ rest[:, :, None, :, None])[..., 0] + shift[:, pts.joints]  # (B, n, m, 3)
    posed = np.einsum("nm,bnmc->bnc", pts.weights, x) + transl[:, None]
    if not jacobian:
        return Linearization(posed)
    n = len(pts.ids)
    num_coeffs = coeffs.shape[1]
    jac = np.zeros((batch, n, 3, 3 * num_joints + num_coeffs + 3))
    # rotations: u_ia = Σ_m below_iam x_im − (Σ_m below_iam) p_{k_a}
    pos_pad = np.concatenate([pos, np.zeros((batch, 1, 3))], axis=1)
    u = np.einsum("nam,bnmc->bnac", pts.below, x) - pts.below.sum(-1)[None, :, :, None] * pos_pad[:, pts.ancestors]
    local = world @ right_jacobian(theta)  # (B, J, 3, 3): d world-axis / d θ_k
    local_pad = np.concatenate([local, np.zeros((batch, 1, 3, 3))], axis=1)
    blocks = -skew(u) @ local_pad[:, pts.ancestors]  # (B, n, a, 3, 3)
    rot_jac = np.zeros((batch, n, num_joints + 1, 3, 3))
    rows = np.arange(n)[:, None]
    rot_jac[:, rows, pts.ancestors] = blocks
    rot_jac = rot_jac[:, :, :num_joints]
    blend = np.einsum("nm,bnmcd->bncd", pts.weights, g)  # A_i
    if pts.posedirs is not None:
        # d vec(R_k) / d θ_k: columns vec(R_k [c]×) for the columns c of J_r(θ_k)
        jr = right_jacobian(theta[:, 1:])
        dvec = (rot[:, 1:, None] @ skew(np.swapaxes(jr, -1, -2))).reshape(batch, num_joints - 1, 3, 9)
        corr = np.einsum("ncjf,bjaf->bnjca", pts.posedirs, dvec)  # (B, n, J-1, 3, 3)
        rot_jac[:, :, 1:] += blend[:, :, None] @ corr
    jac[..., : 3 * num_joints] = rot_jac.transpose(0, 1, 3, 2, 4).reshape(batch, n, 3, 3 * num_joints)
    # coefficients
    parent = np.maximum(body.parents, 0)
    parent_world = np.where((body.parents >= 0)[None, :, None, None], world[:, parent], np.eye(3))
    steps = (parent_world - world) @ body.joint_shape  # (B, J, 3, K)
    totals = np.empty_like(steps)
    for j in body.tree.order:
        p = body.parents[j]
        totals[:, j] = steps[:, j] if p < 0 else steps[:, j] + totals[:, p]
    coeff_jac = blend @ pts.shape + np.einsum("nm,bnmck->bnck", pts.weights, totals[:, pts.joints])
    jac[..., 3 * num_joints : 3 * num_joints + num_coeffs] = coeff_jac
    jac[..., -3:] = np.eye(3)
    return Linearization(posed, jac)
