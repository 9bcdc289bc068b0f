"""The public facts of a body model with its options applied: :class:`Rig`.

A :class:`Rig` is what every consumer of a model (fitting, the motion pipeline, exporters, viewers,
measurements) reads: the template, the blend bases and the joint directions they induce, the joint
regressor, the skinning weights, the kinematic tree, the pose blocks with their column offsets, the hand
PCA and the mean pose, joint names with their left/right twins, the rows of every output point and the
UV map. It is frozen and its arrays are read-only float64 (int64 for indices); the caller casts.

Every front end has one: ``smplcore.create(...).rig``, ``smplcore.BodyModel(...).rig``. The forward of the
model is, for a full pose ``θ`` (axis-angle, (3 J,), the ``pose_mean`` included) and coefficients ``c``::

    v_shaped = template + shapedirs·β + exprdirs·ψ + dmpldirs·δ
    joints   = joint_regressor @ v_shaped  (= template_joints + joint_shapedirs·β + ...)
    v_posed  = v_shaped + Σ_k posedirs[k] f_k(θ),   f = (R_j - I) flattened, joints 1..J-1
    vertices = Σ_j weights[:, j] G_j(θ) (v_posed - joints_j) + transl

and the output joints are the posed ``joints`` followed by the :attr:`Rig.output_joint_names` points
(extra vertex joints, face landmarks, the dynamic contour, regressed keypoints), see :meth:`Rig.output_rows`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import scipy.sparse as sp

    from smplcore.frontend.setup import ModelSetup

__all__ = ["PoseBlock", "Rig", "UVMap", "rig_from_setup", "rig_of"]


@dataclass(frozen=True)
class PoseBlock:
    """One pose keyword of the forward (``global_orient``, ``body_pose``, ``left_hand_pose``, ...).

    Attributes
    ----------
    name : the forward's keyword.
    first_joint : the block's first joint in the skeleton (and in the full pose, ``3 first_joint``).
    num_joints : consecutive joints the block sets.
    width : values per body in axis-angle mode: ``3 num_joints``, or the PCA coefficient count.
    pca : whether the block is given as hand-PCA coefficients (``hand_components[name]`` maps them).
    offset : the block's first column in the flat pose vector (the blocks' widths in order).
    """

    name: str
    first_joint: int
    num_joints: int
    width: int
    pca: bool
    offset: int = 0

    @property
    def columns(self) -> slice:
        """The block's columns in the flat pose vector (PCA coefficients for PCA blocks)."""
        return slice(self.offset, self.offset + self.width)

    @property
    def full_pose_columns(self) -> slice:
        """The block's columns in the (3 J,) axis-angle full pose."""
        return slice(3 * self.first_joint, 3 * (self.first_joint + self.num_joints))


@dataclass(frozen=True, eq=False)
class UVMap:
    """Texture coordinates: ``vt`` (T, 2) (OBJ convention, v up) and ``ft`` (F, 3) int64 indices into ``vt``,
    corner for corner with the model's faces."""

    vt: np.ndarray
    ft: np.ndarray


