"""Readers: OpenPose JSON folders and COCO keypoint JSON into (frames, people, K, 3) arrays."""

from __future__ import annotations

import json

import numpy as np
import pytest

from smplcore import keypoints as kp
from smplcore.errors import ModelFileError


def _person(k, seed, hands=False, face=False):
    rng = np.random.default_rng(seed)
    p = {"person_id": [-1], "pose_keypoints_2d": rng.uniform(0, 500, 3 * k).round(2).tolist()}
    p["hand_left_keypoints_2d"] = rng.uniform(0, 500, 63).round(2).tolist() if hands else []
    p["hand_right_keypoints_2d"] = rng.uniform(0, 500, 63).round(2).tolist() if hands else []
    p["face_keypoints_2d"] = rng.uniform(0, 500, 210).round(2).tolist() if face else []
    return p


def _write_openpose(folder, frames):
    folder.mkdir(exist_ok=True)
    for i, people in enumerate(frames):
        doc = {"version": 1.3, "people": people}
        (folder / f"clip_{i:012d}_keypoints.json").write_text(json.dumps(doc))
    return folder


def test_openpose_folder_body25_with_several_people(tmp_path):
    a, b, c = _person(25, 0), _person(25, 1), _person(25, 2)
    folder = _write_openpose(tmp_path / "op", [[a, b], [c], []])
    arr = kp.read_openpose(folder)
    assert arr.points.shape == (3, 2, 25, 3) and arr.points.dtype == np.float32
    assert arr.convention == "openpose25" and arr.names == kp.names("openpose25")
    np.testing.assert_allclose(arr.points[0, 1].ravel(), b["pose_keypoints_2d"], rtol=1e-6)
    np.testing.assert_allclose(arr.points[1, 0].ravel(), c["pose_keypoints_2d"], rtol=1e-6)
    assert not arr.points[1, 1].any() and not arr.points[2].any()  # missing people are zeros
    assert arr.frames[0].endswith("clip_000000000000_keypoints.json")
    coco, mask = arr.to("coco17")
    assert coco.shape == (3, 2, 17, 3) and mask.all()
    np.testing.assert_array_equal(coco[0, 0, 5], arr.points[0, 0, 5])  # LShoulder is BODY_25's 5
    assert kp.read_openpose(folder, max_people=1).points.shape == (3, 1, 25, 3)


def test_openpose_hands_and_face_give_openpose137(tmp_path):
    p = _person(25, 3, hands=True, face=True)
    folder = _write_openpose(tmp_path / "op", [[p], [_person(25, 4)]])
    arr = kp.read_openpose(folder, hands=True, face=True)
    assert arr.convention == "openpose137" and arr.points.shape == (2, 1, 137, 3)
    np.testing.assert_allclose(arr.points[0, 0, 25:46].ravel(), p["hand_left_keypoints_2d"], rtol=1e-6)
    np.testing.assert_allclose(arr.points[0, 0, 67:].ravel(), p["face_keypoints_2d"], rtol=1e-6)
    assert not arr.points[1, 0, 25:].any()  # empty hand / face lists: zeros
    body_hands = kp.read_openpose(sorted(folder.glob("*.json")), hands=True)
    assert body_hands.convention is None and len(body_hands.names) == 67
    out, mask = kp.convert(body_hands.points, body_hands, "openpose137")
    assert mask[:67].all() and not mask[67:135].any()
    assert mask[135:].all()  # the pupils, approximated by the eyes
    assert kp.plan(body_hands, "openpose137").how[1] == "exact"  # BODY_25's neck keeps its definition


