"""The body-model forward pass, once for every model and both namespaces.

:class:`BodyArrays` holds a model's arrays arranged for fast evaluation (bases as matrices, shape
terms of the joints precomputed); :func:`forward` maps shape coefficients and joint rotations to
posed vertices and joints:

    shape blend → joint regression → pose correctives → kinematic chain → skinning
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from smplcore.engine.backend import array_identity, for_cache, from_numpy, host_numpy, index, is_torch, namespace
from smplcore.engine.kernels import blocked, dqs, gemm
from smplcore.engine.kernels.blocked import vertex_columns
from smplcore.engine.rotations import pose_features
from smplcore.engine.skeleton import (
    KinematicTree,
    chain,
    skinning_transforms,
    with_translation,
)


def regress(regressor: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``regressor @ values`` for a (J, V) joint regressor and (V, ...) values, over each row's non-zero columns
    only (10-40 vertices a joint): no dense (J, V) product, and no SciPy import on the way to the first body."""
    regressor = np.asarray(regressor, dtype=np.float64)
    flat = np.asarray(values, dtype=np.float64).reshape(values.shape[0], -1)
    out = np.empty((regressor.shape[0], flat.shape[1]))
    for j, row in enumerate(regressor):
        cols = np.flatnonzero(row)
        out[j] = row[cols] @ flat[cols]
    return out.reshape((regressor.shape[0],) + tuple(values.shape[1:]))


def _stacked(parts: list[np.ndarray], width: int, convert: Callable[[np.ndarray], Any]) -> Any:
    """``convert(np.concatenate([p.reshape(-1, width) for p in parts]))`` without the float64 copies: each (strided)
    part is copied once, cast on the way, into the converted array (the same values: a copy and one rounding).

    Where the products with it are packed (:func:`gemm.available`: float32 on a CPU with oneDNN), a torch result
    is the transpose of a contiguous (width, rows) matrix: each column's values are contiguous, the layout
    :func:`gemm.pack` takes without a transposed copy, and the pose correctives (stored one vertex coordinate's
    column at a time) are copied in contiguous runs. Elsewhere the products read it as it is: row-major, where a
    product with one body runs fastest."""
    like = convert(np.zeros((1, 1)))
    rows = sum(p.shape[0] for p in parts)
    if is_torch(like):
        import warnings

        import torch

        # on the CPU in NumPy's memory (huge pages), first touched here
        packed = gemm.available(like)
        out = blocked.empty((width, rows), like).T if packed else blocked.empty((rows, width), like)
        start = 0
        for p in parts:
            with warnings.catch_warnings():  # read-only model arrays: only read here
                warnings.simplefilter("ignore", UserWarning)
                source = torch.from_numpy(np.asarray(p))
            out[start : start + p.shape[0]].view(p.shape).copy_(source)
            start += p.shape[0]
        return out
    if type(like) is not np.ndarray:  # another namespace: the plain way
        return convert(np.concatenate([np.asarray(p, np.float64).reshape(-1, width) for p in parts]))
    result = np.empty((rows, width), dtype=like.dtype)
    start = 0
    for p in parts:
        np.copyto(result[start : start + p.shape[0]].reshape(p.shape), p, casting="unsafe")
        start += p.shape[0]
    return convert(result)


