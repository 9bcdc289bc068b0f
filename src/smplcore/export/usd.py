"""Rigged, animated bodies as USD (``.usd``, ``.usda``, ``.usdc``) and USDZ, written with usd-core's UsdSkel.

The stage (Y up, ``metersPerUnit`` 1, time codes = frames at the sequence's frame rate) holds one
``SkelRoot`` ``/Body`` (the default prim) with

* ``Skeleton`` ``/Body/Skeleton``: one joint per model joint, named by its path in the kinematic tree
  (``pelvis``, ``pelvis/left_hip``, ...); ``bindTransforms`` are the shaped rest joints (world
  translations, identity rotation), ``restTransforms`` the same as parent-relative translations -- the
  rest pose of :mod:`smplcore.export.animation`;
* ``SkelAnimation`` ``/Body/Skeleton/Motion``: per frame and joint a rotation (quaternion), a translation
  (the rest offset; the root's is its rest position + ``transl``) and a unit scale;
* ``Mesh`` ``/Body/Mesh``: the shaped rest vertices, ``primvars:skel:jointIndices`` /
  ``jointWeights`` (every non-zero weight of the model by default, so USD's skinning is the model's LBS
  exactly; ``influences=k`` keeps the top k, renormalised), ``geomBindTransform`` identity, the UV map as
  the face-varying primvar ``st`` (indexed, so no seam split) when the model has one, and a
  ``UsdPreviewSurface`` material (with the texture when given);
* ``BlendShape`` prims under the mesh (with ``pointIndices`` when a shape moves under 3/4 of the vertices),
  weights animated in the ``SkelAnimation``: the expression (when it
  varies), DMPL soft tissue (when given), and with ``pose_correctives=True`` one per pose-corrective
  feature (``pose_k``: the entries of ``R_j - I``), which makes the USD body the model's full forward;
  ``shape_blend_shapes=True`` adds the shape components (``beta_k``, weight 0).

**Identity is baked, not blend-shaped.** The shape moves the joints, and a UsdSkel skeleton's bind and
rest transforms are constants that no blend shape can move, so a body shaped by blend shapes would be
skinned about the wrong joints. The points and the skeleton are the shaped body; the optional ``beta_k``
shapes are small edits on top of it (the skeleton does not follow them).

USDZ (``.usdz``) is the same stage written as ``.usdc`` with its texture and packaged by
``UsdUtils.CreateNewUsdzPackage``.
"""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from smplcore.errors import warn
from smplcore.export.animation import (
    Animation,
    ExportReport,
    Progress,
    pose_corrective_error,
    prepare_animation,
    top_k_weights,
    truncation_error,
)
from smplcore.uv import TextureInput, encode_png, resolve_texture

if TYPE_CHECKING:  # pragma: no cover
    from smplcore.model import Rig

__all__ = ["USD_SUFFIXES", "save_usd"]

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
_TEXTURE_NAME = "textures/body_albedo.png"


def _rig_of(model: Any) -> Rig:
    """The model's public facts (:class:`smplcore.model.Rig`): pose-corrective, expression, shape and DMPL
    bases, the UV map, the gender -- what the writer needs beyond the :class:`Animation`."""
    return model.rig


def _uv_of(rig: Rig) -> tuple[np.ndarray, np.ndarray] | None:
    return None if rig.uv is None else (np.asarray(rig.uv.vt), np.asarray(rig.uv.ft))


def joint_paths(joint_names: list[str], parents: np.ndarray) -> list[str]:
    """UsdSkel joint tokens: each joint's path from the root through the kinematic tree (``a/b/c``)."""
    from pxr import Tf

    names = [Tf.MakeValidIdentifier(n) for n in joint_names]
    paths: list[str] = []
    for j, name in enumerate(names):
        p = int(parents[j])
        if p >= j:
            raise ValueError(f"parents: joint {j} has parent {p}; expected parents listed before children")
        paths.append(name if p < 0 else f"{paths[p]}/{name}")
    return paths


def _translations(offsets: np.ndarray) -> np.ndarray:
    """(N, 3) translations -> (N, 4, 4) USD matrices (row vectors: the translation is the last row)."""
    m = np.tile(np.eye(4), (offsets.shape[0], 1, 1))
    m[:, 3, :3] = offsets
    return m


