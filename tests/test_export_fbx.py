"""FBX 7.4 binary export, read back by real FBX readers (never our own): ufbx (PyPI, an independent C reader
that also evaluates skinning and blend shapes at a time) and Blender's own FBX importer (headless, when the
``blender`` program is installed). The skeleton, the weights, the blend shapes and the posed vertices at
several frames must equal the model's."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import smplcore
from export_helpers import make_motion, open_model, without_correctives
from smplcore.export import ExportReport, save_fbx, weight_colors
from smplcore.export.fbx.binary import FILE_ID, FOOTER_ID, FOOTER_MAGIC, HEADER_MAGIC, I64, Node, encode_file
from smplcore.export.uv import encode_png, uv_grid_texture

HERE = Path(__file__).resolve().parent
pytestmark = pytest.mark.filterwarnings("ignore:.*pose-corrective.*:UserWarning")
TOL = 1e-4  # metres, the bar; the files are in fact exact to ~1e-6 (float32 curves)


def read_with_ufbx(path: Path, frames: list[int]) -> dict:
    """What ufbx reads from ``path`` (see fbx_ufbx_check.py): ``info`` and arrays."""
    pytest.importorskip("ufbx", reason="ufbx (the independent FBX reader) is not installed")
    out = path.with_suffix(".ufbx.npz")
    result = subprocess.run(
        [sys.executable, str(HERE / "fbx_ufbx_check.py"), str(path), ",".join(map(str, frames)), str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    with np.load(out) as data:
        got = {k: data[k] for k in data.files}
    got["info"] = json.loads(str(got["info"]))
    return got


def forward(model, motion, frame, correctives=False):
    """The model's vertices and skeleton joints at ``frame`` (with or without pose correctives)."""
    use = model if correctives else without_correctives(model)
    params = motion.model_params(model.model_type, model.skeleton_joint_names)
    one = {k: v[frame : frame + 1] if k != "betas" else v for k, v in params.items()}
    out = use(**one)
    return np.asarray(out.vertices[0], np.float64), np.asarray(out.joints[0, : len(model.skeleton_joint_names)])


def check_frames(got, model, motion, frames, correctives=False, vertex_tol=TOL, joint_tol=TOL):
    worst = 0.0
    names = list(model.skeleton_joint_names)
    order = [got["info"]["bones"].index(n) for n in names]
    for k in frames:
        verts, joints = forward(model, motion, k, correctives)
        err = float(np.abs(got[f"vertices_{k}"] - verts).max())
        assert err <= vertex_tol, f"frame {k}: ufbx's skinned vertices off by {err * 1000:.4f} mm"
        np.testing.assert_allclose(got[f"joints_{k}"][order], joints, atol=joint_tol, rtol=0, err_msg=f"frame {k}")
        worst = max(worst, err)
    return worst


@pytest.fixture(scope="module")
def smpl(fake_models):
    return smplcore.BodyModel(fake_models["smpl_neutral_pkl"])


@pytest.fixture(scope="module")
def smpl_fbx(tmp_path_factory, smpl):
    motion = make_motion("smpl", seconds=1.0, fps=30.0, seed=4)
    path = tmp_path_factory.mktemp("fbx") / "smpl.fbx"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = save_fbx(path, smpl, motion, shape_keys=True)
    frames = [0, 1, 13, motion.num_frames - 1]
    return path, motion, report, [str(w.message) for w in caught], read_with_ufbx(path, frames), frames


def test_container_header_and_footer(tmp_path):
    data = encode_file([Node("Creator", ["x"]), Node("Objects", [], [Node("Empty")])])
    assert data.startswith(HEADER_MAGIC) and data[23:27] == (7400).to_bytes(4, "little")
    assert data.endswith(FOOTER_MAGIC) and len(data) % 16 == 0
    assert int.from_bytes(data[-144:-140], "little") == 0 and int.from_bytes(data[-140:-136], "little") == 7400
    # the first record ends where the second begins; the second's end is followed by the null record, the footer id
    first_end = int.from_bytes(data[27:31], "little")
    assert data[first_end + 13 : first_end + 13 + 7] == b"Objects"
    second_end = int.from_bytes(data[first_end : first_end + 4], "little")
    assert data[second_end : second_end + 13] == b"\x00" * 13 and data[second_end + 13 : second_end + 29] == FOOTER_ID
    with pytest.raises(TypeError, match="no FBX property type"):
        encode_file([Node("Bad", [object()])])
    with pytest.raises(TypeError, match="FBX arrays"):
        encode_file([Node("Bad", [np.zeros(3, np.complex64)])])
    assert b"L" + (2**40).to_bytes(8, "little") in encode_file([Node("Id", [I64(2**40)])])


