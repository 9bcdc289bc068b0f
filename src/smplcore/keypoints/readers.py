"""Readers for the common keypoint files: OpenPose JSON folders and COCO keypoint JSON.

Both give a :class:`KeypointArray`: ``points`` (frames, people, K, 3) float32 holding x, y and a
confidence (OpenPose's score, COCO's visibility flag 0/1/2), with people missing from a frame
left as zeros, and the ``names`` / ``convention`` of the K points, ready for
:func:`smplcore.keypoints.convert`. Bad files raise :class:`~smplcore.errors.ModelFileError`
naming the file and the field.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.keypoints.conventions import COCO17, CONVENTIONS, FACE68, FEET6, hand21


@dataclass(frozen=True)
class KeypointArray:
    """Keypoints read from files.

    Attributes
    ----------
    points : (F, P, K, 3) float32: x, y (pixels) and confidence per frame, person and point.
    names : K vocabulary names of the points.
    convention : the convention key when the points are exactly one (``"openpose25"``), else None.
    frames : F labels: the JSON file of each frame (OpenPose) or the image id (COCO).
    qualified : K names qualified by the convention of the part they come from
        (``"openpose25:neck"``, ``"hand21_left:left_index1"``), so that points keep their
        convention's definitions when the whole is no single convention.
    """

    points: np.ndarray
    names: tuple[str, ...]
    convention: str | None
    frames: tuple[Any, ...]
    qualified: tuple[str, ...] = ()

    @property
    def joint_names(self) -> list[str]:
        """The point names (so a KeypointArray can be ``src`` of :func:`~smplcore.keypoints.convert`)."""
        return list(self.qualified or self.names)

    def to(self, dst: Any, exact_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``convert(self.points, self, dst, exact_only)``: (F, P, K_dst, 3) points and the (K_dst,) mask."""
        from smplcore.keypoints.convert import convert

        return convert(self.points, self, dst, exact_only=exact_only)


def _convention_of(names: tuple[str, ...]) -> str | None:
    return next((key for key, value in CONVENTIONS.items() if value == names), None)


def _load_json(path: Path) -> Any:
    from smplcore.io import read_json

    return read_json(path, "a keypoint file (.json)")


def _triples(path: Path, field: str, value: Any, count: int | None) -> np.ndarray | None:
    """A flat [x, y, c, x, y, c, ...] list as (K, 3); None for an empty list. ``count``: required K."""
    if value is None or (isinstance(value, list) and len(value) == 0):
        return None
    if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise ModelFileError(path, "expected a flat list of numbers [x, y, c, x, y, c, ...]", key=field)
    if len(value) % 3:
        raise ModelFileError(path, f"expected 3 numbers per point, got {len(value)} numbers", key=field)
    out = np.asarray(value, dtype=np.float32).reshape(-1, 3)
    if not np.all(np.isfinite(out)):
        raise ModelFileError(path, "holds NaN or infinite numbers", key=field)
    if count is not None and out.shape[0] != count:
        raise ModelFileError(path, f"expected {count} points ({3 * count} numbers), got {out.shape[0]}", key=field)
    return out


# -- OpenPose -------------------------------------------------------------------------------------

_OPENPOSE_BODIES = {25: "openpose25", 18: "openpose18", 135: "openpose135"}


def _max_people(value: int | None) -> None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 0):
        raise ValueError(f"max_people: expected None or a non-negative integer, got {value!r}")


def _openpose_files(source: str | Path | Sequence[str | Path]) -> list[Path]:
    if not isinstance(source, (str, Path, list, tuple)):
        raise TypeError(f"source: expected a folder, a file or a list of files, got {type(source).__name__}")
    if isinstance(source, (str, Path)):
        path = Path(source)
        if path.is_dir():
            files = sorted(path.glob("*.json"))
            if not files:
                raise ModelFileError(path, "no OpenPose .json files in this folder")
            return files
        return [path]
    return [Path(p) for p in source]