def _quaternions_xyzw(rotations: np.ndarray) -> np.ndarray:
    from smplcore.export.gltf import quaternions

    return quaternions(rotations)


def save_usd(
    path: str | Path,
    model: Any,
    source: Any,
    *,
    fps: float | None = None,
    pose_correctives: bool = False,
    shape_blend_shapes: bool = False,
    unit_weights: bool = False,
    influences: int | None = None,
    uv: bool | None = None,
    texture: TextureInput | None = None,
    name: str | None = None,
    progress: Progress | None = None,
) -> ExportReport:
    """Write ``source`` on ``model`` as a rigged, animated USD stage (``.usd``/``.usda``/``.usdc``) or USDZ.

    Parameters
    ----------
    path : the file to write; the suffix picks the encoding (``.usda`` text, ``.usd``/``.usdc`` binary,
        ``.usdz`` a package for viewers such as Apple's Quick Look).
    model : a :class:`smplcore.BodyModel`.
    source : a :class:`~smplcore.motion.Motion`, a motion, parameter or ``.smpl`` file, a dict of parameter
        arrays (one set or T frames), a :class:`~smplcore.fit.FitResult` (one frame per fitted body), or an
        :class:`~smplcore.export.animation.Animation` (see
        :func:`~smplcore.export.animation.prepare_animation`).
    fps : frame rate (default: the motion's, 30 for parameter sets); the stage's time codes per second.
    pose_correctives : write the model's pose-corrective blend shapes (9 per non-root joint) with their
        per-frame weights, so that USD reproduces the full model (a larger file: 207 shapes for SMPL).
        Without them the body is the model without pose correctives, and the report says by how much.
    shape_blend_shapes : add the shape components as blend shapes ``beta_k`` at weight 0 (edits on top
        of the baked shape; the skeleton does not follow them).
    unit_weights : write each animated blend shape as a pair, ``name_pos`` and ``name_neg`` (the offsets
        negated), both scaled so that their weights stay in [0, 1]: the same deformation for importers that
        clamp blend-shape weights to [0, 1] -- Blender's shape keys, whose sliders default to that range
        (without it, Blender drops the negative half of the pose correctives and expressions). Doubles the
        animated blend shapes.
    influences : joint weights kept per vertex (default: all non-zero weights of the model, exact).
    uv : write the model's UV map as ``primvars:st`` (default: whenever the model has one).
    texture : base-colour texture for the UV map: an image file, an (H, W, 3|4) uint8 array or
        ``"uv-grid"``; written as a PNG beside the stage (``textures/``) or inside the ``.usdz``.
    name : name of the ``SkelAnimation`` prim (default ``Motion``).
    progress : called with numbers of frames processed.

    Returns
    -------
    :class:`ExportReport` (``format`` ``"usd"`` or ``"usdz"``); ``pose_corrective_max`` is set when the
    model has pose correctives and they were not written.
    """
    from smplcore._deps import require

    require("pxr", "save_usd", "export")

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in USD_SUFFIXES:
        raise ValueError(f"path: expected a {', '.join(USD_SUFFIXES)} file, got {str(path)!r}")
    if influences is not None and influences < 1:
        raise ValueError(f"influences: expected a positive number of weights per vertex or None, got {influences!r}")
    anim = source if isinstance(source, Animation) else prepare_animation(model, source, fps=fps, progress=progress)
    if fps is not None and isinstance(source, Animation):
        anim = dataclasses.replace(anim, fps=float(fps))
    rig = _rig_of(model)
    uv_map = _uv_of(rig)
    if uv and uv_map is None:
        raise ValueError(f"uv: the {anim.model_type} model has no UV map (vt/ft)")
    if texture is not None and (uv_map is None or uv is False):
        raise ValueError("texture: a texture needs the model's UV map; the model has none or uv=False was given")
    has_correctives = bool(rig.posedirs.size) and bool(np.any(rig.posedirs))
    if pose_correctives and not has_correctives:
        raise ValueError(f"pose_correctives: the {anim.model_type} model has no pose-corrective blend shapes")
    image = resolve_texture(texture)
    notes = list(anim.notes)

    max_influences = int((anim.weights > 0).sum(axis=1).max())
    k = max_influences if influences is None else min(int(influences), max_influences)
    joints_idx, values, _ = top_k_weights(anim.weights, k)
    err = truncation_error(anim, joints_idx, values, progress=progress) if k < max_influences else None
    corrective = None
    if has_correctives and not pose_correctives:
        corrective = pose_corrective_error(model, anim)
        if corrective is not None:
            message = (
                f"the {anim.model_type} model has pose-corrective blend shapes, not written "
                f"(pose_correctives=False): the exported body differs from the model by up to "
                f"{corrective * 1000:.1f} mm (it matches the model evaluated without pose correctives)"
            )
            notes.append(message)
            warn(message)
    if anim.dmpls is not None:
        from smplcore.export.soft_tissue import dmpl_joint_shift

        shift = dmpl_joint_shift(model, anim.dmpls)
        if shift > 1e-6:
            notes.append(
                f"DMPL soft tissue moves the model's rest joints by up to {shift * 1000:.2f} mm; the skeleton "
                "uses the joints without soft tissue"
            )

    shapes = _blend_shapes(anim, rig, pose_correctives, shape_blend_shapes, progress)
    if unit_weights:
        shapes = _unit_weight_pairs(shapes)
    with tempfile.TemporaryDirectory(prefix="smplcore-usd-") as tmp:
        stage_path = Path(tmp) / (path.stem + ".usdc") if suffix == ".usdz" else path
        stage_path.parent.mkdir(parents=True, exist_ok=True)
        texture_file = None
        if image is not None:
            texture_file = stage_path.parent / _TEXTURE_NAME
            texture_file.parent.mkdir(parents=True, exist_ok=True)
            texture_file.write_bytes(encode_png(image))
        _write_stage(
            stage_path,
            anim,
            rig,
            joints_idx,
            values,
            shapes,
            uv=uv_map if uv is not False else None,
            texture=_TEXTURE_NAME if texture_file is not None else None,
            anim_name=name or "Motion",
            progress=progress,
        )
        if suffix == ".usdz":
            from pxr import Sdf, UsdUtils

            path.parent.mkdir(parents=True, exist_ok=True)
            if path.exists():
                path.unlink()
            if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(stage_path)), str(path)):
                raise OSError(f"path: usd-core could not package {str(path)!r}")

    return ExportReport(
        path=path,
        format="usdz" if suffix == ".usdz" else "usd",
        num_frames=anim.num_frames,
        fps=anim.fps,
        num_joints=anim.num_joints,
        num_vertices=int(anim.rest_vertices.shape[0]),
        file_size=path.stat().st_size,
        influences=k,
        max_model_influences=max_influences,
        top4_max_error=None if err is None else err["max"],
        top4_mean_error=None if err is None else err["mean"],
        top4_vertices_affected=None if err is None else int(err["affected"]),
        top4_max_dropped_weight=None if err is None else err["max_dropped"],
        pose_corrective_max=corrective,
        morph_targets=[s[0] for s in shapes],
        warnings=notes,
    )