@dataclass(frozen=True, eq=False)
class Rig:
    """A body model with its options applied (``num_betas``, ``use_pca``, ``flat_hand_mean``, ``v_template``,
    ``age='kid'``, ``dmpl_path``, ``use_face_contour``, ``joint_regressors``, ...), as read-only NumPy arrays.

    Shapes use ``V`` vertices, ``F`` faces, ``J`` skeleton joints, ``J'`` output joints.

    Attributes
    ----------
    model_type : ``'smpl'``, ``'smplh'``, ``'smplx'``, ``'mano'``, ``'flame'`` or ``'open'``.
    gender : ``'neutral'``, ``'male'`` or ``'female'`` (``'neutral'`` for MANO, whose hand is in ``side``).
    source : the file the model came from (or a description).
    num_vertices, num_joints, num_betas, num_expression_coeffs, num_dmpls : sizes (coefficient counts as
        the forward takes them, after the options; ``age='kid'`` adds one beta).
    template : (V, 3) rest-pose template (the ``v_template`` option applied).
    faces : (F, 3) int64 triangles.
    shapedirs : (V, 3, num_betas) shape basis; exprdirs : (V, 3, E) expression basis (E may be 0);
    dmpldirs : (V, 3, D) DMPL soft-tissue basis, or None.
    posedirs : (9 (J - 1), V, 3) pose-corrective basis; row ``(j - 1) * 9 + 3 r + c`` is the blend shape of
        entry ``(r, c)`` of ``R_j - I`` (zeros for a model without correctives, see ``has_pose_correctives``).
    joint_regressor : (J, V) dense.
    template_joints : (J, 3) joints of the template; joint_shapedirs : (J, 3, num_betas),
        joint_exprdirs : (J, 3, E), joint_dmpldirs : (J, 3, D) or None: the joint directions the bases induce.
    weights : (V, J) skinning weights.
    parents : (J,) int64, -1 for the root.
    joint_names : the J skeleton joints; output_joint_names : the J' rows of the forward's ``joints``.
    mirror : (J,) int64 each joint's left/right twin (itself on the midline).
    pose_blocks : the forward's pose keywords in full-pose order.
    hand_components : (C, 45) PCA basis of each PCA block; hand_means : (45,) mean pose of each hand block
        (zeros when flat); pose_mean : (3 J,) added to the full pose (the hand means in place).
    uv : the UV map, or None.
    skinning : ``'lbs'`` or ``'dqs'``.
    side : ``'left'`` / ``'right'`` for MANO, else None.
    extra_vertices : (X,) int64 vertices appended to the joints (extra joints: nose, toes, fingertips, ...).
    landmark_faces : (L, 3) int64 vertices of each static landmark's face; landmark_weights : (L, 3) barycentric.
    contour_faces : (79, 17, 3) int64 and contour_weights : (79, 17, 3) of the dynamic face contour (the row is
        picked from the neck chain's rotation, ``contour_chain``), or None without ``use_face_contour``.
    regressor_vertices : (n,) int64 and regressor_weights : (K, n): points of the ``joint_regressors`` option
        as combinations of posed vertices (K = 0 without it).
    has_pose_correctives : whether the file has non-zero pose correctives.
    """

    model_type: str
    gender: str
    source: str
    num_vertices: int
    num_joints: int
    num_betas: int
    num_expression_coeffs: int
    num_dmpls: int
    template: np.ndarray
    faces: np.ndarray
    shapedirs: np.ndarray
    exprdirs: np.ndarray
    dmpldirs: np.ndarray | None
    posedirs: np.ndarray
    joint_regressor: np.ndarray
    template_joints: np.ndarray
    joint_shapedirs: np.ndarray
    weights: np.ndarray
    parents: np.ndarray
    joint_names: tuple[str, ...]
    output_joint_names: tuple[str, ...]
    mirror: np.ndarray
    pose_blocks: tuple[PoseBlock, ...]
    hand_components: dict[str, np.ndarray]
    hand_means: dict[str, np.ndarray]
    pose_mean: np.ndarray
    uv: UVMap | None
    skinning: str
    # additions to the agreed fields
    side: str | None = None
    joint_exprdirs: np.ndarray | None = None
    joint_dmpldirs: np.ndarray | None = None
    extra_vertices: np.ndarray | None = None
    landmark_faces: np.ndarray | None = None
    landmark_weights: np.ndarray | None = None
    contour_faces: np.ndarray | None = None
    contour_weights: np.ndarray | None = None
    contour_chain: tuple[int, ...] = ()
    regressor_vertices: np.ndarray | None = None
    regressor_weights: np.ndarray | None = None
    has_pose_correctives: bool = True

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                object.__setattr__(self, f.name, _read_only(value))
            elif isinstance(value, dict):
                object.__setattr__(self, f.name, {k: _read_only(v) for k, v in value.items()})
        if self.uv is not None:
            object.__setattr__(self, "uv", UVMap(_read_only(self.uv.vt), _read_only(self.uv.ft)))

    # -- derived facts ----------------------------------------------------------------------------

    @property
    def num_pose(self) -> int:
        """Columns of the flat pose vector (the pose blocks' widths summed)."""
        return sum(b.width for b in self.pose_blocks)

    @property
    def num_output_joints(self) -> int:
        """Rows of the forward's ``joints`` output (J')."""
        return len(self.output_joint_names)

    @property
    def blend_dirs(self) -> np.ndarray:
        """(V, 3, K) shape, expression and DMPL bases in the order of the forward's coefficients."""
        parts = [self.shapedirs, self.exprdirs] + ([] if self.dmpldirs is None else [self.dmpldirs])
        return np.concatenate(parts, axis=-1)

    @property
    def levels(self) -> tuple[np.ndarray, ...]:
        """The joints by depth in the tree: level 0 is the root, level ``d`` the joints ``d`` bones below it."""
        depth = np.zeros(self.num_joints, np.int64)
        for j in range(1, self.num_joints):
            depth[j] = depth[self.parents[j]] + 1
        return tuple(np.flatnonzero(depth == d) for d in range(int(depth.max()) + 1))

    def block(self, name: str) -> PoseBlock:
        """The pose block named ``name`` (a KeyError naming the blocks otherwise)."""
        for block in self.pose_blocks:
            if block.name == name:
                return block
        raise KeyError(
            f"{name!r}: not a pose block of this {self.model_type} model; expected one of "
            f"{[b.name for b in self.pose_blocks]}"
        )

    def pose_map(self) -> np.ndarray:
        """(num_pose, 3 J): the flat pose vector ``q`` (PCA coefficients for PCA blocks) to the axis-angle full
        pose: ``full_pose = pose_mean + q @ pose_map``."""
        out = np.zeros((self.num_pose, 3 * self.num_joints))
        for b in self.pose_blocks:
            basis = self.hand_components[b.name] if b.pca else np.eye(b.width)
            out[b.columns, b.full_pose_columns] = basis
        return out

    def output_rows(self) -> sp.csr_matrix:
        """(J', V + J) each output joint as a combination of the posed vertices and then the posed skeleton
        joints. The dynamic contour's rows (which vertices they read depends on the pose) are empty; see
        :attr:`dynamic_output_rows`."""
        import scipy.sparse as sp

        V, J = self.num_vertices, self.num_joints
        rows: list[np.ndarray] = [np.arange(J)]
        cols: list[np.ndarray] = [V + np.arange(J)]
        vals: list[np.ndarray] = [np.ones(J)]
        first = J
        if self.extra_vertices is not None and self.extra_vertices.size:
            n = self.extra_vertices.size
            rows.append(first + np.arange(n))
            cols.append(self.extra_vertices)
            vals.append(np.ones(n))
            first += n
        if self.landmark_faces is not None and self.landmark_faces.size:
            assert self.landmark_weights is not None
            n = len(self.landmark_faces)
            rows.append(np.repeat(first + np.arange(n), 3))
            cols.append(self.landmark_faces.ravel())
            vals.append(self.landmark_weights.ravel())
            first += n
        if self.contour_faces is not None:
            first += self.contour_faces.shape[1]
        if self.regressor_weights is not None and self.regressor_weights.size:
            assert self.regressor_vertices is not None
            k, n = self.regressor_weights.shape
            rows.append(np.repeat(first + np.arange(k), n))
            cols.append(np.tile(self.regressor_vertices, k))
            vals.append(self.regressor_weights.ravel())
        shape = (self.num_output_joints, V + J)
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=shape)

    @property
    def dynamic_output_rows(self) -> np.ndarray:
        """(n,) int64 the output joints whose vertices depend on the pose (the dynamic face contour)."""
        if self.contour_faces is None:
            return np.zeros(0, np.int64)
        first = self.num_joints + _size(self.extra_vertices) + _size(self.landmark_weights, axis=0)
        return first + np.arange(self.contour_faces.shape[1], dtype=np.int64)


