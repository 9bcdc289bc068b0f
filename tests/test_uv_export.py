"""UV maps and textures in the exports: OBJ (vt, f v/vt, .mtl + .png) and glTF (TEXCOORD_0 on a mesh split
along its seams, skin weights and morph targets carried, an embedded baseColor texture), checked with the
Khronos validator, three.js and an independent reader."""

from __future__ import annotations

import io
import warnings

import numpy as np
import pytest

pytest.importorskip("pygltflib", reason="the export extra (pygltflib) is not installed")
trimesh = pytest.importorskip("trimesh", reason="the export extra (trimesh) is not installed")
PIL = pytest.importorskip("PIL.Image", reason="Pillow is not installed")

import smplcore
from export_helpers import GlbReader, issues, make_motion, three_js, validate
from smplcore.export import save_glb, save_mesh
from smplcore.export.animation import top_k_weights
from smplcore.export.uv import load_texture, model_uv, split_seams, uv_grid_texture


@pytest.fixture(scope="module")
def smplx(fake_models):
    return smplcore.BodyModel(fake_models["smplx_neutral_npz"], use_pca=False, flat_hand_mean=True)


@pytest.fixture(scope="module")
def textured_glb(tmp_path_factory, smplx):
    path = tmp_path_factory.mktemp("uv") / "textured.glb"
    motion = make_motion("smplx", seconds=0.5, fps=30.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pose correctives are not exported (tested elsewhere)
        report = save_glb(path, smplx, motion, texture="uv-grid", morph_targets=True)
    return path, motion, report


def _corner_ids(reader):
    return reader.array(reader.gltf.meshes[0].primitives[0].indices).reshape(-1, 3)


def test_split_seams_gives_one_vertex_per_vertex_uv_pair(smplx):
    vt, ft = model_uv(smplx)
    split = split_seams(smplx.faces, vt, ft)
    pairs = {(v, t) for v, t in zip(np.ravel(smplx.faces), np.ravel(ft))}
    assert split.num_vertices == len(pairs) > smplx.setup.data.num_vertices
    np.testing.assert_array_equal(split.vertex_ids[split.faces], smplx.faces)
    np.testing.assert_array_equal(split.uv[split.faces], vt[ft])


def test_glb_texcoords_match_the_uv_map_corner_for_corner(textured_glb, smplx):
    path, _, report = textured_glb
    reader = GlbReader(path)
    prim = reader.gltf.meshes[0].primitives[0]
    corners = _corner_ids(reader)
    texcoord = reader.array(prim.attributes.TEXCOORD_0)
    vt, ft = model_uv(smplx)
    # glTF's UV origin is the top-left corner: v is flipped
    np.testing.assert_allclose(texcoord[corners], np.stack([vt[ft][..., 0], 1 - vt[ft][..., 1]], -1), atol=1e-6)
    # every written vertex copies one model vertex: same rest position (betas baked in), same skin weights
    ids = np.full(texcoord.shape[0], -1)
    ids[corners.ravel()] = np.ravel(smplx.faces)
    np.testing.assert_array_equal(ids[corners], smplx.faces)
    assert report.num_vertices == texcoord.shape[0] > smplx.setup.data.num_vertices
    joints, values, _ = top_k_weights(np.asarray(smplx.skinning_weights), 4)
    written_joints = reader.array(prim.attributes.JOINTS_0)
    written_weights = reader.array(prim.attributes.WEIGHTS_0)
    np.testing.assert_array_equal(written_joints, joints[ids])
    np.testing.assert_allclose(written_weights, values[ids], atol=1e-6)
    # morph targets are carried to the copies
    delta = reader.array(prim.targets[0]["POSITION"] if isinstance(prim.targets[0], dict) else prim.targets[0].POSITION)
    np.testing.assert_allclose(delta, smplx.setup.shapedirs[ids, :, 0], atol=1e-6)


def test_glb_embeds_the_texture_as_base_color(textured_glb):
    path, _, _ = textured_glb
    reader = GlbReader(path)
    material = reader.gltf.materials[0]
    assert material.pbrMetallicRoughness.baseColorTexture.index == 0
    image = reader.gltf.images[reader.gltf.textures[0].source]
    assert image.mimeType == "image/png"
    view = reader.gltf.bufferViews[image.bufferView]
    png = reader.blob[view.byteOffset : view.byteOffset + view.byteLength]
    decoded = np.asarray(PIL.open(io.BytesIO(png)).convert("RGB"))
    np.testing.assert_array_equal(decoded, uv_grid_texture())


def test_textured_glb_is_validator_clean(textured_glb):
    path, _, _ = textured_glb
    report = validate(path)
    assert report["issues"]["numErrors"] == 0, issues(report)
    assert report["issues"]["numWarnings"] == 0, issues(report, 1)
    info = report["info"]
    assert info["materialCount"] == 1 and info["hasTextures"] and info["hasSkins"] and info["hasMorphTargets"]


def test_three_js_reads_the_uvs_and_the_texture(textured_glb):
    path, motion, _ = textured_glb
    result = three_js(path, motion.fps, [0])
    reader = GlbReader(path)
    texcoord = reader.array(reader.gltf.meshes[0].primitives[0].attributes.TEXCOORD_0)
    np.testing.assert_allclose(np.asarray(result["uv"]), texcoord, atol=1e-6)
    assert result["map"]["png"] and (result["map"]["width"], result["map"]["height"]) == (1024, 1024)
    assert result["map"]["flipY"] is False  # glTF textures are not flipped: the top-left origin is honoured


def test_uv_false_and_models_without_uvs(tmp_path, smplx, fake_models):
    motion = make_motion("smplx", seconds=0.2, fps=30.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        report = save_glb(tmp_path / "plain.glb", smplx, motion, uv=False)
    assert report.num_vertices == smplx.setup.data.num_vertices
    assert GlbReader(tmp_path / "plain.glb").gltf.meshes[0].primitives[0].attributes.TEXCOORD_0 is None
    smpl = smplcore.BodyModel(fake_models["smpl_neutral_pkl"])
    with pytest.raises(ValueError, match="texture: a texture needs the model's UV map"):
        save_glb(tmp_path / "t.glb", smpl, make_motion("smpl", seconds=0.2), texture="uv-grid")


def test_obj_with_uv_mtl_and_texture(tmp_path, smplx):
    vt, ft = model_uv(smplx)
    verts = smplx(betas=np.zeros((1, 10))).vertices[0]
    path = save_mesh(tmp_path / "body.obj", verts, smplx.faces, uv=(vt, ft), texture="uv-grid")
    text = path.read_text()
    assert text.count("\nvt ") == vt.shape[0] and "mtllib body.mtl" in text and "usemtl body" in text
    first_face = next(line for line in text.splitlines() if line.startswith("f "))
    f0, t0 = smplx.faces[0] + 1, ft[0] + 1
    assert first_face == "f " + " ".join(f"{a}/{b}" for a, b in zip(f0, t0))
    assert "map_Kd body_texture.png" in (tmp_path / "body.mtl").read_text()
    np.testing.assert_array_equal(load_texture(tmp_path / "body_texture.png"), uv_grid_texture())
    # trimesh keeps the vertex order with maintain_order=True, and splits the seams by itself without it
    kept = trimesh.load(path, process=False, maintain_order=True)
    np.testing.assert_allclose(kept.vertices, verts, atol=1e-6)
    np.testing.assert_array_equal(kept.faces, smplx.faces)
    split = trimesh.load(path, process=False)
    assert split.vertices.shape[0] == split_seams(smplx.faces, vt, ft).num_vertices
    np.testing.assert_allclose(split.visual.uv[split.faces], vt[ft], atol=1e-6)
    assert split.visual.material.image.size == (1024, 1024)


def test_obj_uv_arguments_are_checked(tmp_path, smplx):
    vt, ft = model_uv(smplx)
    verts = smplx.setup.data.v_template
    with pytest.raises(ValueError, match="texture: a texture needs a UV map"):
        save_mesh(tmp_path / "a.obj", verts, smplx.faces, texture="uv-grid")
    with pytest.raises(ValueError, match="uv: UV maps are written to .obj files only"):
        save_mesh(tmp_path / "a.ply", verts, smplx.faces, uv=(vt, ft))
    with pytest.raises(ValueError, match=r"ft: expected shape \(F=20908, 3\)"):
        save_mesh(tmp_path / "a.obj", verts, smplx.faces, uv=(vt, ft[:-1]))
    with pytest.raises(FileNotFoundError, match="texture: no such image file"):
        save_mesh(tmp_path / "a.obj", verts, smplx.faces, uv=(vt, ft), texture=tmp_path / "missing.png")


def test_uv_grid_texture_layout():
    img = uv_grid_texture(256, cells=4)
    assert img.shape == (256, 256, 3) and img.dtype == np.uint8
    # hue changes along u (columns), brightness along v (rows; the top row is v = 1, the brightest)
    left, right = img[200, 20].astype(int), img[200, 236].astype(int)
    assert np.abs(left - right).sum() > 60
    top, bottom = img[20, 20].astype(float).mean(), img[236, 20].astype(float).mean()
    assert top > bottom


def test_uv_maps_live_below_export_render_and_view_under_both_names():
    """``smplcore.uv`` is the home (render and view use it without the exporters); the old name is the same module."""
    import smplcore.export.uv as old_name
    import smplcore.uv as home

    assert old_name is home and home.model_uv is model_uv