_Shape = tuple[str, np.ndarray, np.ndarray | None]  # name, (V, 3) offsets, (T,) weights or None (rest at 0)


def _blend_shapes(
    anim: Animation, rig: Rig, pose_correctives: bool, shape: bool, progress: Progress | None
) -> list[_Shape]:
    """The blend shapes to write, with their per-frame weights."""
    from smplcore.engine import pose_features

    shapes: list[_Shape] = []
    if anim.expression_varies and anim.expression is not None and anim.base_expression is not None:
        weights = anim.expression - anim.base_expression
        shapes += [(f"expr_{i}", rig.exprdirs[:, :, i], weights[:, i]) for i in range(weights.shape[1])]
    if anim.dmpls is not None and rig.dmpldirs is not None:
        shapes += [(f"dmpl_{i}", rig.dmpldirs[:, :, i], anim.dmpls[:, i]) for i in range(anim.dmpls.shape[1])]
    if pose_correctives:
        features = np.empty((anim.num_frames, rig.posedirs.shape[0]))
        for start in range(0, anim.num_frames, 256):
            stop = min(start + 256, anim.num_frames)
            features[start:stop] = pose_features(anim.rotations[start:stop])
            if progress is not None:
                progress(stop - start)
        shapes += [(f"pose_{p}", rig.posedirs[p], features[:, p]) for p in range(features.shape[1])]
    if shape:
        shapes += [(f"beta_{i}", rig.shapedirs[:, :, i], None) for i in range(rig.shapedirs.shape[2])]
    return shapes