def test_ufbx_reads_the_settings_skeleton_and_skin(smpl_fbx, smpl):
    path, motion, report, _, got, _ = smpl_fbx
    info = got["info"]
    assert info["version"] == 7400 and info["warnings"] == []
    assert info["unit_meters"] == pytest.approx(0.01) and info["fps"] == pytest.approx(30.0)
    assert info["up"] == 2  # ufbx's CoordinateAxis: 2 = +Y
    names = list(smpl.skeleton_joint_names)
    assert sorted(info["bones"]) == sorted(names) and sorted(info["clusters"]) == sorted(names)
    order = [info["clusters"].index(n) for n in names]  # ufbx lists them by depth in the tree
    parents = [None if p < 0 else names[p] for p in smpl.parents]
    assert [info["parents"][n] for n in names] == parents
    rest_verts, rest_joints = smpl.rest_pose(motion.betas[: smpl.num_betas])
    np.testing.assert_allclose(got["rest_vertices"], rest_verts, atol=1e-6)
    np.testing.assert_allclose(got["bind_positions"][order], rest_joints, atol=1e-6)
    np.testing.assert_array_equal(got["vertex_indices"].reshape(-1, 3), smpl.faces)
    np.testing.assert_allclose(got["weights"][:, order], smpl.skinning_weights, atol=1e-12)  # every weight, unrounded
    assert info["stack"] == "motion" and info["time_end"] == pytest.approx((motion.num_frames - 1) / 30)
    assert isinstance(report, ExportReport) and report.format == "fbx" and report.file_size == path.stat().st_size
    assert FILE_ID in path.read_bytes() and b"1970-01-01 10:00:00:000" in path.read_bytes()  # the known-working trio


def test_ufbx_evaluates_the_model_at_several_frames(smpl_fbx, smpl):
    _, motion, report, caught, got, frames = smpl_fbx
    worst = check_frames(got, smpl, motion, frames)
    assert worst < 1e-5
    # not exported unless asked: measured, reported and warned
    assert report.pose_corrective_max is not None and report.pose_corrective_max > 0
    assert any("pose-corrective" in w for w in report.warnings) and any("pose-corrective" in w for w in caught)


def test_shape_keys_hold_the_shape_basis(smpl_fbx, smpl):
    _, _, report, _, got, frames = smpl_fbx
    assert got["info"]["blend_channels"] == [f"beta_{k}" for k in range(10)] == report.morph_targets
    np.testing.assert_allclose(got["shape_offsets"], smpl.setup.shapedirs.transpose(2, 0, 1), atol=1e-9)
    for k in frames:
        np.testing.assert_array_equal(got[f"blend_weights_{k}"], 0.0)  # the shape is baked into the mesh


def test_pose_correctives_as_keyed_blend_shapes_reproduce_the_full_model(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.5, fps=30.0, seed=5)
    report = save_fbx(tmp_path / "pc.fbx", smpl, motion, pose_correctives=True, unit="m", up_axis="z")
    assert report.pose_corrective_max is None and not report.warnings
    assert len(report.morph_targets) == 9 * 23 and report.morph_targets[0] == "pose_left_hip_00"
    frames = [0, 7, motion.num_frames - 1]
    got = read_with_ufbx(tmp_path / "pc.fbx", frames)
    assert got["info"]["unit_meters"] == pytest.approx(1.0) and got["info"]["up"] == 4  # 4 = +Z
    worst = check_frames(got, smpl, motion, frames, correctives=True)
    assert worst < 1e-5