@dataclass
class BodyArrays:
    """A model's arrays in one namespace, dtype and device, laid out for one GEMM per body part.

    Attributes
    ----------
    blend_basis : (1 + K [+ P], 3 * V) rows: the template, the K shape (and expression) blend
        shapes, then the P pose correctives when the model has any; columns are coordinate-major
        (all x, then all y, then all z). Rest-pose vertices are ``[1, coeffs, pose_features] @
        blend_basis``: template, shape and pose blend in one product, laid out as (B, 3, V).
    num_coeffs : K.
    joint_basis : (1 + K, 6 J) rows: the template, then the K coefficients; columns: the rest joints,
        then each joint's offset from its parent (the root's: its position), both in depth order
        (``tree.order``) so that the kinematic chain reads each level as a contiguous run.
        ``[1, coeffs] @ joint_basis`` is exact for rest joints: the regressor is linear.
    weights_t : (J, V) skinning weights, transposed, rows in depth order (like the transforms).
    tree : the kinematic tree.
    weights_sum_to_one : every vertex's weights sum to 1 within a few units of rounding of the arrays'
        dtype. Only then is a translation folded into the skinning transforms (``Σ w (A v + t) = Σ w A v +
        (Σ w) t``); else it is added after skinning. Float32-stored weights sum to 1 within ~1e-7: exact
        in float32, not in float64, where folding moved a body 1,000 km away by 13 cm.
    """

    blend_basis: Any
    num_coeffs: int
    joint_basis: Any
    weights_t: Any
    tree: KinematicTree
    weights_sum_to_one: bool = False
    _derived: dict = field(default_factory=dict, repr=False)

    @classmethod
    def build(
        cls,
        v_template: np.ndarray,
        shapedirs: np.ndarray,
        J_regressor: np.ndarray,
        posedirs: np.ndarray | None,
        weights: np.ndarray,
        parents: np.ndarray,
        convert: Callable[[np.ndarray], Any] = np.asarray,
    ) -> BodyArrays:
        """Arrange NumPy model arrays for evaluation; ``convert`` moves each to the target namespace.

        ``shapedirs`` is (V, 3, K) (shape and expression columns already concatenated), ``posedirs``
        (V, 3, P) or None; all-zero pose correctives are dropped.
        """
        v_template = np.asarray(v_template, dtype=np.float64)
        shapedirs = np.asarray(shapedirs, dtype=np.float64)
        J_regressor = np.asarray(J_regressor, dtype=np.float64)
        tree = KinematicTree.from_parents(parents)
        num_verts, num_coeffs = v_template.shape[0], shapedirs.shape[-1]
        # (rows, 3, V) blocks of the blend basis: template, coefficients, pose correctives (coordinate-major)
        parts = [v_template.T[None], shapedirs.transpose(2, 1, 0)]
        if posedirs is not None and np.any(posedirs):
            parts.append(np.asarray(posedirs).transpose(2, 1, 0))
        # rest joints of the template and per coefficient: (1 + K, J, 3)
        per_coeff = regress(J_regressor, shapedirs).transpose(2, 0, 1)  # (K, J, 3)
        joints = np.concatenate([regress(J_regressor, v_template)[None], per_coeff])
        parent = np.maximum(np.asarray(tree.parents), 0)
        offsets = joints - joints[:, parent] * (np.asarray(tree.parents) >= 0)[None, :, None]
        order = list(tree.order)
        joint_basis = np.concatenate([joints[:, order], offsets[:, order]], axis=1).reshape(1 + num_coeffs, -1)
        weights_t = convert(np.ascontiguousarray(np.asarray(weights).T[order]))
        return cls(
            blend_basis=_stacked(parts, 3 * num_verts, convert),
            num_coeffs=num_coeffs,
            joint_basis=convert(joint_basis),
            weights_t=weights_t,
            tree=tree,
            weights_sum_to_one=sums_to_one(weights, weights_t.dtype),
        )

    @property
    def has_pose_correctives(self) -> bool:
        return self.blend_basis.shape[0] > 1 + self.num_coeffs

    def derived(self, key: Any, make: Callable[[], Any]) -> Any:
        """``make()``, cached under ``key`` until the basis or the weights move (device, dtype, edit)."""
        owner = (array_identity(self.blend_basis), array_identity(self.weights_t))
        if self._derived.get("owner") != owner:
            self._derived.clear()
            self._derived["owner"] = owner
        if key not in self._derived:
            with for_cache():
                self._derived[key] = make()
        return self._derived[key]

    def vertex_blocks(self, size: int) -> tuple[blocked.VertexBlock, ...]:
        """The mesh cut into blocks of ``size`` vertices for :func:`blocked.posed_vertices` (cached)."""
        return self.derived(("blocks", size), lambda: self._vertex_blocks(size))

    def _vertex_blocks(self, size: int) -> tuple[blocked.VertexBlock, ...]:
        if size < self.weights_t.shape[1]:
            return blocked.vertex_blocks(self.weights_t, size, self.blend_basis)
        # one block of the whole mesh: its columns of the basis are all of them, in order, so the basis is packed
        # as it is (the same packed matrix as a gathered copy of its columns, without that 3 V-column copy)
        (block,) = blocked.vertex_blocks(self.weights_t, size)
        packed = self._packed_basis()
        return (block if packed is None else replace(block, packed_blend=packed),)

    def _packed_basis(self) -> Any:
        """The whole blend basis packed by :func:`gemm.pack` (None where it does not pack), once."""
        return self.derived("packed basis", lambda: gemm.pack(self.blend_basis))

    def vertex_subset(self, ids: np.ndarray) -> tuple[Any, Any, tuple[blocked.VertexBlock, ...]]:
        """Basis columns, weights and one vertex block for the vertices ``ids`` only (cached)."""

        def make():
            cols = index(vertex_columns(ids, self.weights_t.shape[1]), self.weights_t)
            rows = index(ids, self.weights_t)
            basis, weights_t = self.blend_basis[:, cols], self.weights_t[:, rows]
            return basis, weights_t, blocked.vertex_blocks(weights_t, max(len(ids), 1), basis)

        return self.derived(("subset", np.asarray(ids).tobytes()), make)

    def dqs_blocks(self, size: int, ids: np.ndarray | None = None) -> tuple:
        """Dual-quaternion skinning's vertex blocks, pair blocks and pairs (:mod:`dqs`), for the whole mesh
        (blocks of ``size`` vertices) or the vertices ``ids`` only (one block); cached."""
        if ids is None:
            key, weights_t, blocks = None, self.weights_t, self.vertex_blocks(size)
        else:
            key = np.asarray(ids).tobytes()
            _, weights_t, blocks = self.vertex_subset(ids)
        pairs = self.derived(("dqs pairs", key), lambda: dqs.pairs(weights_t, self.tree.order))
        return blocks, self.derived(("dqs pair blocks", key, size), lambda: dqs.pair_blocks(pairs, blocks)), pairs

    def packed_blend(self) -> tuple[Any, Any] | None:
        """The blend basis and its transpose packed for :func:`gemm.product_with_gradients` (cached);
        None where :mod:`~smplcore.engine.gemm` does not pack."""
        if not gemm.available(self.blend_basis):
            return None
        return self._packed_basis(), self.derived("packed basis t", lambda: gemm.pack(self.blend_basis.T))

    def map(self, fn: Callable[[Any], Any]) -> BodyArrays:
        """The same arrays with ``fn`` applied to each (e.g. a dtype or device change)."""
        weights_t = fn(self.weights_t)
        host = weights_t.detach().cpu().numpy() if is_torch(weights_t) else np.asarray(weights_t)
        exact = sums_to_one(host.T, weights_t.dtype)
        return BodyArrays(fn(self.blend_basis), self.num_coeffs, fn(self.joint_basis), weights_t, self.tree, exact)