def read_openpose(
    source: str | Path | Sequence[str | Path],
    *,
    hands: bool = False,
    face: bool = False,
    max_people: int | None = None,
) -> KeypointArray:
    """Read OpenPose's JSON output: a folder of per-frame files (sorted by name), one file, or a list.

    Parameters
    ----------
    source : folder, file or list of files.
    hands, face : also read ``hand_left_keypoints_2d``, ``hand_right_keypoints_2d`` (21 each) and
        ``face_keypoints_2d`` (70), appended after the body in that order. Parts a person lacks
        (empty lists) are zeros.
    max_people : keep at most this many people per frame (in file order); default all.

    Returns
    -------
    KeypointArray with points (F, P, K, 3); convention ``openpose25`` (or ``openpose18`` /
    ``openpose135`` by the body's size), ``openpose137`` for BODY_25 with hands and face, else None.
    """
    _max_people(max_people)
    files = _openpose_files(source)
    body_k: int | None = None
    frames: list[list[np.ndarray]] = []
    for path in files:
        doc = _load_json(path)
        if not isinstance(doc, dict) or not isinstance(doc.get("people"), list):
            raise ModelFileError(path, "expected an object with a list 'people' (OpenPose's JSON output)", key="people")
        people = []
        for p, person in enumerate(doc["people"]):
            if not isinstance(person, dict):
                raise ModelFileError(path, "expected an object per person", key=f"people[{p}]")
            field = f"people[{p}].pose_keypoints_2d"
            body = _triples(path, field, person.get("pose_keypoints_2d"), body_k)
            if body is None:
                if "pose_keypoints_2d" not in person:
                    raise ModelFileError(path, "missing", key=field)
                continue  # a person without a body: OpenPose writes these when only hands/face ran
            if body_k is None:
                if body.shape[0] not in _OPENPOSE_BODIES:
                    raise ModelFileError(
                        path, f"{body.shape[0]} body points; expected 25 (BODY_25), 18 (COCO) or 135", key=field
                    )
                body_k = body.shape[0]
            parts = [body]
            for wanted, key, count in (
                (hands, "hand_left_keypoints_2d", 21),
                (hands, "hand_right_keypoints_2d", 21),
                (face, "face_keypoints_2d", 70),
            ):
                if wanted:
                    part = _triples(path, f"people[{p}].{key}", person.get(key), count)
                    parts.append(np.zeros((count, 3), np.float32) if part is None else part)
            people.append(np.concatenate(parts))
        frames.append(people[:max_people] if max_people is not None else people)
    if body_k is None:
        body_k = 25
    conventions = (
        [_OPENPOSE_BODIES[body_k]] + (["hand21_left", "hand21_right"] if hands else []) + (["face70"] if face else [])
    )
    return _pack(frames, conventions, tuple(str(f) for f in files))


def _pack(frames: list[list[np.ndarray]], parts: list[str] | tuple[str, ...], labels: tuple[Any, ...]) -> KeypointArray:
    """Stack per-frame people into (F, P, K, 3); ``parts``: the conventions (or names) of the K points."""
    if all(p in CONVENTIONS for p in parts):
        names = tuple(n for p in parts for n in CONVENTIONS[p])
        qualified = tuple(f"{p}:{n}" for p in parts for n in CONVENTIONS[p])
    else:
        names, qualified = tuple(parts), ()
    count = max((len(f) for f in frames), default=0)
    points = np.zeros((len(frames), count, len(names), 3), dtype=np.float32)
    for i, people in enumerate(frames):
        for j, person in enumerate(people):
            points[i, j] = person
    convention = _convention_of(names)
    return KeypointArray(points, names, convention, labels, () if convention else qualified)


# -- COCO -----------------------------------------------------------------------------------------

_WHOLEBODY_PARTS = (
    ("keypoints", COCO17),
    ("foot_kpts", FEET6),
    ("face_kpts", FACE68),
    ("lefthand_kpts", hand21("left")),
    ("righthand_kpts", hand21("right")),
)
_WHOLEBODY = COCO17 + FEET6 + FACE68 + hand21("left") + hand21("right")