@pytest.mark.parametrize("unit,up,order", [("cm", "z", "ZXY"), ("m", "y", "YZX"), ("m", "z", "XYZ")])
def test_units_axes_and_rotation_orders(tmp_path, smpl, unit, up, order):
    motion = make_motion("smpl", seconds=0.4, fps=25.0, seed=6)
    save_fbx(tmp_path / "u.fbx", smpl, motion, unit=unit, up_axis=up, rotation_order=order)
    got = read_with_ufbx(tmp_path / "u.fbx", [0, 9])
    assert got["info"]["unit_meters"] == pytest.approx(0.01 if unit == "cm" else 1.0)
    assert got["info"]["rotation_orders"] == [["XYZ", "XZY", "YZX", "YXZ", "ZXY", "ZYX"].index(order)]
    check_frames(got, smpl, motion, [0, 9])


def test_root_bone(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.3, fps=30.0, seed=7)
    report = save_fbx(tmp_path / "r.fbx", smpl, motion, root_bone="root", up_axis="z")
    assert report.num_joints == 25
    got = read_with_ufbx(tmp_path / "r.fbx", [0, 8])
    assert got["info"]["parents"]["pelvis"] == "root" and got["info"]["parents"]["root"] is None
    root = got["info"]["bones"].index("root")
    np.testing.assert_allclose(got["joints_8"][root], 0.0, atol=1e-12)  # the root stays at the origin
    check_frames(got, smpl, motion, [0, 8])


def test_open_model_with_uvs(tmp_path):
    model = open_model()
    motion = make_motion("smpl", seconds=0.5, fps=30.0, seed=1)
    colors = weight_colors(model.skinning_weights)
    report = save_fbx(tmp_path / "open.fbx", model, motion, vertex_colors=colors, texture="uv-grid")
    assert report.pose_corrective_max is None and not report.warnings and report.num_vertices == 13380
    got = read_with_ufbx(tmp_path / "open.fbx", [0, 14])
    check_frames(got, model, motion, [0, 14])
    vt, ft = model.setup.data.vt, model.setup.data.ft
    assert got["info"]["uv_sets"] == ["UVMap"]
    # ufbx's UV of every face corner is the model's: no seam splitting needed in FBX
    corners = np.asarray(vt)[np.asarray(ft).reshape(-1)]
    np.testing.assert_allclose(got["uv_values"][got["uv_indices"]], corners, atol=1e-9)
    assert got["info"]["color_sets"] == ["Col"]
    # the embedded texture is the material's diffuse colour, read through the UV map
    assert got["info"]["textures"] == ["base_color"] and got["info"]["diffuse_texture"] == "base_color"
    assert got["info"]["texture_uv_set"] == "UVMap"
    assert got["texture_content"].tobytes() == encode_png(uv_grid_texture())
    rgba = np.c_[colors, np.full(len(colors), 255)][np.asarray(model.faces).reshape(-1)] / 255.0
    np.testing.assert_allclose(got["color_corners"], rgba, atol=1e-9)
    with pytest.raises(ValueError, match="no pose-corrective"):
        save_fbx(tmp_path / "x.fbx", model, motion, pose_correctives=True)
    with pytest.raises(ValueError, match="texture"):
        save_fbx(tmp_path / "x.fbx", model, motion, texture="uv-grid", uv=False)


def test_smplx_hands_expressions_and_correctives(tmp_path, fake_models):
    model = smplcore.BodyModel(
        fake_models["smplx_neutral_npz"], use_pca=False, flat_hand_mean=True, num_expression_coeffs=10
    )
    motion = make_motion("smplx", seconds=0.5, fps=30.0, expression=10, seed=2)
    with pytest.warns(UserWarning, match="needs blend shapes"):
        save_fbx(tmp_path / "plain.fbx", model, motion, pose_correctives=True)
    report = save_fbx(tmp_path / "x.fbx", model, motion, shape_keys=True, pose_correctives=True)
    names = report.morph_targets
    assert names[:20] == [f"beta_{k}" for k in range(10)] + [f"expr_{k}" for k in range(10)]
    assert len(names) == 20 + 9 * (len(model.skeleton_joint_names) - 1)
    frames = [0, 6, motion.num_frames - 1]
    got = read_with_ufbx(tmp_path / "x.fbx", frames)
    expr = motion.expression
    for k in frames:  # the expression channels are keyed with the motion's coefficients
        np.testing.assert_allclose(got[f"blend_weights_{k}"][10:20], expr[k], atol=1e-5)
    # the skeleton is the neutral expression's (a rig's joints are fixed): that shift is allowed
    shift = max(
        (float(n.split("up to ")[1].split(" mm")[0]) / 1000 for n in report.warnings if "rest joints" in n),
        default=0.0,
    )
    check_frames(got, model, motion, frames, correctives=True, vertex_tol=shift + TOL, joint_tol=shift + TOL)


