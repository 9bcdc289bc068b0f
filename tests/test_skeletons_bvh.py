"""The BVH reader: BVH text built in code (every rotation order, gzip, CRLF, tabs, exponents, End Sites, zero
offsets), checked against an independent forward kinematics; malformed files give errors naming file and line;
a round trip through smplcore's own BVH exporter; real clips when the shared mocap is present."""

from __future__ import annotations

import gzip
import itertools
from pathlib import Path

import numpy as np
import pytest

from bvh_text import bvh_text, reference_positions
from smplcore.errors import ModelFileError
from smplcore.skeletons import BVHClip, parse_bvh, read_bvh

MOCAP = Path("/work/shared/data/mocap")
ORDERS = ["".join(p) for p in itertools.permutations("XYZ")] + ["XY", "ZX", "Y", ""]


def _chain(orders, frames=5, seed=0):
    """A root and a chain of joints with the given rotation orders, random angles and offsets."""
    rng = np.random.default_rng(seed)
    count = len(orders)
    parents = [-1] + list(range(count - 1))
    offsets = rng.normal(size=(count, 3))
    offsets[0] = 0.0
    angles = [rng.uniform(-179, 179, size=(frames, len(o))) for o in orders]
    root = rng.normal(size=(frames, 3)) * 10
    names = [f"j{k}" for k in range(count)]
    return names, parents, offsets, orders, angles, root


@pytest.mark.parametrize("order", ORDERS)
def test_every_rotation_order_matches_forward_kinematics_by_hand(order):
    names, parents, offsets, orders, angles, root = _chain(["ZYX", order, order, "XZY"])
    clip = parse_bvh(bvh_text(names, parents, offsets, orders, angles, root, number="{:.10f}"))
    want = reference_positions(parents, offsets, orders, angles, root)
    np.testing.assert_allclose(clip.world_positions(), want, atol=1e-7)
    assert clip.channels[1] == tuple(f"{a}rotation" for a in order)


def test_mixed_orders_in_one_file_and_angles_wrapping():
    names, parents, offsets, orders, angles, root = _chain(["ZYX", "ZXY", "YXZ", "XYZ", "ZYX"], frames=4)
    angles[2] = angles[2] + 360.0  # wrapped angles: the same rotations
    clip = parse_bvh(bvh_text(names, parents, offsets, orders, angles, root, number="{:.10f}"))
    want = reference_positions(parents, offsets, orders, angles, root)
    np.testing.assert_allclose(clip.world_positions(), want, atol=1e-7)


def test_crlf_lf_mix_tabs_exponents_and_short_frame_time():
    names, parents, offsets, orders, angles, root = _chain(["ZYX", "ZXY", "ZXY"], frames=3)
    text = bvh_text(names, parents, offsets, orders, angles, root, frame_time=".0083333", newline="\r\n",
                    indent="\t", number="{:.8e}")  # fmt: skip
    first, rest = text.split("\r\n", 2)[:2], text.split("\r\n", 2)[2]
    text = "\n".join(first) + "\n" + rest.replace("Frames: ", "Frames:\t").replace("Frame Time: ", "Frame Time:\t")
    clip = parse_bvh(text)
    assert clip.fps == 120.0 and clip.frame_time == 0.0083333  # a Frame Time printed to few digits
    np.testing.assert_allclose(clip.world_positions(), reference_positions(parents, offsets, orders, angles, root),
                               atol=1e-6)  # fmt: skip


def test_end_sites_and_zero_length_offsets():
    names = ["Hips", "LowerBack", "Spine", "Neck", "Head"]
    parents = [-1, 0, 1, 2, 3]
    offsets = np.array([[0, 0, 0], [0, 0, 0], [0, 2.0, 0], [0, 0, 0], [0, 1.5, 0]])
    orders = ["ZYX"] * 5
    frames = 2
    angles = [np.zeros((frames, 3)) for _ in names]
    angles[3][:, 2] = 90.0  # the zero-length Neck still rotates what hangs from it
    root = np.zeros((frames, 3))
    text = bvh_text(names, parents, offsets, orders, angles, root, end_sites={4: (0, 1.0, 0)})
    clip = parse_bvh(text)
    pos = clip.world_positions(end_sites=True)
    assert clip.point_names == ("Hips", "LowerBack", "Spine", "Neck", "Head", "Head_end")
    np.testing.assert_allclose(pos[0, 3], pos[0, 2])  # Neck coincides with Spine
    np.testing.assert_allclose(pos[0, 4], [0, 2.0, 1.5], atol=1e-12)  # Head: 1.5 along the rotated Neck's y = +z
    np.testing.assert_allclose(pos[0, 5], [0, 2.0, 2.5], atol=1e-12)
    np.testing.assert_allclose(clip.rest_positions(end_sites=True)[-1], [0, 4.5, 0])