def _with_one(coeffs: Any) -> Any:
    xp = namespace(coeffs)
    one = xp.ones_like(coeffs[:, :1]) if coeffs.shape[1] else coeffs.sum(axis=1, keepdims=True) + 1  # K = 0 too
    return xp.concat([one, coeffs], axis=1)


def blend_features(coeffs: Any, rotmats: Any | None, arrays: BodyArrays) -> Any:
    """(B, R) ``[1, coeffs, pose features]``: the rows of ``blend_basis`` a body uses (no pose
    features when ``rotmats`` is None or the model has no pose correctives)."""
    feats = _with_one(coeffs)
    if rotmats is not None and arrays.has_pose_correctives:
        feats = namespace(coeffs).concat([feats, pose_features(rotmats)], axis=1)
    return feats


def rest_vertices(coeffs: Any, rotmats: Any | None, arrays: BodyArrays) -> Any:
    """(B, 3, V) rest-pose vertices, one row per coordinate: template + shape blend (+ pose
    correctives when ``rotmats`` is given)."""
    return _blend(blend_features(coeffs, rotmats, arrays), arrays.blend_basis)


def _blend(feats: Any, basis: Any) -> Any:
    """(B, 3, n) ``feats @ basis`` over the rows ``feats`` has (a coordinate-major basis of n vertices)."""
    return (feats @ basis[: feats.shape[1]]).reshape(feats.shape[0], 3, -1)


def shaped_vertices(coeffs: Any, arrays: BodyArrays) -> Any:
    """(B, V, 3) rest-pose vertices for (B, K) shape coefficients (no pose correctives)."""
    return rest_vertices(coeffs, None, arrays).mT


def _depth_ordered_joints(coeffs: Any, joint_basis: Any, tree: KinematicTree) -> tuple[Any, Any]:
    """(B, J, 3) rest joints and (B, J, 3) offsets from their parents, in depth order."""
    batch, num_joints = coeffs.shape[0], len(tree.parents)
    both = (_with_one(coeffs) @ joint_basis).reshape(batch, 2, num_joints, 3)
    return both[:, 0], both[:, 1]


