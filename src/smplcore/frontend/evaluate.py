"""One evaluation of a model, for both front ends: inputs in, a typed :class:`Evaluation` out.

:func:`evaluate` turns keyword parameters (NumPy or torch) into the full pose (hand PCA and the mean
pose applied), picks the kernel (:func:`smplcore.engine.kernels.select`), runs it and appends the
extra vertex joints and face landmarks. The arrays come from an :class:`ArraySource`, which each
front end provides (the torch modules from their buffers, so that edits of a buffer reach the output).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from smplcore.engine import body as engine
from smplcore.engine import reference
from smplcore.engine.backend import eye, from_numpy, host_numpy, is_torch, namespace
from smplcore.engine.kernels.select import Plan, plan, traced
from smplcore.engine.landmarks import barycentric_points, contour_rows
from smplcore.engine.rotations import rodrigues
from smplcore.engine.skeleton import records_gradients
from smplcore.frontend import inputs
from smplcore.frontend.inputs import batch_of, rotmat_rows, rows
from smplcore.frontend.setup import ModelSetup


@dataclass(frozen=True)
class PlainArrays:
    """A model's arrays as the official files lay them out, for :mod:`smplcore.engine.reference`.

    ``shapedirs`` (V, 3, K) holds the shape and then the expression columns; ``posedirs`` is
    (9 (J - 1), 3 V) or None; ``parents`` a tuple of ints.
    """

    v_template: Any
    shapedirs: Any
    posedirs: Any | None
    J_regressor: Any
    parents: tuple[int, ...]
    weights: Any


class ArraySource(Protocol):
    """Where :func:`evaluate` takes a model's arrays from, in the namespace/dtype/device of ``like``."""

    def fast_arrays(self) -> engine.BodyArrays: ...

    def plain_arrays(self) -> PlainArrays: ...

    def constant(self, name: str, like: Any) -> Any: ...

    def trainable(self) -> bool: ...

    @property
    def handle(self) -> int | None:
        """The arrays' name in :mod:`smplcore.engine.kernels.ops` (torch modules), or None: then a
        ``torch.compile``-d call runs the reference kernel."""
        ...

    def latest_arrays(self) -> engine.BodyArrays:
        """The fast arrays as last built (their tree and layout), without checking for edits."""
        ...


@dataclass(frozen=True)
class Evaluation:
    """The outputs of one call. **Every position is translated** by ``transl`` (when one was given).

    Attributes
    ----------
    vertices : (B, V, 3), or None for a joints-only call.
    joints : (B, J', 3): the J skeleton joints, then the extra vertex joints and face landmarks.
    untranslated_joints : (B, J', 3) the same before translation (for smplx's ``joint_mapper``).
    transl : (B, 3) or None.
    full_pose : (B, 3 J) axis-angle (mean pose included), or (B, J, 3, 3) rotation matrices.
    rotmats : (B, J, 3, 3) local joint rotations.
    betas : (B, num_betas); expression : (B, num_expression_coeffs) or None.
    pose : each pose block as used, (B, 3 n) axis-angle (hand PCA expanded) or (B, n, 3, 3).
    kernel : the kernel that ran.
    """

    vertices: Any | None
    joints: Any
    untranslated_joints: Any
    transl: Any | None
    full_pose: Any
    rotmats: Any
    betas: Any
    expression: Any | None
    pose: dict[str, Any]
    kernel: str


