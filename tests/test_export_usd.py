"""USD / USDZ export: usd-core's validators (what ``usdchecker`` runs) report nothing, and USD's own skeleton
API -- ``UsdSkel.Cache`` + ``SkinningQuery.ComputeSkinnedPoints``, or ``UsdSkel.BakeSkinning`` when blend shapes
are involved -- poses the written body like the model's forward (within 1e-4 m) at several frames."""

from __future__ import annotations

import json
import os
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pxr", reason="the export extra (usd-core) is not installed")

import smplcore
from export_helpers import make_motion, open_model, without_correctives
from smplcore.export import save_usd

pytestmark = pytest.mark.filterwarnings("ignore:.*pose-corrective.*:UserWarning")


# ------------------------------------------------------------------------------------------- USD readers


def validation_errors(path: Path) -> list[str]:
    """Every registered usd-core validator (``usdchecker``'s rules: stage metadata, UsdSkel binding,
    UsdShade, USDZ packaging, ...) run on the stage; their messages (empty: clean)."""
    from pxr import Usd, UsdValidation

    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    assert len(validators) > 10
    errors = UsdValidation.ValidationContext(validators).Validate(Usd.Stage.Open(str(path)))
    return [f"{e.GetName()}: {e.GetMessage()}" for e in errors]


def skinned_points(path: Path, frames: list[int]) -> dict[int, np.ndarray]:
    """USD's skinning of the mesh (no blend shapes): UsdSkel.Cache, the skeleton's skinning transforms and
    the mesh's SkinningQuery."""
    from pxr import Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(path))
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetDefaultPrim()), Usd.PrimDefaultPredicate)
    skel = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath("/Body/Skeleton")))
    query = cache.GetSkinningQuery(stage.GetPrimAtPath("/Body/Mesh"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Body/Mesh"))
    out = {}
    for k in frames:
        points = mesh.GetPointsAttr().Get(k)
        assert query.ComputeSkinnedPoints(skel.ComputeSkinningTransforms(Usd.TimeCode(k)), points, Usd.TimeCode(k))
        out[k] = np.array(points, dtype=np.float64)
    return out


def baked_points(path: Path, frames: list[int]) -> dict[int, np.ndarray]:
    """USD's full deformation (blend shapes, then skinning): ``UsdSkel.BakeSkinning`` in memory."""
    from pxr import Gf, Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(path))
    layer = stage.GetRootLayer()
    try:
        stage.SetEditTarget(layer)  # the root layer's time codes per second (a session layer's differ)
        assert UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(min(frames), max(frames)))
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Body/Mesh"))
        return {k: np.array(mesh.GetPointsAttr().Get(k), dtype=np.float64) for k in frames}
    finally:
        layer.Reload(force=True)  # drop the in-memory bake (never saved)


def forward(model, motion, frame: int) -> np.ndarray:
    params = motion.model_params(model.model_type, model.skeleton_joint_names)
    one = {k: v[frame : frame + 1] if k != "betas" else v for k, v in params.items()}
    return np.asarray(model(**one).vertices[0], dtype=np.float64)


def worst(points: dict[int, np.ndarray], model, motion) -> float:
    return max(float(np.linalg.norm(points[k] - forward(model, motion, k), axis=1).max()) for k in points)


# ----------------------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def smpl(fake_models):
    return smplcore.BodyModel(fake_models["smpl_neutral_pkl"])


@pytest.fixture(scope="module")
def smplx_model(fake_models):
    return smplcore.BodyModel(
        fake_models["smplx_neutral_npz"], use_pca=False, flat_hand_mean=True, num_expression_coeffs=10
    )


# ------------------------------------------------------------------------------------------------- tests


def test_open_model_usd_is_clean_and_usd_skinning_equals_the_forward(tmp_path):
    model = open_model()
    motion = open_motion(seconds=1.0, seed=3)
    path = tmp_path / "open.usda"
    report = save_usd(path, model, motion, texture="uv-grid")
    assert report.format == "usd" and report.num_frames == 30 and report.pose_corrective_max is None
    assert validation_errors(path) == []
    frames = [0, 13, 29]
    err = worst(skinned_points(path, frames), model, motion)
    assert err < 1e-4, f"USD skinning differs from the model by {err * 1000:.4f} mm"
    assert (tmp_path / "textures" / "body_albedo.png").stat().st_size > 1000