def test_openpose_bad_files_name_file_and_field(tmp_path):
    folder = tmp_path / "bad"
    folder.mkdir()
    (folder / "a.json").write_text("{not json")
    with pytest.raises(ModelFileError, match=r"a\.json: not valid JSON"):
        kp.read_openpose(folder)
    (folder / "a.json").write_text(json.dumps({"people": [{"pose_keypoints_2d": [1.0] * 74}]}))
    with pytest.raises(ModelFileError, match=r"a\.json \[key 'people\[0\]\.pose_keypoints_2d'\]: expected 3 numbers"):
        kp.read_openpose(folder)
    (folder / "a.json").write_text(json.dumps({"people": [{"pose_keypoints_2d": [1.0] * 60}]}))
    with pytest.raises(ModelFileError, match="20 body points; expected 25"):
        kp.read_openpose(folder)
    (folder / "a.json").write_text(json.dumps({"people": [_person(25, 0), _person(18, 1)]}))
    with pytest.raises(ModelFileError, match=r"people\[1\]\.pose_keypoints_2d'\]: expected 25 points"):
        kp.read_openpose(folder)
    (folder / "a.json").write_text(json.dumps({"persons": []}))
    with pytest.raises(ModelFileError, match="key 'people'"):
        kp.read_openpose(folder)
    bad_hand = _person(25, 0)
    bad_hand["hand_left_keypoints_2d"] = ["x"] * 63
    (folder / "a.json").write_text(json.dumps({"people": [bad_hand]}))
    with pytest.raises(ModelFileError, match="hand_left_keypoints_2d'\\]: expected a flat list of numbers"):
        kp.read_openpose(folder, hands=True)
    with pytest.raises(ModelFileError, match="no OpenPose .json files"):
        kp.read_openpose(tmp_path)


def _coco_doc():
    rng = np.random.default_rng(5)

    def ann(i, image):
        kps = np.column_stack([rng.uniform(0, 640, 17), rng.uniform(0, 480, 17), rng.integers(0, 3, 17)])
        return {"id": i, "image_id": image, "category_id": 1, "keypoints": kps.ravel().tolist(), "num_keypoints": 17}

    return {
        "images": [{"id": 7}, {"id": 3}, {"id": 9}],
        "annotations": [ann(1, 3), ann(2, 7), ann(3, 3)],
        "categories": [{"id": 1, "name": "person", "keypoints": list(kp.names("coco17"))}],
    }


def test_coco_keypoints_grouped_by_image(tmp_path):
    doc = _coco_doc()
    path = tmp_path / "person_keypoints.json"
    path.write_text(json.dumps(doc))
    arr = kp.read_coco(path)
    assert arr.convention == "coco17" and arr.frames == (7, 3, 9)
    assert arr.points.shape == (3, 2, 17, 3)
    np.testing.assert_allclose(arr.points[0, 0].ravel(), doc["annotations"][1]["keypoints"], rtol=1e-6)
    np.testing.assert_allclose(arr.points[1, 1].ravel(), doc["annotations"][2]["keypoints"], rtol=1e-6)
    assert not arr.points[2].any()  # image 9 has nobody
    assert set(np.unique(arr.points[..., 2][arr.points[..., 0] > 0])) <= {0.0, 1.0, 2.0}


def test_coco_wholebody(tmp_path):
    doc = _coco_doc()
    for ann in doc["annotations"]:
        for key, k in (("foot_kpts", 6), ("face_kpts", 68), ("lefthand_kpts", 21), ("righthand_kpts", 21)):
            ann[key] = [float(ann["id"])] * (3 * k)
    doc["annotations"][0]["face_kpts"] = []
    path = tmp_path / "wholebody.json"
    path.write_text(json.dumps(doc))
    arr = kp.read_coco(path)
    assert arr.convention == "coco_wholebody133" and arr.points.shape == (3, 2, 133, 3)
    assert np.all(arr.points[1, 0, 17:23] == 1.0) and not arr.points[1, 0, 23:91].any()


def test_coco_bad_files_name_file_and_field(tmp_path):
    path = tmp_path / "c.json"
    doc = _coco_doc()
    doc["annotations"][1]["keypoints"] = doc["annotations"][1]["keypoints"][:-3]
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelFileError, match=r"c\.json \[key 'annotations\[1\]\.keypoints'\]: expected 17 points"):
        kp.read_coco(path)
    doc = _coco_doc()
    del doc["annotations"][2]["image_id"]
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelFileError, match=r"annotations\[2\]\.image_id"):
        kp.read_coco(path)
    doc = _coco_doc()
    doc["images"] = [{"id": 7}]
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelFileError, match=r"image ids \[3\] not listed in 'images'"):
        kp.read_coco(path)
    path.write_text(json.dumps({"images": []}))
    with pytest.raises(ModelFileError, match="key 'annotations'"):
        kp.read_coco(path)