def pose_skeleton(coeffs: Any, rotmats: Any, joint_basis: Any, tree: KinematicTree) -> tuple[Any, Any]:
    """(B, J, 3) posed joints (model order) and (B, J, 12) skinning transforms (depth order)."""
    idx = tree.indices(rotmats)
    joints, offsets = _depth_ordered_joints(coeffs, joint_basis, tree)
    local = rotmats if idx["order"] is None else rotmats[:, idx["order"]]
    world_rot, world_pos = chain(local, offsets, tree)
    transforms = skinning_transforms(world_rot, world_pos, joints)
    return (world_pos if idx["inverse"] is None else world_pos[:, idx["inverse"]]), transforms


def sums_to_one(weights: np.ndarray, dtype: Any) -> bool:
    """Whether every row of (V, J) ``weights`` sums to 1 within 4 units of rounding of ``dtype`` (a NumPy or
    torch float dtype), summed in float64."""
    eps = _eps(dtype)
    sums = np.asarray(weights, dtype=np.float64).sum(axis=1)
    return bool(sums.size == 0 or np.abs(sums - 1).max() <= 4 * eps)


def _eps(dtype: Any) -> float:
    if isinstance(dtype, np.dtype) or isinstance(dtype, type):
        return float(np.finfo(dtype).eps)
    import torch

    return float(torch.finfo(dtype).eps)


def rest_joints(coeffs: Any, arrays: BodyArrays) -> Any:
    """(B, J, 3) rest-pose joints for (B, K) shape coefficients (no mesh is built)."""
    joints = _depth_ordered_joints(coeffs, arrays.joint_basis, arrays.tree)[0]
    inverse = arrays.tree.indices(coeffs)["inverse"]
    return joints if inverse is None else joints[:, inverse]


def forward(
    coeffs: Any,
    rotmats: Any,
    arrays: BodyArrays,
    *,
    vertices: bool = True,
    translation: Any = None,
    kernel: str = "blocked",
    skinning: str = "lbs",
    host_skeleton: bool | None = None,
) -> tuple[Any | None, Any, Any]:
    """Posed body.

    Parameters
    ----------
    coeffs : (B, K) shape (and expression) coefficients, matching ``arrays``.
    rotmats : (B, J, 3, 3) local joint rotations.
    arrays : the model.
    vertices : build the mesh (False: joints only).
    translation : (B, 3) added to the vertices (not to the joints or transforms), or None; folded into the
        skinning only where that is exact (see :attr:`BodyArrays.weights_sum_to_one`).
    kernel : ``"blocked"`` (no autograd graph) or ``"autograd"`` (torch).
    skinning : ``"lbs"`` or ``"dqs"`` (dual-quaternion skinning, :mod:`smplcore.engine.kernels.dqs`).
    host_skeleton : the plan's choice (:class:`smplcore.engine.kernels.select.Plan`): pose the skeleton in NumPy
        (a small CPU torch batch without autograd); None: decided here from the arrays (callers without a plan).

    Returns
    -------
    posed_vertices : (B, V, 3), or None when ``vertices`` is False.
    posed_joints : (B, J, 3).
    transforms : (B, J, 12) skinning transforms in depth order (the rows of ``arrays.weights_t``),
        for posing any further rest-pose points.
    """
    host: list[Any] = [None]
    if host_skeleton is not False:
        host = [host_numpy(coeffs), host_numpy(rotmats), host_numpy(arrays.joint_basis, max_batch=None)]
    if is_torch(rotmats) and all(a is not None for a in host):  # small batch: per-joint math is faster in NumPy
        posed_joints, transforms = (from_numpy(a) for a in pose_skeleton(host[0], host[1], host[2], arrays.tree))
    else:
        posed_joints, transforms = pose_skeleton(coeffs, rotmats, arrays.joint_basis, arrays.tree)
    if not vertices:
        return None, posed_joints, transforms
    feats = blend_features(coeffs, rotmats, arrays)
    # dual quaternions are normalised after blending: folding is exact whatever the weights sum to
    fold = skinning == "dqs" or arrays.weights_sum_to_one
    verts = _skin_from_basis(
        feats,
        transforms,
        arrays.blend_basis,
        arrays.weights_t,
        arrays.vertex_blocks,
        translation if fold else None,
        kernel,
        arrays.packed_blend,
        (arrays.dqs_blocks, arrays.tree) if skinning == "dqs" else None,
    )
    if translation is not None and not fold:
        verts = verts + translation[:, None]
    return verts, posed_joints, transforms