def test_stage_layout_skeleton_time_and_uvs(tmp_path):
    from pxr import Usd, UsdGeom, UsdShade, UsdSkel

    model = open_model()
    motion = open_motion(seconds=0.5, fps=24.0, seed=4)
    path = tmp_path / "layout.usdc"
    save_usd(path, model, motion, texture="uv-grid")
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 24.0
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, motion.num_frames - 1)
    assert stage.GetDefaultPrim().GetPath() == "/Body" and stage.GetDefaultPrim().IsA(UsdSkel.Root)

    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/Body/Skeleton"))
    joints = list(skel.GetJointsAttr().Get())
    names, parents = model.skeleton_joint_names, model.parents
    assert len(joints) == len(names)
    for j, token in enumerate(joints):  # a joint's path is its parent's path / its name
        assert token.split("/")[-1] == names[j]
        if parents[j] >= 0:
            assert token == f"{joints[parents[j]]}/{names[j]}"
    rest_vertices, rest_joints = model.rest_pose()
    bind = np.array(skel.GetBindTransformsAttr().Get())
    np.testing.assert_allclose(bind[:, 3, :3], rest_joints, atol=1e-6)
    np.testing.assert_allclose(bind[:, :3, :3], np.broadcast_to(np.eye(3), bind[:, :3, :3].shape))
    rest = np.array(skel.GetRestTransformsAttr().Get())
    np.testing.assert_allclose(rest[1:, 3, :3], rest_joints[1:] - rest_joints[parents[1:]], atol=1e-6)

    anim = UsdSkel.Animation(stage.GetPrimAtPath("/Body/Skeleton/Motion"))
    assert list(anim.GetRotationsAttr().GetTimeSamples()) == list(range(motion.num_frames))
    translations = np.array(anim.GetTranslationsAttr().Get(5))
    np.testing.assert_allclose(translations[0], rest_joints[0] + motion.trans[5], atol=1e-6)

    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Body/Mesh"))
    np.testing.assert_allclose(np.array(mesh.GetPointsAttr().Get()), rest_vertices, atol=1e-6)
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying
    vt, ft = model.uv
    np.testing.assert_allclose(np.array(st.ComputeFlattened()), np.asarray(vt)[np.asarray(ft).reshape(-1)], atol=1e-6)
    material, _ = UsdShade.MaterialBindingAPI(mesh.GetPrim()).ComputeBoundMaterial()
    shader = UsdShade.Shader(stage.GetPrimAtPath(material.GetPath().AppendChild("Albedo")))
    assert shader.GetInput("file").Get().path == "./textures/body_albedo.png"


def test_smpl_usdz_with_pose_correctives_is_the_full_model(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.5, seed=5)
    path = tmp_path / "walk.usdz"
    report = save_usd(path, smpl, motion, pose_correctives=True)
    assert report.format == "usdz" and report.pose_corrective_max is None and report.warnings == []
    assert len(report.morph_targets) == 9 * 23
    assert validation_errors(path) == []
    with zipfile.ZipFile(path) as z:
        assert [n for n in z.namelist() if n.endswith(".usdc")] == ["walk.usdc"]
    err = worst(baked_points(path, [0, 7, 14]), smpl, motion)  # the full forward, correctives included
    assert err < 1e-4, f"USD (blend shapes + skinning) differs from the model by {err * 1000:.4f} mm"

    # unit_weights: every signed shape as a +/- pair with weights in [0, 1] (for Blender); the same body
    from pxr import Usd, UsdSkel

    path = tmp_path / "unit.usdc"
    report = save_usd(path, smpl, motion, pose_correctives=True, unit_weights=True)
    assert len(report.morph_targets) == 2 * 9 * 23 and report.morph_targets[:2] == ["pose_0_pos", "pose_0_neg"]
    stage = Usd.Stage.Open(str(path))
    weights = np.array(
        [
            UsdSkel.Animation(stage.GetPrimAtPath("/Body/Skeleton/Motion")).GetBlendShapeWeightsAttr().Get(k)
            for k in range(motion.num_frames)
        ]
    )
    assert weights.min() >= 0.0 and weights.max() <= 1.0
    assert worst(baked_points(path, [0, 7, 14]), smpl, motion) < 1e-4


def test_smpl_without_correctives_says_so_and_equals_the_plain_model(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.5, seed=6)
    path = tmp_path / "plain.usd"
    with pytest.warns(UserWarning, match="pose-corrective"):
        report = save_usd(path, smpl, motion)
    assert report.pose_corrective_max is not None and report.pose_corrective_max > 1e-3
    assert "pose_correctives=False" in report.warnings[0]
    assert report.morph_targets == []
    assert validation_errors(path) == []
    err = worst(skinned_points(path, [0, 8, 14]), without_correctives(smpl), motion)
    assert err < 1e-4