def test_gzip_is_read_from_its_first_bytes(tmp_path):
    names, parents, offsets, orders, angles, root = _chain(["ZYX", "ZXY"], frames=3)
    text = bvh_text(names, parents, offsets, orders, angles, root)
    plain = tmp_path / "clip.bvh"
    plain.write_text(text)
    zipped = tmp_path / "clip.bvh.gz"
    zipped.write_bytes(gzip.compress(text.encode()))
    unnamed = tmp_path / "other.bvh"
    unnamed.write_bytes(gzip.compress(text.encode()))
    a, b, c = read_bvh(plain), read_bvh(zipped), read_bvh(unnamed)
    np.testing.assert_array_equal(a.world_positions(), b.world_positions())
    np.testing.assert_array_equal(a.world_positions(), c.world_positions())
    assert b.source == str(zipped)


def test_reference_pose_frame_zero_is_detected_and_dropped():
    names, parents, offsets, orders, angles, root = _chain(["ZYX", "ZXY", "ZXY"], frames=6)
    for a in angles:
        a[0] = 0.0  # a T-pose frame 0: zero root rotation, joints at rest
    angles[1][0, 0] = 3.0
    clip = parse_bvh(bvh_text(names, parents, offsets, orders, angles, root))
    assert clip.reference_pose and clip.num_frames == 6
    dropped = clip.without_reference_pose()
    assert dropped.num_frames == 5 and dropped.dropped_reference_pose and not dropped.reference_pose
    np.testing.assert_allclose(dropped.world_positions(), clip.world_positions()[1:])
    again = parse_bvh(bvh_text(names, parents, offsets, orders, angles, root), drop_reference_pose=True)
    assert again.num_frames == 5


def test_motion_whose_root_never_turns_is_not_a_reference_pose():
    names, parents, offsets, orders, angles, root = _chain(["ZYX", "ZXY"], frames=4)
    angles[0][:] = 0.0  # the root rotation is zero throughout: frame 0 is motion like the others
    angles[1][0] = 0.0
    assert not parse_bvh(bvh_text(names, parents, offsets, orders, angles, root)).reference_pose


def test_position_channels_on_a_joint_replace_its_offset():
    text = """HIERARCHY
ROOT a
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT b
  {
    OFFSET 1 0 0
    CHANNELS 4 Yposition Zrotation Xrotation Yrotation
  }
}
MOTION
Frames: 1
Frame Time: 0.01
5 6 7 0 0 0 2.5 0 0 0
"""
    clip = parse_bvh(text)
    np.testing.assert_allclose(clip.world_positions()[0], [[5, 6, 7], [6, 8.5, 7]])


def test_round_trip_through_the_bvh_exporter(tmp_path):
    import smplcore
    from smplcore.export import save_bvh

    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    rng = np.random.default_rng(3)
    params = {"body_pose": rng.normal(scale=0.3, size=(3, 69)), "global_orient": rng.normal(scale=0.5, size=(3, 3)),
              "transl": rng.normal(size=(3, 3))}  # fmt: skip
    for order in ("ZYX", "XZY"):
        path = tmp_path / f"motion_{order}.bvh"
        save_bvh(path, model, params, euler=order, decimals=8)
        clip = read_bvh(path)
        joints = model(**params).joints[:, :24]
        assert clip.joint_names[:3] == ("pelvis", "left_hip", "left_knee")
        index = [clip.joint_names.index(n) for n in model.joint_names[:24]]
        np.testing.assert_allclose(clip.world_positions()[:, index], joints, atol=1e-6)


def _bad(text: str, tmp_path, name="bad.bvh") -> str:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ModelFileError) as info:
        read_bvh(path)
    message = str(info.value)
    assert str(path) in message
    return message


GOOD = bvh_text(*_chain(["ZYX", "ZXY"], frames=3))


def test_truncated_motion_names_the_last_line(tmp_path):
    lines = GOOD.splitlines()
    message = _bad("\n".join(lines[:-1]) + "\n", tmp_path)
    assert "truncated motion: Frames: 3" in message and f"line {len(lines) - 1}" in message