def evaluate(
    setup: ModelSetup,
    source: ArraySource,
    params: dict[str, Any],
    *,
    rotation_matrices: bool = False,
    vertices: bool = True,
    like: Any = None,
    kernel: str = "auto",
    check_finite: bool = True,
    check_rotations: bool = False,
    template: Any = None,
) -> Evaluation:
    """Run the model.

    Parameters
    ----------
    setup : the model with its options.
    source : the model's arrays.
    params : ``betas``, ``expression``, ``transl``, ``dmpls`` (models with DMPL blend shapes) and one
        entry per pose block; None entries are zero (identity rotations); see
        :mod:`smplcore.frontend.inputs` for the layouts.
    rotation_matrices : the pose blocks are rotation matrices (no PCA, no mean pose added).
    vertices : build the mesh; without it only the joints (extra joints and landmarks included).
    like : an array giving namespace, dtype and device when every parameter is None.
    kernel : ``"auto"`` or a kernel to force (:data:`smplcore.engine.kernels.KERNELS`).
    check_finite : refuse NaN / inf inputs (naming the argument and the first bad index); skipped for
        non-CPU tensors and under tracing, where it would cost a device round trip.
    check_rotations : with ``rotation_matrices``, refuse matrices that are not rotations.
    template : a rest template replacing the source's for this call: (V, 3), or (N, V, 3) one per body (the
        call's batch is then N; parameters of batch 1 broadcast). Runs the reference kernel, which takes the
        template as an input (the fast kernels hold theirs in their bases).
    """
    spec = setup.spec
    if template is not None:
        if kernel not in ("auto", "reference"):
            raise ValueError(
                f"kernel={kernel!r} cannot run a per-call or per-body v_template (its bases hold the model's one "
                "template): it runs the reference kernel; pass kernel='auto' or 'reference'"
            )
        kernel = "reference"
    given = {k: v for k, v in params.items() if v is not None}
    if "dmpls" in given and not setup.num_dmpls:
        raise ValueError(
            "dmpls: this model has no DMPL blend shapes; create it with dmpl_path=<the dmpl.npz file> "
            "(smplcore.create(..., dmpl_path=...) or BodyModel(..., dmpl_path=...)), or leave dmpls out"
        )
    ref = next(iter(given.values()), like)
    xp = namespace(ref)
    batched = {k: (v if v.ndim > 1 else v[None]) for k, v in given.items()}
    if template is not None and template.ndim == 3:  # one template per body: a batch like a parameter's
        batched["v_template"] = template
    batch = batch_of(batched)
    if batch == 0:  # empty outputs of the right shapes: one zero body, then no rows of it
        ones = {k: v.sum(axis=0, keepdims=True) * 0 if v.ndim > 1 else v for k, v in given.items()}  # (1, ...) zeros
        return _empty(
            evaluate(
                setup,
                source,
                ones,
                rotation_matrices=rotation_matrices,
                vertices=vertices,
                like=like,
                kernel=kernel,
                check_finite=False,
                template=None if template is None else template[:1] if template.ndim == 3 else template,
            )
        )
    if check_finite and not (is_torch(ref) and (ref.device.type != "cpu" or traced())):
        inputs.check_finite(given if template is None else {**given, "v_template": template})
    zeros = source.constant("zero", ref)  # (1, 1) in the model's dtype and device
    how: Plan = plan(
        kernel,
        zeros,
        gradients=_records(given.values()),
        trainable_model=source.trainable(),
        batch=batch,
        operator_arrays=source.handle is not None,
        skinning=setup.skinning,
    )
    chosen, operators = how.kernel, how.operators

    def coefficients(name: str, width: int) -> Any:
        value = given.get(name)
        if value is None or width == 0:
            return xp.broadcast_to(zeros, (batch, width)) if width else xp.broadcast_to(zeros[:, :0], (batch, 0))
        return rows(name, value, batch, width, allow_narrower=True)

    betas = coefficients("betas", setup.num_betas)
    expression = coefficients("expression", setup.num_expression_coeffs) if spec.has_expression else None
    coeffs = betas if expression is None else xp.concat([betas, expression], axis=1)
    if setup.num_dmpls:  # DMPL blend shapes follow the shape and expression ones (setup.blend_dirs)
        coeffs = xp.concat([coeffs, coefficients("dmpls", setup.num_dmpls)], axis=1)

    pose: dict[str, Any] = {}
    if rotation_matrices:
        identity = eye(3, zeros)
        for block in spec.pose_blocks:
            value = given.get(block.name)
            pose[block.name] = (
                xp.broadcast_to(identity, (batch, block.num_joints, 3, 3))
                if value is None
                else rotmat_rows(block.name, value, batch, block.num_joints)
            )
            if check_rotations and value is not None:
                inputs.check_rotations(block.name, pose[block.name])
        rotmats = full_pose = xp.concat(list(pose.values()), axis=1)
    else:
        for block in spec.pose_blocks:
            value = given.get(block.name)
            if value is None:
                value = xp.broadcast_to(zeros, (batch, 3 * block.num_joints))
            elif block.name in setup.pca_blocks:
                value = rows(block.name, value, batch, setup.pose_width(block.name))
                value = value @ source.constant(f"hand_components/{block.name}", zeros)
            else:
                value = rows(block.name, value, batch, 3 * block.num_joints, joints=block.num_joints)
            pose[block.name] = value
        full_pose = xp.concat(list(pose.values()), axis=1)
        if setup.has_pose_mean:
            full_pose = full_pose + source.constant("pose_mean", zeros)
        rotvecs = full_pose.reshape(batch, -1, 3)
        host = host_numpy(rotvecs) if how.host_skeleton else None
        if host is not None:  # a small CPU batch: the same formula in NumPy, on the same memory
            rotmats = from_numpy(rodrigues(host))
        elif chosen == "reference" or operators:
            rotmats = reference.rodrigues(rotvecs)
        else:
            rotmats = rodrigues(rotvecs)

    transl = given.get("transl")
    transl = None if transl is None else rows("transl", transl, batch, 3)
    if chosen == "reference":
        verts, joints = _reference_forward(setup, source, coeffs, rotmats, zeros, template)
    elif operators:
        verts, joints = _operator_forward(setup, source, coeffs, rotmats, vertices, transl, chosen == "autograd", zeros)
    else:
        verts, joints = _fast_forward(setup, source.fast_arrays(), coeffs, rotmats, vertices, transl, how)
    if transl is not None:
        shifted = joints + transl[:, None]
        if chosen == "reference":
            verts = verts + transl[:, None]
    else:
        shifted = joints
    return Evaluation(
        vertices=verts if vertices else None,
        joints=shifted,
        untranslated_joints=joints,
        transl=transl,
        full_pose=full_pose,
        rotmats=rotmats,
        betas=betas,
        expression=expression,
        pose=pose,
        kernel=chosen,
    )


