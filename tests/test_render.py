"""Offscreen rendering: framing, cameras, batches, joints, PNG output and input checks."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import ndimage

# pyrender is imported by smplcore only when rendering, after it picked the OpenGL platform;
# it is not imported here, so that choice is tested as users get it.
from smplcore.render import render_mesh, render_to_png, save_png

SIZE = 160
BG = (1.0, 1.0, 1.0)


def _capsule(height: float = 1.7, radius: float = 0.15) -> trimesh.Trimesh:
    """A capsule standing on y = 0, ``height`` metres tall, along Y."""
    cap = trimesh.creation.capsule(height=height - 2 * radius, radius=radius, count=[16, 16])
    cap.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    cap.apply_translation([0.0, -cap.bounds[0, 1], 0.0])
    return cap


def _slab() -> trimesh.Trimesh:
    """A box 0.6 wide (X), 1.7 tall (Y), 0.15 deep (Z), standing on y = 0."""
    box = trimesh.creation.box(extents=[0.6, 1.7, 0.15])
    box.apply_translation([0.0, 0.85, 0.0])
    return box


def _foreground(img: np.ndarray, background=BG) -> np.ndarray:
    bg = np.round(np.asarray(background) * 255).astype(int)
    return np.any(np.abs(img.astype(int) - bg) > 2, axis=2)


def _check_framed(img: np.ndarray) -> np.ndarray:
    mask = _foreground(img)
    frac = mask.mean()
    assert 0.03 <= frac <= 0.80, f"foreground covers {frac:.1%} of the image"
    rows, cols = np.nonzero(mask)
    h, w = mask.shape
    assert rows.min() > 0 and cols.min() > 0 and rows.max() < h - 1 and cols.max() < w - 1, "object touches the border"
    return mask


@pytest.fixture(scope="module")
def gl() -> None:
    """Skip the GL tests, with the reason, only when no offscreen OpenGL context can be made."""
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    try:
        render_mesh(tri, np.array([[0, 1, 2]]), width=8, height=8)
    except RuntimeError as exc:
        if "could not create an offscreen OpenGL context" in str(exc):
            pytest.skip(f"offscreen OpenGL (EGL/OSMesa) cannot be initialised: {exc}")
        raise


@pytest.fixture(scope="module")
def capsule_image(gl) -> np.ndarray:
    cap = _capsule()
    return render_mesh(cap.vertices, cap.faces, width=SIZE, height=SIZE)


def test_capsule_is_framed_centred_and_shaded(capsule_image, tmp_path):
    img = capsule_image
    assert img.shape == (SIZE, SIZE, 3) and img.dtype == np.uint8
    mask = _check_framed(img)
    rows, cols = np.nonzero(mask)
    # centred, and tall: a 1.7 m capsule fills most of the height
    assert abs(cols.mean() - SIZE / 2) < SIZE * 0.05
    assert abs((rows.min() + rows.max()) / 2 - SIZE / 2) < SIZE * 0.05
    assert rows.max() - rows.min() > 0.6 * SIZE
    # lit and shaded: the object is not one flat colour
    fg = img[mask].astype(float)
    assert fg.std(axis=0).max() > 5.0
    assert np.all(img[0, 0] == 255)
    out = save_png(img, tmp_path / "capsule.png")
    from PIL import Image

    with Image.open(out) as im:
        assert im.size == (SIZE, SIZE) and im.mode == "RGB"
        assert np.array_equal(np.asarray(im), img)


def test_cameras_frame_the_object_and_differ(gl):
    slab = _slab()
    widths = {}
    for camera in ("front", "three_quarter", "side"):
        mask = _check_framed(render_mesh(slab.vertices, slab.faces, width=SIZE, height=SIZE, camera=camera))
        cols = np.nonzero(mask.any(axis=0))[0]
        widths[camera] = cols.max() - cols.min()
    # the slab is 0.6 m wide and 0.15 m deep: narrowest seen from the side
    assert widths["front"] > widths["three_quarter"] > widths["side"]


def test_batch_is_drawn_side_by_side(gl):
    cap = _capsule()
    verts = np.stack([cap.vertices, cap.vertices * [1.4, 1.0, 1.4]])
    img = render_mesh(verts, cap.faces, width=SIZE, height=SIZE, color=[(0.8, 0.3, 0.3), (0.3, 0.3, 0.8)])
    mask = _check_framed(img)
    labels, count = ndimage.label(mask)
    assert count == 2
    centres = [np.nonzero(labels == k)[1].mean() for k in (1, 2)]
    left, right = sorted(zip(centres, (1, 2)))
    # per-mesh colours: the first mesh (red) is on the left
    assert img[labels == left[1]].mean(axis=0)[0] > img[labels == left[1]].mean(axis=0)[2]
    assert img[labels == right[1]].mean(axis=0)[2] > img[labels == right[1]].mean(axis=0)[0]


def test_joints_are_drawn(capsule_image):
    cap = _capsule()
    joints = np.array([[0.0, 0.4, 0.0], [0.0, 0.85, 0.0], [0.0, 1.3, 0.0]])

    def reddish(img):
        px = img.astype(int)
        return int(np.count_nonzero((px[..., 0] - px[..., 2] > 40) & (px[..., 0] - px[..., 1] > 30)))

    plain = capsule_image
    with_joints = render_mesh(cap.vertices, cap.faces, width=SIZE, height=SIZE, joints=joints, joint_radius=0.05)
    assert reddish(plain) == 0
    assert reddish(with_joints) > 20
    _check_framed(with_joints)
    # batch of two with (N, J, 3) joints
    img = render_mesh(np.stack([cap.vertices] * 2), cap.faces, width=SIZE, height=SIZE, joints=np.stack([joints] * 2))
    assert ndimage.label(_foreground(img))[1] == 2


def test_render_to_png_non_square_and_background(gl, tmp_path):
    cap = _capsule()
    black = (0.0, 0.0, 0.0)
    path = render_to_png(tmp_path / "sub" / "out.png", cap.vertices, cap.faces, width=200, height=120, background=black)
    from PIL import Image

    with Image.open(path) as im:
        assert im.size == (200, 120)
        img = np.asarray(im.convert("RGB"))
    assert np.all(img[0, 0] == 0)
    mask = _foreground(img, black)
    assert 0.03 <= mask.mean() <= 0.8
    rows, cols = np.nonzero(mask)
    assert rows.min() > 0 and rows.max() < 119 and abs(cols.mean() - 100) < 10


# ---- input checks: these raise before any OpenGL work, so they need no context ----------------

TRI_V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
TRI_F = np.array([[0, 1, 2]])


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"vertices": np.zeros((4, 2))}, r"vertices: expected shape \(V, 3\) or \(N, V, 3\), got \(4, 2\)"),
        ({"vertices": np.zeros((2, 3, 3, 3))}, r"vertices: expected shape .*got \(2, 3, 3, 3\)"),
        ({"vertices": np.array([[0.0, np.nan, 0.0]] * 3)}, r"vertices: expected finite"),
        ({"faces": np.array([0, 1, 2])}, r"faces: expected shape \(F, 3\).*got \(3,\)"),
        ({"faces": np.array([[0, 1, 3]])}, r"faces: indices must be in \[0, 2\]"),
        ({"faces": np.array([[0.0, 1.0, 2.0]])}, r"faces: expected an integer array"),
        ({"camera": "top"}, r"camera: expected one of"),
        ({"color": (1.0, 2.0, 0.0)}, r"color: expected values in \[0, 1\]"),
        ({"color": (1.0, 0.0)}, r"color: expected shape"),
        ({"background": (255, 255, 255)}, r"background: expected values in \[0, 1\]"),
        ({"width": 0}, r"width: expected 1 to"),
        ({"height": 2.5}, r"height: expected an integer"),
        ({"yfov_deg": 180}, r"yfov_deg: expected"),
        ({"joints": np.zeros((2, 2))}, r"joints: expected shape \(J, 3\), got \(2, 2\)"),
        ({"joints": np.zeros((1, 2, 3))}, r"joints: expected shape \(J, 3\), got \(1, 2, 3\)"),
        ({"joints": np.zeros((2, 3)), "joint_radius": -1.0}, r"joint_radius: expected a positive"),
        ({"alpha": 1.5}, r"alpha: expected a number in \[0, 1\]"),
    ],
)
def test_bad_inputs_name_the_argument(kwargs, pattern):
    args = {"vertices": TRI_V, "faces": TRI_F}
    args.update(kwargs)
    v, f = args.pop("vertices"), args.pop("faces")
    with pytest.raises(ValueError, match=pattern):
        render_mesh(v, f, **args)


def test_batch_joints_must_match_batch():
    verts = np.stack([TRI_V] * 2)
    with pytest.raises(ValueError, match=r"joints: expected shape \(N=2, J, 3\).*got \(3, 2, 3\)"):
        render_mesh(verts, TRI_F, joints=np.zeros((3, 2, 3)))
    with pytest.raises(ValueError, match=r"joints: expected shape \(N=2, J, 3\).*got \(2, 3\)"):
        render_mesh(verts, TRI_F, joints=np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"color: expected shape"):
        render_mesh(verts, TRI_F, color=np.zeros((3, 3)))


def test_save_png_checks(tmp_path):
    with pytest.raises(ValueError, match=r"image: expected shape"):
        save_png(np.zeros((4, 4, 2), dtype=np.uint8), tmp_path / "a.png")
    with pytest.raises(ValueError, match=r"image: expected dtype uint8"):
        save_png(np.zeros((4, 4, 3)), tmp_path / "a.png")
    with pytest.raises(ValueError, match=r"path: expected a file name ending in \.png"):
        save_png(np.zeros((4, 4, 3), dtype=np.uint8), tmp_path / "a.jpg")
    with pytest.raises(ValueError, match=r"path: expected a file name ending in \.png"):
        render_to_png(tmp_path / "a.jpg", TRI_V, TRI_F)


def test_texture_through_the_uv_map_is_drawn_the_right_way_up(gl):
    """A slab whose UVs are its front-view x, y: each quadrant of the texture lands on that quadrant of the
    image (OBJ convention, v up: the texture's first row is the top of the slab)."""
    slab = _slab()
    verts = np.asarray(slab.vertices)
    vt = np.c_[(verts[:, 0] + 0.3) / 0.6, verts[:, 1] / 1.7]
    ft = np.asarray(slab.faces)
    tex = np.zeros((64, 64, 3), np.uint8)
    tex[:32, :32] = (220, 30, 30)  # top left: red
    tex[:32, 32:] = (30, 200, 30)  # top right: green
    tex[32:, :32] = (30, 30, 220)  # bottom left: blue
    tex[32:, 32:] = (230, 230, 30)  # bottom right: yellow
    img = render_mesh(verts, ft, width=SIZE, height=SIZE, uv=(vt, ft), texture=tex).astype(int)
    mask = _foreground(img)
    rows, cols = np.nonzero(mask)
    r0, r1, c0, c1 = rows.min(), rows.max(), cols.min(), cols.max()
    quarter = lambda fy, fx: img[int(r0 + fy * (r1 - r0)), int(c0 + fx * (c1 - c0))]  # noqa: E731
    red, green, blue, yellow = quarter(0.25, 0.25), quarter(0.25, 0.75), quarter(0.75, 0.25), quarter(0.75, 0.75)
    assert red[0] > red[1] + 40 and red[0] > red[2] + 40, red
    assert green[1] > green[0] + 40 and green[1] > green[2] + 40, green
    assert blue[2] > blue[0] + 40 and blue[2] > blue[1] + 40, blue
    assert yellow[0] > yellow[2] + 40 and yellow[1] > yellow[2] + 40, yellow


def test_texture_needs_a_uv_map():
    slab = _slab()
    with pytest.raises(ValueError, match=r"uv: a texture needs the mesh's UV map"):
        render_mesh(slab.vertices, slab.faces, texture="uv-grid")