def test_smplx_constant_and_varying_expression(tmp_path, smplx_model):
    """A constant expression is baked into the points (exact); a varying one becomes animated blend shapes
    ``expr_k`` -- exact on the vertices up to what the expression does to the joints, which the report states."""
    motion = make_motion("smplx", seconds=0.4, seed=7, expression=10)
    still = dataclasses_replace(motion, expression=np.repeat(motion.expression[:1], motion.num_frames, axis=0))
    path = tmp_path / "still.usdz"
    report = save_usd(path, smplx_model, still, pose_correctives=True)
    assert not any(n.startswith("expr_") for n in report.morph_targets)
    assert validation_errors(path) == []
    assert worst(baked_points(path, [0, 5, 11]), smplx_model, still) < 1e-4

    path = tmp_path / "talk.usd"
    report = save_usd(path, smplx_model, motion, pose_correctives=True)
    assert [n for n in report.morph_targets if n.startswith("expr_")] == [f"expr_{i}" for i in range(10)]
    shift = [w for w in report.warnings if "expression moves" in w]
    assert validation_errors(path) == []
    from pxr import Usd, UsdSkel

    stage = Usd.Stage.Open(str(path))
    expr = UsdSkel.BlendShape(stage.GetPrimAtPath("/Body/Mesh/expr_0"))
    moved = np.flatnonzero(np.any(smplx_model.rig.exprdirs[:, :, 0] != 0, axis=1))
    np.testing.assert_array_equal(np.array(expr.GetPointIndicesAttr().Get()), moved)  # sparse: the face only
    assert len(moved) < smplx_model.rig.num_vertices / 4
    err = worst(baked_points(path, [0, 5, 11]), smplx_model, motion)
    # the skeleton is the neutral expression's: the error is bounded by the joint shift the report gives
    bound = float(shift[0].split("up to ")[1].split(" mm")[0]) / 1000 + 1e-4 if shift else 1e-4
    assert err < bound


def test_top_k_influences_are_measured(tmp_path, smplx_model):
    from pxr import Usd, UsdSkel

    motion = make_motion("smplx", seconds=0.2, seed=9)
    path = tmp_path / "k2.usdc"
    report = save_usd(path, smplx_model, motion, influences=2)
    assert report.influences == 2 and report.max_model_influences > 2
    assert report.top4_max_error is not None and report.top4_max_error > 0
    stage = Usd.Stage.Open(str(path))
    binding = UsdSkel.BindingAPI(stage.GetPrimAtPath("/Body/Mesh"))
    assert binding.GetJointIndicesPrimvar().GetElementSize() == 2
    err = worst(skinned_points(path, [0, 5]), without_correctives(smplx_model), motion)
    assert err <= report.top4_max_error + 1e-5  # USD shows exactly the error the report measured


def test_shape_blend_shapes_rest_at_zero(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.1, seed=10)
    path = tmp_path / "shape.usda"
    report = save_usd(path, smpl, motion, shape_blend_shapes=True)
    assert [n for n in report.morph_targets if n.startswith("beta_")] == [f"beta_{i}" for i in range(10)]
    assert validation_errors(path) == []
    assert worst(skinned_points(path, [0, 2]), without_correctives(smpl), motion) < 1e-4


def test_errors_name_the_argument(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.1)
    with pytest.raises(ValueError, match="path: expected a .usd"):
        save_usd(tmp_path / "x.fbx", smpl, motion)
    with pytest.raises(ValueError, match="influences"):
        save_usd(tmp_path / "x.usd", smpl, motion, influences=0)
    with pytest.raises(ValueError, match="texture: a texture needs the model's UV map"):
        save_usd(tmp_path / "x.usd", smpl, motion, texture="uv-grid")
    with pytest.raises(ValueError, match="pose_correctives: the open model has no pose-corrective"):
        save_usd(tmp_path / "x.usd", open_model(), open_motion(seconds=0.1), pose_correctives=True)


def dataclasses_replace(motion, **changes):
    import dataclasses

    return dataclasses.replace(motion, **changes)


def open_motion(**options):
    """A SMPL+H test motion for the open model, with zero betas (SMPL+H betas mean nothing to it)."""
    return dataclasses_replace(make_motion("smplh", **options), betas=np.zeros(10))


# ---------------------------------------------------------------------------------------------- Blender


BLENDER_SCRIPT = r"""
import json, os, sys
import bpy
path, frames = sys.argv[-2], [int(k) for k in sys.argv[-1].split(",")]
bpy.ops.wm.read_factory_settings(use_empty=True)
if not hasattr(bpy.ops.wm, "usd_import") or bpy.app.version < (3, 5, 0):
    sys.stdout.write("\nJSON:" + json.dumps({"skip": "Blender %s has no UsdSkel import" % bpy.app.version_string}))
    sys.stdout.flush()
    os._exit(0)
bpy.ops.wm.usd_import(filepath=path, import_skeletons=True, import_blendshapes=True, scale=1.0)
scene = bpy.context.scene
mesh_obj = next(o for o in scene.objects if o.type == "MESH")
out = {"version": bpy.app.version_string, "vertices": {}}
for k in frames:
    scene.frame_set(k)
    evaluated = mesh_obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    # Blender converts the Y-up stage to Z-up: (x, y, z) -> (x, -z, y); back to Y-up
    out["vertices"][str(k)] = [[p[0], p[2], -p[1]] for p in (mesh_obj.matrix_world @ v.co for v in mesh.vertices)]
    evaluated.to_mesh_clear()
sys.stdout.write("\nJSON:" + json.dumps(out) + "\n")
sys.stdout.flush()
os._exit(0)
"""