def read_coco(path: str | Path, *, max_people: int | None = None) -> KeypointArray:
    """Read a COCO keypoint JSON (``annotations[].keypoints``, grouped per ``image_id``).

    COCO-WholeBody files (with ``foot_kpts``, ``face_kpts``, ``lefthand_kpts``, ``righthand_kpts``)
    give all 133 points. Frames are the images in the order of ``images`` (images without people
    give an all-zero frame), or the sorted image ids when there is no ``images`` list. A keypoint
    list of another length than 17 uses the names in ``categories[0].keypoints``.

    Returns
    -------
    KeypointArray with points (F, P, K, 3): x, y and COCO's visibility (0 not labelled, 1 labelled
    but hidden, 2 visible); convention ``coco17`` / ``coco_wholebody133`` (None for other lists).
    """
    _max_people(max_people)
    path = Path(path)
    doc = _load_json(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("annotations"), list):
        raise ModelFileError(
            path, "expected an object with a list 'annotations' (a COCO keypoint file)", key="annotations"
        )
    annotations = doc["annotations"]
    wholebody = any(isinstance(a, dict) and "foot_kpts" in a for a in annotations)
    names: tuple[str, ...] | None = _WHOLEBODY if wholebody else None
    by_image: dict[Any, list[np.ndarray]] = {}
    for i, ann in enumerate(annotations):
        where = f"annotations[{i}]"
        if not isinstance(ann, dict):
            raise ModelFileError(path, "expected an object", key=where)
        if "image_id" not in ann:
            raise ModelFileError(path, "missing", key=f"{where}.image_id")
        if not isinstance(ann["image_id"], (int, str)) or isinstance(ann["image_id"], bool):
            got = repr(ann["image_id"])[:40]
            raise ModelFileError(path, f"expected a number or a string, got {got}", key=f"{where}.image_id")
        if "keypoints" not in ann:
            raise ModelFileError(path, "missing (not a keypoint annotation)", key=f"{where}.keypoints")
        if wholebody:
            parts = []
            for key, part_names in _WHOLEBODY_PARTS:
                part = _triples(path, f"{where}.{key}", ann.get(key), len(part_names))
                parts.append(np.zeros((len(part_names), 3), np.float32) if part is None else part)
            person = np.concatenate(parts)
        else:
            found = _triples(path, f"{where}.keypoints", ann["keypoints"], None if names is None else len(names))
            if found is None:
                raise ModelFileError(path, "empty", key=f"{where}.keypoints")
            person = found
            if names is None:
                names = _coco_names(path, doc, person.shape[0], f"{where}.keypoints")
        by_image.setdefault(ann["image_id"], []).append(person)
    images = doc.get("images")
    if isinstance(images, list) and all(isinstance(im, dict) and "id" in im for im in images):
        ids = [im["id"] for im in images]
        for i, k in enumerate(ids):
            if not isinstance(k, (int, str)) or isinstance(k, bool):
                raise ModelFileError(path, f"expected a number or a string, got {repr(k)[:40]}", key=f"images[{i}].id")
        unknown = [k for k in by_image if k not in set(ids)]
        if unknown:
            raise ModelFileError(
                path, f"annotations refer to image ids {unknown[:5]} not listed in 'images'", key="images"
            )
    else:
        ids = sorted(by_image, key=lambda k: (str(type(k)), k))
    frames = [by_image.get(k, [])[:max_people] if max_people is not None else by_image.get(k, []) for k in ids]
    names = names or COCO17
    convention = _convention_of(names)
    return _pack(frames, [convention] if convention else names, tuple(ids))


def _coco_names(path: Path, doc: dict, count: int, field: str) -> tuple[str, ...]:
    if count == 17:
        return COCO17
    categories = doc.get("categories")
    listed = categories[0].get("keypoints") if isinstance(categories, list) and categories else None
    if isinstance(listed, list) and len(listed) == count and all(isinstance(n, str) for n in listed):
        from smplcore.keypoints.aliases import canonical_names

        return canonical_names(listed)
    raise ModelFileError(
        path, f"{count} keypoints per person, not COCO's 17, and no matching 'categories[0].keypoints' names", key=field
    )