def test_rejects_bad_options(tmp_path, smpl):
    params = {"body_pose": np.zeros(69)}
    for kwargs, match in [
        ({"unit": "inch"}, "unit"),
        ({"up_axis": "x"}, "up_axis"),
        ({"rotation_order": "XXY"}, "rotation_order"),
        ({"root_bone": "pelvis"}, "root_bone"),
    ]:
        with pytest.raises(ValueError, match=match):
            save_fbx(tmp_path / "bad.fbx", smpl, params, **kwargs)
    with pytest.raises(ValueError, match=r"\.fbx"):
        save_fbx(tmp_path / "bad.glb", smpl, params)


def _blender(path: Path, frames: list[int], *options: str) -> dict:
    exe = shutil.which("blender")
    if exe is None:
        pytest.skip("Blender is not installed (apt-get install blender)")
    command = [exe, "-b", "--factory-startup", "--python-exit-code", "1", "-P", str(HERE / "fbx_blender_check.py")]
    command += ["--", str(path), ",".join(map(str, frames)), *options]
    result = subprocess.run(command, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0 and "\nJSON:" in result.stdout, (result.stdout[-2000:], result.stderr[-2000:])
    return json.loads(result.stdout.split("\nJSON:", 1)[1])


@pytest.mark.slow
@pytest.mark.parametrize("unit,up", [("cm", "y"), ("m", "z")])
def test_blender_imports_the_fbx(tmp_path, smpl, unit, up):
    """Blender's own FBX importer: armature, weights as vertex groups, shape keys, and the posed mesh."""
    motion = make_motion("smpl", seconds=1.0, fps=30.0, seed=8)
    save_fbx(tmp_path / "b.fbx", smpl, motion, unit=unit, up_axis=up, shape_keys=True, root_bone="root")
    frames = [0, 11, motion.num_frames - 1]
    data = _blender(tmp_path / "b.fbx", frames)
    names = list(smpl.skeleton_joint_names)
    assert data["fps"] == pytest.approx(30.0)
    assert sorted(data["bones"]) == sorted(["root"] + names) and data["parents"]["pelvis"] == "root"
    assert all(data["parents"][n] == (names[p] if p >= 0 else "root") for n, p in zip(names, smpl.parents))
    assert data["shape_keys"] == ["Basis"] + [f"beta_{k}" for k in range(10)]
    assert data["vertex_groups"] == len(names)
    for k in frames:
        verts, joints = forward(smpl, motion, k)
        np.testing.assert_allclose(data["vertices"][str(k)], verts, atol=TOL, rtol=0, err_msg=f"frame {k}")
        heads = np.array([data["heads"][str(k)][n] for n in names])
        np.testing.assert_allclose(heads, joints, atol=TOL, rtol=0, err_msg=f"frame {k}")


def test_command_line(tmp_path, capsys, smpl, fake_models):
    from smplcore.cli import main
    from smplcore.motion import save_motion

    motion = make_motion("smpl", seconds=0.4, fps=30.0, seed=9)
    path = save_motion(motion, tmp_path / "walk.npz")
    model_path = str(fake_models["smpl_neutral_pkl"])
    args = ["export", str(path), "--model-path", model_path, "--num-betas", "10", "--no-progress"]
    fbx_options = ["--up-axis", "z", "--root-bone", "root", "--morph-targets", "--colors", "weights"]
    assert main(args + ["-o", str(tmp_path / "t.fbx"), "--texture", "uv-grid"]) == 2  # the fake SMPL has no UVs
    assert "texture" in capsys.readouterr().err
    assert main(args + ["-o", str(tmp_path / "w.fbx"), *fbx_options]) == 0
    printed = capsys.readouterr()
    assert "(fbx," in printed.out and "12 frame(s) at 30 fps, 25 joints" in printed.out
    assert "pose-corrective" in printed.out  # what the file does not hold is said
    got = read_with_ufbx(tmp_path / "w.fbx", [0, 5])
    assert got["info"]["up"] == 4 and got["info"]["parents"]["pelvis"] == "root"
    assert got["info"]["blend_channels"] == [f"beta_{k}" for k in range(10)]
    assert got["info"]["color_sets"] == ["Col"]
    check_frames(got, smpl, motion, [0, 5])
    # --format picks the writer (a suffix-less OUT gets it); --pose-correctives gives the exact body
    assert main(args + ["-o", str(tmp_path / "exact"), "--format", "fbx", "--pose-correctives", "--fbx-unit", "m"]) == 0
    got = read_with_ufbx(tmp_path / "exact.fbx", [0, 5])
    assert got["info"]["unit_meters"] == pytest.approx(1.0)
    check_frames(got, smpl, motion, [0, 5], correctives=True)
    assert main(args + ["-o", str(tmp_path / "w.glb"), "--format", "fbx"]) == 2
    assert "--format fbx" in capsys.readouterr().err


def test_a_z_up_motion_stands_up_and_keeps_an_upright_bind_pose(tmp_path, smpl):
    motion = make_motion("smpl", seconds=0.3, fps=30.0, seed=10)
    save_fbx(tmp_path / "amass.fbx", smpl, motion, input_up_axis="z")
    got = read_with_ufbx(tmp_path / "amass.fbx", [0, 8])
    rest_verts, _ = smpl.rest_pose(motion.betas[: smpl.num_betas])
    np.testing.assert_allclose(got["rest_vertices"], rest_verts, atol=1e-6)  # upright in SMPL's frame
    turn = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # the input's +Z -> +Y
    for k in (0, 8):
        verts, joints = forward(smpl, motion, k)
        np.testing.assert_allclose(got[f"vertices_{k}"], verts @ turn.T, atol=TOL, rtol=0)
    with pytest.raises(ValueError, match="input_up_axis"):
        save_fbx(tmp_path / "bad.fbx", smpl, motion, input_up_axis="x")


def test_dmpl_soft_tissue_is_keyed(tmp_path, fake_models):
    from fakes_dmpl import dmpl_sequence, write_dmpl

    model = smplcore.BodyModel(fake_models["smpl_neutral_pkl"], dmpl_path=write_dmpl(tmp_path))
    frames = 6
    rng = np.random.default_rng(11)
    params = {"body_pose": rng.normal(0, 0.2, (frames, 69)), "dmpls": dmpl_sequence(frames)}
    report = save_fbx(tmp_path / "d.fbx", model, params, pose_correctives=True)
    assert report.morph_targets[:8] == [f"dmpl_{k}" for k in range(8)]
    got = read_with_ufbx(tmp_path / "d.fbx", [0, 5])
    shift = max(
        (float(n.split("up to ")[1].split(" mm")[0]) / 1000 for n in report.warnings if "dmpls move" in n),
        default=0.0,
    )
    for k in (0, 5):
        np.testing.assert_allclose(got[f"blend_weights_{k}"][:8], params["dmpls"][k], atol=1e-5)
        out = model(**{key: value[k : k + 1] for key, value in params.items()})
        err = float(np.abs(got[f"vertices_{k}"] - np.asarray(out.vertices[0])).max())
        assert err <= shift + TOL, f"frame {k}: {err * 1000:.4f} mm"


@pytest.mark.slow
def test_blender_plays_keyed_pose_correctives(tmp_path, smpl):
    """With the shape keys' slider range widened (Blender clamps values to 0..1 by default), Blender's import
    of a pose_correctives=True file reproduces the full model, correctives included."""
    motion = make_motion("smpl", seconds=0.5, fps=30.0, seed=12)
    save_fbx(tmp_path / "pc.fbx", smpl, motion, pose_correctives=True)
    frames = [0, motion.num_frames - 1]
    data = _blender(tmp_path / "pc.fbx", frames, "--wide-sliders")
    assert len(data["shape_keys"]) == 1 + 9 * 23
    for k in frames:
        verts, _ = forward(smpl, motion, k, correctives=True)
        np.testing.assert_allclose(data["vertices"][str(k)], verts, atol=TOL, rtol=0, err_msg=f"frame {k}")


def test_dual_quaternion_skinning_is_declared_and_evaluated_by_ufbx(tmp_path):
    model = open_model(skinning="dqs")
    motion = make_motion("smpl", seconds=0.4, fps=30.0, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the SMPL betas drive the open model's shape space
        save_fbx(tmp_path / "dq.fbx", model, motion)
    got = read_with_ufbx(tmp_path / "dq.fbx", [0, 10])
    assert got["info"]["skinning_method"] == 2  # ufbx's SkinningMethod.DUAL_QUATERNION
    lbs = open_model()
    params = motion.model_params(model.model_type, model.skeleton_joint_names)
    for k in (0, 10):
        one = {key: v[k : k + 1] if key != "betas" else v for key, v in params.items()}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            dqs, plain = model(**one).vertices[0], lbs(**one).vertices[0]
        np.testing.assert_allclose(got[f"vertices_{k}"], dqs, atol=TOL, rtol=0)
        assert k == 0 or np.abs(got[f"vertices_{k}"] - plain).max() > 10 * TOL  # and it is not LBS


def test_single_parameter_set(tmp_path, smpl):
    rng = np.random.default_rng(13)
    params = {"betas": rng.normal(size=10), "body_pose": rng.normal(0, 0.3, 69), "transl": [0.1, 0.2, 0.3]}
    report = save_fbx(tmp_path / "one.fbx", smpl, params, name="pose")
    assert report.num_frames == 1
    got = read_with_ufbx(tmp_path / "one.fbx", [0])
    assert got["info"]["stack"] == "pose" and got["info"]["time_end"] == 0.0
    out = without_correctives(smpl)(**{k: np.asarray(v)[None] for k, v in params.items()})
    np.testing.assert_allclose(got["vertices_0"], out.vertices[0], atol=TOL, rtol=0)


def test_assimp_reads_every_object_without_errors(tmp_path, smpl, fake_models):
    """A third reader, Assimp (Debian's assimp-utils): its log has no error or warning, and it finds the skinned
    mesh, the bones and the animation with a channel per joint."""
    exe = shutil.which("assimp")
    if exe is None:
        pytest.skip("Assimp's command line tool is not installed (apt-get install assimp-utils)")
    model = smplcore.BodyModel(
        fake_models["smplx_neutral_npz"], use_pca=False, flat_hand_mean=True, num_expression_coeffs=10
    )
    motion = make_motion("smplx", seconds=0.3, fps=30.0, expression=10, seed=14)
    options = {"shape_keys": True, "pose_correctives": True, "root_bone": "root", "up_axis": "z"}
    save_fbx(tmp_path / "x.fbx", model, motion, vertex_colors=weight_colors(model.skinning_weights), **options)
    dump = subprocess.run([exe, "dump", "x.fbx", "-l"], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    log = [line for line in dump.stdout.splitlines() if line.startswith(("Error", "Warn"))]
    assert dump.returncode == 0 and log == [], log[:5]
    info = subprocess.run([exe, "info", "x.fbx"], capture_output=True, text=True, cwd=tmp_path, timeout=600).stdout
    joints = len(model.skeleton_joint_names)
    for expected in ("Meshes:             1", "Animations:         1", f"Bones:              {joints}"):
        assert expected in info, info[:2000]
    assert f"Animation Channels: {joints}" in info


@pytest.mark.slow
def test_blender_imports_uvs_and_the_embedded_texture(tmp_path):
    model = open_model()
    rng = np.random.default_rng(15)
    params = {"body_pose": rng.normal(0, 0.2, (4, 69)), "transl": rng.normal(0, 0.1, (4, 3))}
    save_fbx(tmp_path / "t.fbx", model, params, texture="uv-grid", up_axis="z")
    data = _blender(tmp_path / "t.fbx", [0, 3])
    assert data["uv_layers"] == ["UVMap"] and data["images"] == [["base_color", [1024, 1024]]]
    for k in (0, 3):
        out = model(**{key: value[k : k + 1] for key, value in params.items()})
        np.testing.assert_allclose(data["vertices"][str(k)], out.vertices[0], atol=TOL, rtol=0)