def _blender_command(script: Path) -> list[str]:
    """Blender's Python (SMPLCORE_TEST_BLENDER_PYTHON, a Python with ``pip install bpy``) or a ``blender``
    executable run headless."""
    import shutil

    python = os.environ.get("SMPLCORE_TEST_BLENDER_PYTHON")
    if python:
        return [python, str(script)]
    exe = shutil.which("blender")
    if exe:
        return [exe, "--background", "--factory-startup", "--python", str(script), "--"]
    pytest.skip("neither SMPLCORE_TEST_BLENDER_PYTHON nor a `blender` executable is available")


@pytest.mark.slow
def test_blender_imports_the_usd(tmp_path, smpl):
    """Blender's own USD importer (UsdSkel skeleton, skin, blend shapes as shape keys) poses the body like the
    model: the plain rig like the model without pose correctives, and a file with the pose correctives written
    with ``unit_weights`` (Blender clamps shape keys to [0, 1]) like the full model. Skips on a Blender without
    USD support (Debian's 3.4 is built without it) or without UsdSkel import (before 3.5)."""
    script = tmp_path / "blender_usd.py"
    script.write_text(BLENDER_SCRIPT)
    motion = make_motion("smpl", seconds=0.5, seed=11)
    frames = [0, 7, 14]
    plain = without_correctives(smpl)
    save_usd(tmp_path / "plain.usdc", smpl, motion)
    save_usd(tmp_path / "full.usdz", smpl, motion, pose_correctives=True, unit_weights=True)
    for name, reference in (("plain.usdc", plain), ("full.usdz", smpl)):
        result = subprocess.run(
            [*_blender_command(script), str(tmp_path / name), ",".join(map(str, frames))],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert result.returncode == 0, result.stderr[-2000:]
        data = json.loads(result.stdout.split("\nJSON:", 1)[1])
        if "skip" in data:
            pytest.skip(data["skip"])
        for k in frames:
            got = np.array(data["vertices"][str(k)])
            err = float(np.linalg.norm(got - forward(reference, motion, k), axis=1).max())
            assert err < 1e-4, f"Blender {data['version']}, {name}, frame {k}: {err * 1000:.4f} mm"


def test_dmpl_soft_tissue_is_animated_blend_shapes(tmp_path, fake_models):
    from fakes_dmpl import write_dmpl

    dmpl = write_dmpl(tmp_path)
    model = smplcore.BodyModel(fake_models["smplh_female_npz"], use_pca=False, flat_hand_mean=True, dmpl_path=dmpl)
    motion = make_motion("smplh", seconds=0.3, seed=14)
    poses, trans = np.array(motion.poses), np.array(motion.trans)
    poses[0], trans[0] = 0.0, 0.0  # frame 0 in the rest pose: skinning is the identity whatever the joints
    dmpls = np.random.default_rng(0).normal(0, 1, (motion.num_frames, 8))
    motion = dataclasses_replace(motion, poses=poses, trans=trans, dmpls=dmpls)
    path = tmp_path / "soft.usdc"
    report = save_usd(path, model, motion, pose_correctives=True)
    assert [n for n in report.morph_targets if n.startswith("dmpl_")] == [f"dmpl_{i}" for i in range(8)]
    assert validation_errors(path) == []
    params = motion.model_params("smplh", model.skeleton_joint_names)
    shift = [w for w in report.warnings if "DMPL soft tissue moves" in w]
    bound = float(shift[0].split("up to ")[1].split(" mm")[0]) / 1000 + 1e-4 if shift else 1e-4
    for k, got in baked_points(path, [0, 8]).items():
        one = {n: v[k : k + 1] if n != "betas" else v for n, v in params.items()}
        expected = model(**one, dmpls=motion.dmpls[k : k + 1]).vertices[0]
        # frame 0: the soft tissue exactly; posed frames: the skeleton is the one without soft tissue, so
        # within the joint shift the report states
        assert float(np.linalg.norm(got - expected, axis=1).max()) < (1e-5 if k == 0 else bound)


def test_progress_counts_every_frame_of_each_pass(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.5, seed=15)
    seen: list[int] = []
    save_usd(tmp_path / "p.usdc", smpl, motion, pose_correctives=True, progress=seen.append)
    # preparing, pose features, writing the animation: each pass reports all frames
    assert sum(seen) == 3 * motion.num_frames