def _empty(out: Evaluation) -> Evaluation:
    """``out`` (of one body) with no rows: the outputs of a batch of 0."""

    def none_or_empty(x: Any) -> Any:
        return None if x is None else x[:0]

    return Evaluation(
        vertices=none_or_empty(out.vertices),
        joints=out.joints[:0],
        untranslated_joints=out.untranslated_joints[:0],
        transl=none_or_empty(out.transl),
        full_pose=out.full_pose[:0],
        rotmats=out.rotmats[:0],
        betas=out.betas[:0],
        expression=none_or_empty(out.expression),
        pose={k: v[:0] for k, v in out.pose.items()},
        kernel=out.kernel,
    )


def _records(values: Any) -> bool:
    values = list(values)
    return bool(values) and records_gradients(*values)


def _reference_forward(
    setup: ModelSetup, source: ArraySource, coeffs: Any, rotmats: Any, like: Any, template: Any = None
) -> tuple:
    """Vertices (untranslated) and all output joints by the plain forward of :mod:`smplcore.engine.reference`,
    on the source's template or ``template`` ((V, 3), or (B, V, 3) one per body)."""
    p = source.plain_arrays()
    template = p.v_template if template is None else template
    verts, joints, _ = reference.forward(
        template, p.shapedirs, p.posedirs, p.J_regressor, p.parents, p.weights, coeffs, rotmats, setup.skinning
    )
    return verts, _with_mesh_keypoints(setup, source, joints, verts, rotmats, like)


def _operator_forward(
    setup: ModelSetup,
    source: ArraySource,
    coeffs: Any,
    rotmats: Any,
    vertices: bool,
    transl: Any | None,
    gradients: bool,
    like: Any,
) -> tuple:
    """Vertices (translated; None when not asked for and no keypoint needs them) and all output joints
    (untranslated) by the fast kernels as torch custom operators (:mod:`smplcore.engine.kernels.ops`), under
    ``torch.compile``."""
    from smplcore.engine.kernels import ops

    mesh = vertices or setup.keypoints.extra.size or setup.spec.landmarks or setup.regressor is not None
    arrays, handle = source.latest_arrays(), source.handle
    assert handle is not None  # evaluate() runs the reference kernel for sources without one
    if not mesh:
        return None, ops.joints(handle, arrays, coeffs, rotmats)
    verts, joints = ops.forward(handle, arrays, coeffs, rotmats, translation=transl, gradients=gradients)
    return verts, _with_mesh_keypoints(setup, source, joints, verts, rotmats, like, offset=transl)


def _with_mesh_keypoints(
    setup: ModelSetup, source: ArraySource, joints: Any, verts: Any, rotmats: Any, like: Any, offset: Any = None
) -> Any:
    """(B, J', 3) the skeleton ``joints`` and the untranslated keypoints read from the mesh ``verts``, which is
    translated by (B, 3) ``offset`` (None: untranslated); the offset leaves each gathered vertex, so weights
    need not sum to one."""

    def gathered(ids: Any) -> Any:  # (B, n, 3) untranslated vertices ids
        return verts[:, ids] if offset is None else verts[:, ids] - offset[:, None]

    def landmarks(corners: Any, bary: Any) -> Any:  # (B, L, 3) untranslated: the offset times each weight sum
        points = barycentric_points(verts, corners, bary)
        return points if offset is None else points - bary.sum(-1)[..., None] * offset[:, None]

    parts = [joints]
    if setup.keypoints.extra.size:
        parts.append(gathered(source.constant("extra_ids", like)))
    if setup.spec.landmarks:
        parts.append(landmarks(source.constant("lmk_corners", like), source.constant("lmk_bary", like)))
        if setup.use_face_contour:
            rows_ = contour_rows(rotmats, setup.neck_chain)
            corners = source.constant("contour_corners", like)[rows_]
            parts.append(landmarks(corners, source.constant("contour_bary", like)[rows_]))
    if setup.regressor is not None:
        subset = gathered(source.constant("regressor_ids", like))
        parts.append(namespace(verts).einsum("kn,bnd->bkd", source.constant("regressor_weights", like), subset))
    return _joined(parts)