def _size(array: np.ndarray | None, axis: int | None = None) -> int:
    if array is None:
        return 0
    return int(array.size if axis is None else array.shape[axis])


def _read_only(array: Any) -> np.ndarray:
    view = np.asarray(array).view()
    view.flags.writeable = False
    return view


def _f64(array: Any) -> np.ndarray:
    return np.asarray(array, dtype=np.float64)


def mirror_of(names: tuple[str, ...]) -> np.ndarray:
    """(J,) each name's left/right twin (``left_x`` <-> ``right_x``), itself when it has none."""
    index = {n: i for i, n in enumerate(names)}
    out = np.arange(len(names), dtype=np.int64)
    for i, name in enumerate(names):
        for a, b in (("left_", "right_"), ("right_", "left_")):
            if name.startswith(a) and b + name[len(a) :] in index:
                out[i] = index[b + name[len(a) :]]
    return out


def rig_of(setup: ModelSetup) -> Rig:
    """The :class:`Rig` of a front end's setup, built on first use and kept in the setup's cache (a change to the
    setup's arrays drops it: ``setup._cache.pop("rig")``), so every front end shares one rule."""
    rig = setup._cache.get("rig")
    if rig is None:
        rig = setup._cache["rig"] = rig_from_setup(setup)
    return rig


