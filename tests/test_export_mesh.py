"""OBJ / PLY export keeps vertex and face order and colours; weight_colors palette mixing."""

from __future__ import annotations

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh", reason="the export extra (trimesh) is not installed")

from smplcore.export import save_mesh, weight_colors


@pytest.fixture()
def mesh():
    """A closed mesh with shuffled vertex and face order, so any reordering would show."""
    rng = np.random.default_rng(7)
    sphere = trimesh.creation.icosphere(subdivisions=2)
    perm = rng.permutation(len(sphere.vertices))
    inverse = np.argsort(perm)
    verts = sphere.vertices[perm] * [0.3, 0.9, 0.2] + [0.0, 0.9, 0.0]
    faces = inverse[sphere.faces][rng.permutation(len(sphere.faces))]
    return verts, faces


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".OBJ", ".PLY"])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_round_trip_keeps_order(tmp_path, mesh, suffix, dtype):
    verts, faces = mesh
    verts = verts.astype(dtype)
    path = save_mesh(tmp_path / f"m{suffix}", verts, faces)
    assert path.exists()
    loaded = trimesh.load(path, process=False)
    assert loaded.vertices.shape == verts.shape
    np.testing.assert_allclose(loaded.vertices, verts, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(loaded.faces, faces)


@pytest.mark.parametrize("suffix", [".ply", ".obj"])
def test_colours_survive(tmp_path, mesh, suffix):
    verts, faces = mesh
    rng = np.random.default_rng(1)
    float_rgb = rng.random((len(verts), 3))
    uint8_rgba = rng.integers(0, 256, size=(len(verts), 4), dtype=np.uint8)
    for colours, expected_rgb in ((float_rgb, np.round(float_rgb * 255)), (uint8_rgba, uint8_rgba[:, :3])):
        path = save_mesh(tmp_path / f"c{suffix}", verts, faces, vertex_colors=colours)
        loaded = trimesh.load(path, process=False)
        got = loaded.visual.vertex_colors
        assert got.shape == (len(verts), 4)
        np.testing.assert_array_equal(got[:, :3].astype(int), expected_rgb.astype(int))
        np.testing.assert_array_equal(loaded.faces, faces)
    if suffix == ".ply":  # PLY keeps alpha too
        np.testing.assert_array_equal(got[:, 3], uint8_rgba[:, 3])


def test_weight_colours_save(tmp_path, mesh):
    verts, faces = mesh
    weights = np.random.default_rng(2).random((len(verts), 24))
    path = save_mesh(tmp_path / "w.ply", verts, faces, vertex_colors=weight_colors(weights))
    loaded = trimesh.load(path, process=False)
    np.testing.assert_array_equal(loaded.visual.vertex_colors[:, :3], weight_colors(weights))


def test_creates_parent_folders(tmp_path, mesh):
    verts, faces = mesh
    path = save_mesh(str(tmp_path / "a" / "b" / "m.obj"), verts, faces)
    assert path == tmp_path / "a" / "b" / "m.obj" and path.exists()


def test_unknown_suffix_raises(tmp_path, mesh):
    verts, faces = mesh
    with pytest.raises(ValueError, match=r"unsupported file suffix '\.stl'.*supported: \.obj, \.ply"):
        save_mesh(tmp_path / "m.stl", verts, faces)
    with pytest.raises(ValueError, match=r"unsupported file suffix ''"):
        save_mesh(tmp_path / "m", verts, faces)
    assert not (tmp_path / "m.stl").exists()


def test_batch_raises(tmp_path, mesh):
    verts, faces = mesh
    with pytest.raises(ValueError, match=r"vertices: .*got a batch \(2, \d+, 3\).*one mesh per file"):
        save_mesh(tmp_path / "m.obj", np.stack([verts, verts]), faces)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"vertices": np.zeros((5, 2))}, r"vertices: expected shape \(V, 3\), got \(5, 2\)"),
        ({"vertices": np.full((162, 3), np.inf)}, r"vertices: expected finite"),
        ({"faces": np.array([[0, 1, 999]])}, r"faces: indices must be in \[0, 161\].*\[0, 999\]"),
        ({"faces": np.zeros((4, 4), dtype=int)}, r"faces: expected shape \(F, 3\).*got \(4, 4\)"),
        ({"faces": np.array([[0.0, 1.0, 2.0]])}, r"faces: expected an integer array"),
        ({"vertex_colors": np.zeros((10, 3))}, r"vertex_colors: expected shape \(V=162, 3\).*got \(10, 3\)"),
        (
            {"vertex_colors": np.full((162, 3), 2.0)},
            r"vertex_colors: float colours must be finite and in \[0, 1\]",
        ),
        (
            {"vertex_colors": np.zeros((162, 3), dtype=np.int64)},
            r"vertex_colors: expected floats in \[0, 1\] or uint8",
        ),
    ],
)
def test_bad_inputs_name_the_argument(tmp_path, mesh, kwargs, pattern):
    verts, faces = mesh
    args = {"vertices": verts, "faces": faces}
    args.update(kwargs)
    with pytest.raises(ValueError, match=pattern):
        save_mesh(tmp_path / "m.ply", **args)


def test_weight_colors_palette_and_mixing():
    joints = 55
    one_hot = np.eye(joints)
    palette = weight_colors(one_hot)
    assert palette.shape == (joints, 3) and palette.dtype == np.uint8
    assert len(np.unique(palette, axis=0)) == joints  # a distinct colour per joint
    np.testing.assert_array_equal(weight_colors(one_hot), palette)  # fixed
    half = np.zeros((1, joints))
    half[0, [3, 10]] = 0.5
    mixed = weight_colors(half)[0].astype(int)
    assert np.all(np.abs(mixed - (palette[3].astype(int) + palette[10].astype(int)) / 2) <= 1)
    # rows are normalised; an all-zero row is grey
    np.testing.assert_array_equal(weight_colors(one_hot[:2] * 3.0), palette[:2])
    np.testing.assert_array_equal(weight_colors(np.zeros((1, 4))), [[128, 128, 128]])


def test_weight_colors_bad_inputs():
    with pytest.raises(ValueError, match=r"weights: expected shape \(V, J\), got \(5,\)"):
        weight_colors(np.ones(5))
    with pytest.raises(ValueError, match=r"weights: expected non-negative"):
        weight_colors(np.array([[1.0, -0.5]]))
    with pytest.raises(ValueError, match=r"weights: expected finite"):
        weight_colors(np.array([[np.nan, 1.0]]))