def test_frame_line_with_a_missing_value_names_its_line(tmp_path):
    lines = GOOD.splitlines()
    lines[-2] = " ".join(lines[-2].split()[:-1])
    message = _bad("\n".join(lines) + "\n", tmp_path)
    assert f"line {len(lines) - 1}: 8 values in a frame line, the CHANNELS declare 9" in message


def test_non_finite_and_non_numeric_values_name_line_and_channel(tmp_path):
    lines = GOOD.splitlines()
    bad = lines[-1].split()
    bad[4] = "nan"
    message = _bad("\n".join(lines[:-1] + [" ".join(bad)]) + "\n", tmp_path)
    assert f"line {len(lines)}: value 5 (j0 Yrotation) is 'nan', not a finite number" in message
    bad[4] = "1e999"
    assert "not a finite number" in _bad("\n".join(lines[:-1] + [" ".join(bad)]) + "\n", tmp_path)
    bad[4] = "abc"
    assert "is 'abc', not a number" in _bad("\n".join(lines[:-1] + [" ".join(bad)]) + "\n", tmp_path)


def test_channel_count_mismatch_in_the_header(tmp_path):
    text = GOOD.replace("CHANNELS 3 Z", "CHANNELS 4 Z", 1)
    message = _bad(text, tmp_path)
    assert "line 9: j1: CHANNELS 4 lists 3 channel name(s)" in message
    text = GOOD.replace("CHANNELS 3 Z", "CHANNELS 2 Z", 1)
    assert "CHANNELS 2 but more channel names follow" in _bad(text, tmp_path)
    assert "then 'Wrotation': expected Xposition ... Zrotation" in _bad(
        GOOD.replace("Xrotation", "Wrotation", 1), tmp_path
    )


def test_absurd_frame_count_is_refused_before_allocating(tmp_path):
    message = _bad(GOOD.replace("Frames: 3", "Frames: 100000000000"), tmp_path)
    assert "Frames: 100000000000 frames of 9 values need at least" in message and "truncated" in message


def test_broken_headers(tmp_path):
    assert "expected 'HIERARCHY'" in _bad("hello\n", tmp_path)
    assert "still open" in _bad(GOOD.replace("}\nMOTION", "MOTION"), tmp_path)
    assert "expected 'Frames: N'" in _bad(GOOD.replace("Frames: 3", "Frames 3 x"), tmp_path)
    assert "Frame Time: expected seconds" in _bad(GOOD.replace("Frame Time: 0.0333333", "Frame Time: -1"), tmp_path)
    assert "truncated header" in _bad(GOOD.split("MOTION")[0][:-3], tmp_path)
    assert "OFFSET: expected a number" in _bad(GOOD.replace("OFFSET 0.000000", "OFFSET x", 1), tmp_path)


def test_gzip_bomb_and_truncated_gzip_are_refused(tmp_path):
    path = tmp_path / "bomb.bvh.gz"
    path.write_bytes(gzip.compress(b"HIERARCHY\n" + b" " * 5_000_000))
    with pytest.raises(ModelFileError, match="decompresses to more than 1,000,000 bytes"):
        read_bvh(path, max_bytes=1_000_000)
    cut = tmp_path / "cut.bvh.gz"
    cut.write_bytes(gzip.compress(GOOD.encode())[:-30])
    with pytest.raises(ModelFileError, match="truncated"):
        read_bvh(cut)


def test_a_folder_is_refused(tmp_path):
    with pytest.raises(ModelFileError, match=str(tmp_path)):
        read_bvh(tmp_path)


def _real(folder: str, name: str) -> Path:
    path = MOCAP / folder / name
    if not path.is_file():
        pytest.skip(f"the shared mocap ({path}) is absent")
    return path


@pytest.mark.parametrize(
    "folder,name,joints,frames,reference",
    [
        ("cmu_daz_ateliercircle", "02_01.bvh.gz", 43, None, True),
        ("cmu_mb_jonathanalderson", "05_06.bvh.gz", 31, 886, True),
        ("cmu_max_bvh11", "131_02.bvh.gz", 31, 1247, False),
        ("fair_animateddrawings", "dab.bvh.gz", 27, 339, False),
    ],
)
def test_real_clips(folder, name, joints, frames, reference):
    clip = read_bvh(_real(folder, name))
    assert isinstance(clip, BVHClip)
    assert clip.num_joints == joints and clip.reference_pose is reference
    if frames is not None:
        assert clip.num_frames == frames
    assert np.all(np.isfinite(clip.world_positions()))
    rot = clip.rotations.reshape(-1, 3, 3)
    np.testing.assert_allclose(rot @ np.swapaxes(rot, -1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)