def rig_from_setup(setup: ModelSetup, *, shapedirs: np.ndarray | None = None) -> Rig:
    """The :class:`Rig` of a front end's :class:`~smplcore.frontend.setup.ModelSetup`.

    ``shapedirs`` replaces the setup's shape basis (MANO's ``fix_left_shapedirs``)."""
    from smplcore.engine.body import regress

    spec, d = setup.spec, setup.data
    num_vertices, num_joints = d.num_vertices, d.num_joints
    template = _f64(d.v_template)
    regressor = _f64(d.J_regressor.toarray() if hasattr(d.J_regressor, "toarray") else d.J_regressor)
    shape = _f64(setup.shapedirs if shapedirs is None else shapedirs)
    expr = _f64(setup.exprdirs)
    dmpl = None if setup.dmpldirs is None else _f64(setup.dmpldirs)

    def joint_dirs(dirs: np.ndarray) -> np.ndarray:  # over each joint's few vertices: the directions cost little
        return regress(regressor, dirs)

    num_pose = 9 * (num_joints - 1)
    has_correctives = d.posedirs is not None and bool(np.any(d.posedirs))
    if d.posedirs is None:
        posedirs = np.broadcast_to(np.zeros((), np.float64), (num_pose, num_vertices, 3))
    else:
        posedirs = _f64(d.posedirs).transpose(2, 0, 1)  # (V, 3, P) -> (P, V, 3)

    blocks, offset, joint = [], 0, 0
    for b in spec.pose_blocks:
        width = setup.pose_width(b.name)
        blocks.append(PoseBlock(b.name, joint, b.num_joints, width, b.name in setup.hand_components, offset))
        offset += width
        joint += b.num_joints

    joint_names = tuple(spec.joint_names if d.joint_names is None else d.joint_names)
    kp = setup.keypoints
    contour = setup.use_face_contour and d.dynamic_lmk_faces_idx is not None
    landmarks = bool(spec.landmarks) and d.lmk_faces_idx is not None
    reg = setup.regressor
    mano = spec.model_type == "mano"
    return Rig(
        model_type=spec.model_type,
        gender="neutral" if mano else str(d.gender),
        source=str(d.source),
        num_vertices=num_vertices,
        num_joints=num_joints,
        num_betas=int(setup.num_betas),
        num_expression_coeffs=int(setup.num_expression_coeffs),
        num_dmpls=int(setup.num_dmpls),
        template=template,
        faces=np.asarray(d.faces, np.int64),
        shapedirs=shape,
        exprdirs=expr,
        dmpldirs=dmpl,
        posedirs=posedirs,
        joint_regressor=regressor,
        template_joints=regress(regressor, template),
        joint_shapedirs=joint_dirs(shape),
        weights=_f64(d.weights),
        parents=np.asarray(d.parents, np.int64),
        joint_names=joint_names,
        output_joint_names=tuple(setup.output_joint_names),
        mirror=mirror_of(joint_names),
        pose_blocks=tuple(blocks),
        hand_components={k: _f64(v) for k, v in setup.hand_components.items()},
        hand_means={k: _f64(v) for k, v in setup.hand_means.items()},
        pose_mean=_f64(setup.pose_mean).reshape(-1),
        uv=UVMap(_f64(d.vt), np.asarray(d.ft, np.int64)) if d.has_uv else None,
        skinning=setup.skinning,
        side=str(d.gender) if mano else None,
        joint_exprdirs=joint_dirs(expr),
        joint_dmpldirs=None if dmpl is None else joint_dirs(dmpl),
        extra_vertices=np.asarray(kp.extra, np.int64),
        landmark_faces=np.asarray(kp.corners, np.int64) if landmarks else np.zeros((0, 3), np.int64),
        landmark_weights=_f64(d.lmk_bary_coords) if landmarks else np.zeros((0, 3)),
        contour_faces=np.asarray(kp.contour_corners, np.int64) if contour else None,
        contour_weights=_f64(d.dynamic_lmk_bary_coords) if contour else None,
        contour_chain=tuple(int(j) for j in setup.neck_chain),
        regressor_vertices=np.zeros(0, np.int64) if reg is None else np.asarray(reg.vertex_ids, np.int64),
        regressor_weights=np.zeros((0, 0)) if reg is None else _f64(reg.weights),
        has_pose_correctives=has_correctives,
    )