def posed_vertex_subset(
    coeffs: Any,
    rotmats: Any,
    transforms: Any,
    arrays: BodyArrays,
    ids: np.ndarray,
    kernel: str = "blocked",
    skinning: str = "lbs",
) -> Any:
    """(B, n, 3) posed vertices ``ids`` only (untranslated), from :func:`forward`'s ``transforms``."""
    basis, weights_t, blocks = arrays.vertex_subset(ids)
    feats = blend_features(coeffs, rotmats, arrays)
    dq = ((lambda size: arrays.dqs_blocks(size, ids)), arrays.tree) if skinning == "dqs" else None
    return _skin_from_basis(feats, transforms, basis, weights_t, lambda size: blocks, None, kernel, None, dq)


# Vertices per block under autograd: small enough that a block uses a handful of joints; up to
# _GRAD_FEW_BODIES bodies the whole mesh is one block (fewer operations: fitting runs at B = 1).
_GRAD_BLOCK = 1024
_GRAD_FEW_BODIES = 16


def _skin_from_basis(
    feats: Any,
    transforms: Any,
    basis: Any,
    weights_t: Any,
    blocks: Callable[[int], Any],
    translation: Any,
    kernel: str,
    packed_blend: Callable[[], Any] | None = None,
    dqs_blocks: tuple[Callable[[int], Any], KinematicTree] | None = None,
) -> Any:
    """Blend ``feats @ basis`` and skin it: vertex-blocked (kernel ``blocked``, no autograd graph), or
    with one autograd node for the skinning (kernel ``autograd``, torch). ``blocks(size)`` gives the
    vertex blocks of about ``size`` vertices; ``packed_blend()`` the basis packed for
    :func:`gemm.product_with_gradients` (or None). With ``dqs_blocks`` (``size`` → the blocks and pairs of
    :meth:`BodyArrays.dqs_blocks`, and the tree), dual-quaternion skinning instead (:mod:`dqs`)."""
    if dqs_blocks is not None:
        return _dqs_from_basis(feats, transforms, basis, translation, kernel, packed_blend, *dqs_blocks)
    transforms = with_translation(transforms, translation)
    if kernel == "blocked":
        size = blocked.block_size(feats.shape[0], weights_t.shape[1])
        return blocked.posed_vertices(feats, transforms, basis, blocks(size))
    packed = None
    if packed_blend is not None and not basis.requires_grad and feats.shape[1] == basis.shape[0]:
        packed = packed_blend()
    if packed is not None:
        v = gemm.product_with_gradients(feats, *packed).view(feats.shape[0], 3, -1)
    else:
        v = _blend(feats, basis)
    from smplcore.engine.kernels.skin_autograd import skin_with_gradients

    few = feats.shape[0] <= _GRAD_FEW_BODIES  # per-op overhead dominates: one block
    return skin_with_gradients(v, transforms, blocks(weights_t.shape[1] if few else _GRAD_BLOCK))


def _dqs_from_basis(
    feats: Any,
    transforms: Any,
    basis: Any,
    translation: Any,
    kernel: str,
    packed_blend: Callable[[], Any] | None,
    dqs_blocks: Callable[[int], Any],
    tree: KinematicTree,
) -> Any:
    """Dual-quaternion skinning of ``feats @ basis`` (block by block for the blocked kernel, else one product
    for the whole rest mesh), moved by ``translation``."""
    batch, num_verts = feats.shape[0], basis.shape[1] // 3
    if kernel == "blocked":
        size = blocked.block_size(batch, num_verts)
    else:
        size = num_verts if batch <= _GRAD_FEW_BODIES else _GRAD_BLOCK
    blocks, pblocks, pairs = dqs_blocks(size)
    rest = None
    if kernel != "blocked":
        full_rows = feats.shape[1] == basis.shape[0]
        trainable = getattr(basis, "requires_grad", False)
        packed = packed_blend() if packed_blend is not None and full_rows and not trainable else None
        rest = (
            _blend(feats, basis) if packed is None else gemm.product_with_gradients(feats, *packed).view(batch, 3, -1)
        )
    # translated joints: the blend of (T q_j) is T times the blend of q_j, and its rotation part is the same, so
    # the result is the skinned vertex plus T (as LBS, no pass over the mesh)
    return dqs.skin(rest, with_translation(transforms, translation), blocks, pblocks, pairs, tree, feats, basis)