def _joined(parts: list[Any]) -> Any:
    """(B, J', 3) the skeleton joints and the keypoint groups after them."""
    return namespace(parts[0]).concat(parts, axis=1) if len(parts) > 1 else parts[0]


def _fast_forward(
    setup: ModelSetup,
    arrays: engine.BodyArrays,
    coeffs: Any,
    rotmats: Any,
    vertices: bool,
    transl: Any | None,
    how: Plan,
) -> tuple:
    """Vertices (translated) and output joints (untranslated) by the blocked or autograd kernels, as planned."""
    kernel = how.kernel
    verts, joints, transforms = engine.forward(
        coeffs,
        rotmats,
        arrays,
        vertices=vertices,
        translation=transl,
        kernel=kernel,
        skinning=setup.skinning,
        host_skeleton=how.host_skeleton,
    )
    parts = [joints]
    if setup.keypoints.ids.size:
        parts += _keypoints(setup, arrays, coeffs, rotmats, transforms, verts, transl, kernel)
    if setup.regressor is not None:
        parts.append(_regressed(setup, arrays, coeffs, rotmats, transforms, verts, transl, kernel))
    return verts, _joined(parts)


def _posed_subset(
    setup: ModelSetup,
    arrays: engine.BodyArrays,
    coeffs: Any,
    rotmats: Any,
    transforms: Any,
    verts: Any | None,
    transl: Any | None,
    kernel: str,
    ids: Any,
    key: str,
) -> Any:
    """(B, n, 3) untranslated posed vertices ``ids``: read from the mesh when there is one; posed alone for a
    joints-only call, or under autograd (where a gather from the mesh back-propagates a mesh-sized gradient)."""
    if verts is None or kernel == "autograd":
        return engine.posed_vertex_subset(coeffs, rotmats, transforms, arrays, ids, kernel, setup.skinning)
    subset = verts[:, setup.const(key, ids, verts)]
    return subset if transl is None else subset - transl[:, None]


def _keypoints(
    setup: ModelSetup,
    arrays: engine.BodyArrays,
    coeffs: Any,
    rotmats: Any,
    transforms: Any,
    verts: Any | None,
    transl: Any | None,
    kernel: str,
) -> list[Any]:
    """Extra vertex joints, static landmarks and the dynamic contour, in smplx's order (untranslated)."""
    kp, d, c = setup.keypoints, setup.data, setup.const
    verts = _posed_subset(setup, arrays, coeffs, rotmats, transforms, verts, transl, kernel, kp.ids, "kp_rows")
    out = []
    if kp.extra.size:
        out.append(verts[:, c("local_extra", kp.local_extra, verts)])
    if setup.spec.landmarks:
        corners = c("local_corners", kp.local_corners, verts)
        out.append(barycentric_points(verts, corners, c("lmk_bary", d.lmk_bary_coords, verts)))
        if setup.use_face_contour:
            rows_ = contour_rows(rotmats, setup.neck_chain)
            dyn_bary = c("dyn_bary", d.dynamic_lmk_bary_coords, verts)[rows_]
            contour = c("local_contour_corners", kp.local_contour_corners, verts)
            out.append(barycentric_points(verts, contour[rows_], dyn_bary))
    return out


def _regressed(
    setup: ModelSetup,
    arrays: engine.BodyArrays,
    coeffs: Any,
    rotmats: Any,
    transforms: Any,
    verts: Any | None,
    transl: Any | None,
    kernel: str,
) -> Any:
    """(B, K, 3) the ``joint_regressors`` points (untranslated), from just the vertices their rows use."""
    reg = setup.regressor
    subset = _posed_subset(
        setup, arrays, coeffs, rotmats, transforms, verts, transl, kernel, reg.vertex_ids, "regressor_ids"
    )
    return namespace(subset).einsum("kn,bnd->bkd", setup.const("regressor_weights", reg.weights, subset), subset)