def _unit_weight_pairs(shapes: list[_Shape]) -> list[_Shape]:
    """Each animated shape (offsets o, weights w) as ``_pos`` (o s, max(w, 0) / s) and ``_neg`` (-o s, max(-w, 0) / s)
    with s = max |w| (at least 1): weights in [0, 1], the same sum."""
    out: list[_Shape] = []
    for name, offsets, weights in shapes:
        if weights is None:
            out.append((name, offsets, weights))
            continue
        scale = max(float(np.abs(weights).max(initial=0.0)), 1.0)
        out.append((f"{name}_pos", offsets * scale, np.maximum(weights, 0.0) / scale))
        out.append((f"{name}_neg", -offsets * scale, np.maximum(-weights, 0.0) / scale))
    return out


def _write_stage(
    path: Path,
    anim: Animation,
    rig: Rig,
    joints_idx: np.ndarray,
    values: np.ndarray,
    shapes: list[_Shape],
    *,
    uv: tuple[np.ndarray, np.ndarray] | None,
    texture: str | None,
    anim_name: str,
    progress: Progress | None,
) -> None:
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, UsdSkel, Vt

    if path.exists():
        path.unlink()
    stage = Usd.Stage.CreateNew(str(path))
    stage.GetRootLayer().documentation = f"smplcore {_version()}: a rigged {anim.model_type} body (UsdSkel)"
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    frames = anim.num_frames
    stage.SetTimeCodesPerSecond(anim.fps)
    stage.SetFramesPerSecond(anim.fps)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(max(frames - 1, 0))

    root = UsdSkel.Root.Define(stage, "/Body")
    stage.SetDefaultPrim(root.GetPrim())
    Usd.ModelAPI(root.GetPrim()).SetKind("component")
    root.GetPrim().SetCustomDataByKey("smplcore:model_type", anim.model_type)
    root.GetPrim().SetCustomDataByKey("smplcore:gender", rig.gender)
    root.GetPrim().SetCustomDataByKey("smplcore:betas", Vt.DoubleArray([float(b) for b in anim.betas]))
    root.GetPrim().SetCustomDataByKey("smplcore:joint_names", Vt.StringArray(list(anim.joint_names)))

    # Skeleton and its animation.
    tokens = Vt.TokenArray(joint_paths(list(anim.joint_names), anim.parents))
    skeleton = UsdSkel.Skeleton.Define(stage, "/Body/Skeleton")
    skeleton.CreateJointsAttr(tokens)
    skeleton.CreateJointNamesAttr(Vt.TokenArray([t.split("/")[-1] for t in tokens]))
    skeleton.CreateBindTransformsAttr(Vt.Matrix4dArray.FromNumpy(_translations(anim.rest_joints)))
    skeleton.CreateRestTransformsAttr(Vt.Matrix4dArray.FromNumpy(_translations(anim.offsets)))
    motion = UsdSkel.Animation.Define(stage, f"/Body/Skeleton/{anim_name}")
    motion.CreateJointsAttr(tokens)
    UsdSkel.BindingAPI.Apply(skeleton.GetPrim()).CreateAnimationSourceRel().SetTargets([motion.GetPath()])
    motion.CreateScalesAttr(Vt.Vec3hArray.FromNumpy(np.ones((anim.num_joints, 3), np.float16)))
    rotations = motion.CreateRotationsAttr()
    translations = motion.CreateTranslationsAttr()
    animated = [s for s in shapes if s[2] is not None]
    weights_attr = None
    if animated:
        motion.CreateBlendShapesAttr(Vt.TokenArray([s[0] for s in animated]))
        weights_attr = motion.CreateBlendShapeWeightsAttr()
        shape_weights = np.stack([s[2] for s in animated], axis=1).astype(np.float32)  # type: ignore[misc]
    offsets = anim.offsets.astype(np.float32)
    roots = anim.root_positions
    for start in range(0, frames, 256):
        stop = min(start + 256, frames)
        quats = _quaternions_xyzw(anim.rotations[start:stop]).astype(np.float32)
        for t in range(start, stop):
            time = Usd.TimeCode(t)
            rotations.Set(Vt.QuatfArray.FromNumpy(np.ascontiguousarray(quats[t - start])), time)
            local = offsets.copy()
            local[0] = roots[t]
            translations.Set(Vt.Vec3fArray.FromNumpy(local), time)
            if weights_attr is not None:
                weights_attr.Set(Vt.FloatArray.FromNumpy(shape_weights[t]), time)
        if progress is not None:
            progress(stop - start)

    # Mesh.
    mesh = UsdGeom.Mesh.Define(stage, "/Body/Mesh")
    points = anim.rest_vertices.astype(np.float32)
    faces = np.asarray(anim.faces, dtype=np.int32)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(faces.shape[0], 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.reshape(-1)))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    mesh.CreateDoubleSidedAttr(False)
    lo, hi = _animated_extent(anim)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
    k = joints_idx.shape[1]
    w32 = values.astype(np.float32)
    w32[:, 0] += (1.0 - w32.astype(np.float64).sum(axis=1)).astype(np.float32)  # rows sum to 1 in float32
    binding.CreateJointIndicesPrimvar(False, k).Set(Vt.IntArray.FromNumpy(joints_idx.astype(np.int32).reshape(-1)))
    binding.CreateJointWeightsPrimvar(False, k).Set(Vt.FloatArray.FromNumpy(w32.reshape(-1)))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    if shapes:
        names, targets = [], []
        for shape_name, offsets_v, _ in shapes:
            blend = UsdSkel.BlendShape.Define(stage, f"/Body/Mesh/{shape_name}")
            offsets32 = np.ascontiguousarray(offsets_v, dtype=np.float32)
            moved = np.flatnonzero(np.any(offsets32 != 0, axis=1))
            if len(moved) < 0.75 * len(offsets32):  # sparse (e.g. an expression moves the face only): exact
                blend.CreatePointIndicesAttr(Vt.IntArray.FromNumpy(moved.astype(np.int32)))
                offsets32 = np.ascontiguousarray(offsets32[moved])
            blend.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(offsets32))
            names.append(shape_name)
            targets.append(blend.GetPath())
        binding.CreateBlendShapesAttr(Vt.TokenArray(names))
        binding.CreateBlendShapeTargetsRel().SetTargets(targets)
    if uv is not None:
        vt, ft = uv
        st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
        )
        st.Set(Vt.Vec2fArray.FromNumpy(np.asarray(vt, dtype=np.float32)))
        st.SetIndices(Vt.IntArray.FromNumpy(np.asarray(ft, dtype=np.int32).reshape(-1)))

    # Material: UsdPreviewSurface, the texture through the st primvar.
    material = UsdShade.Material.Define(stage, "/Body/Materials/Body")
    surface = UsdShade.Shader.Define(stage, "/Body/Materials/Body/PreviewSurface")
    surface.CreateIdAttr("UsdPreviewSurface")
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.7)
    surface.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    diffuse = surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    if texture is not None:
        reader = UsdShade.Shader.Define(stage, "/Body/Materials/Body/StReader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
        image = UsdShade.Shader.Define(stage, "/Body/Materials/Body/Albedo")
        image.CreateIdAttr("UsdUVTexture")
        image.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{texture}"))
        image.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
        image.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
        image.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
        diffuse.ConnectToSource(image.ConnectableAPI(), "rgb")
    else:
        diffuse.Set(Gf.Vec3f(0.8, 0.72, 0.66))
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    stage.GetRootLayer().Save()


def _animated_extent(anim: Animation) -> tuple[np.ndarray, np.ndarray]:
    """A box holding the rest mesh at every frame: rest extent moved by each frame's root path (padded by
    the body's largest distance from its root joint, so any rotation of the body stays inside)."""
    radius = float(np.linalg.norm(anim.rest_vertices - anim.rest_joints[0], axis=1).max())
    roots = anim.root_positions
    return roots.min(axis=0) - radius, roots.max(axis=0) + radius


def _version() -> str:
    try:
        from smplcore import __version__

        return __version__
    except ImportError:  # pragma: no cover
        return "?"
