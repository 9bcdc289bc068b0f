"""Turning model files (official layouts and smplcore's own .npz) into validated :class:`ModelData`."""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError
from smplcore.family.specs import MODEL_TYPE_BY_NUM_JOINTS, get_spec
from smplcore.io.containers import read_container
from smplcore.io.model_data import MODEL_TYPES, ModelData

FORMAT_TAG = "smplcore-model-1"

# Keys official files carry that smplcore does not need (read and ignored without a warning).
_KNOWN_UNUSED = {
    "J",
    "J_regressor_prior",
    "weights_prior",
    "vert_sym_idxs",
    "pose_training_info",
    "bs_style",
    "bs_type",
    "hands_coeffsl",
    "hands_coeffsr",
    "hands_coeffs",
    "vt",
    "ft",
    "joint2num",
    "part2num",
    "allow_pickle",
    "shapedirs_mean",
    "joint_names",
    "e",
    "u",
}
_OFFICIAL_KEYS = {
    "v_template",
    "f",
    "shapedirs",
    "posedirs",
    "J_regressor",
    "weights",
    "kintree_table",
    "hands_componentsl",
    "hands_componentsr",
    "hands_meanl",
    "hands_meanr",
    "hands_components",
    "hands_mean",
    "lmk_faces_idx",
    "lmk_bary_coords",
    "dynamic_lmk_faces_idx",
    "dynamic_lmk_bary_coords",
}
_OURS_OPTIONAL = {
    "posedirs",
    "exprdirs",
    "hands_components_left",
    "hands_components_right",
    "hands_mean_left",
    "hands_mean_right",
    "lmk_faces_idx",
    "lmk_bary_coords",
    "dynamic_lmk_faces_idx",
    "dynamic_lmk_bary_coords",
    "joint_names",
    "extra_joint_names",
    "extra_joint_vertex_ids",
    "vt",
    "ft",
}
_OURS_REQUIRED = {
    "format",
    "model_type",
    "gender",
    "v_template",
    "faces",
    "shapedirs",
    "J_regressor",
    "weights",
    "parents",
}

# File names (upper-cased) that tell the model type when the name does not start with it.
_NAME_PATTERNS = (
    (re.compile(r"^BASICMODEL_(F|M|NEUTRAL)_LBS"), "smpl"),
    (re.compile(r"^SMPLX_"), "smplx"),
    (re.compile(r"^SMPLH_"), "smplh"),
    (re.compile(r"^SMPL_"), "smpl"),
    (re.compile(r"^MANO_"), "mano"),
    (re.compile(r"^(FLAME|GENERIC_MODEL)"), "flame"),
)


def model_type_from_name(path: str | Path) -> str | None:
    """The model type an official file name states (``SMPLH_MALE.pkl`` → ``smplh``), or None."""
    name = Path(path).name.upper()
    for pattern, model_type in _NAME_PATTERNS:
        if pattern.match(name):
            return model_type
    return None


def gender_from_name(path: str | Path) -> str | None:
    """The gender (or MANO side) an official file name states, or None."""
    name = Path(path).name.upper()
    basic = re.match(r"^BASICMODEL_(F|M|NEUTRAL)_", name)
    if basic:
        return {"F": "female", "M": "male", "NEUTRAL": "neutral"}[basic.group(1)]
    for word in ("FEMALE", "MALE", "NEUTRAL", "RIGHT", "LEFT"):
        if re.search(rf"(^|[_\-/.]){word}([_\-.]|$)", name):
            return word.lower()
    return None


def load_model(path: str | Path, *, model_type: str | None = None, gender: str | None = None) -> ModelData:
    """Read a model file of any supported layout into :class:`ModelData`.

    Parameters
    ----------
    path : an official ``.pkl`` / ``.npz`` file (SMPL, SMPL+H, SMPL-X, MANO, FLAME) or a smplcore
        ``.npz`` written by :func:`save_npz`. No chumpy is needed and nothing in the file is run.
    model_type : expected model type; when None it is taken from the file name, else from the
        number of joints the file holds. A file whose contents contradict it is rejected.
    gender : recorded in the result; when None it is taken from the file name (``neutral`` if none).

    Raises
    ------
    ModelFileError
        naming the file, and the key with expected and found shapes where one is at fault.
    """
    path = Path(path)
    raw = read_container(path)
    if "format" in raw:
        data = _from_smplcore_npz(path, raw, model_type)
    else:
        data = _from_official(path, raw, model_type, gender)
    return _with_file_uv(data, path, raw)


def _with_file_uv(data: ModelData, path: Path, raw: dict[str, Any]) -> ModelData:
    """The UV map (``vt``, ``ft``) the file carries, checked against its faces (see :mod:`smplcore.io.uv`)."""
    from smplcore.io.uv import uv_from_file_arrays

    uv = uv_from_file_arrays(path, raw, data.faces.shape[0])
    return data.replace(**uv) if uv else data


def save_npz(data: ModelData, path: str | Path) -> Path:
    """Write ``data`` as smplcore's pickle-free ``.npz`` (loads with ``np.load(allow_pickle=False)``)."""
    path = Path(path)
    arrays: dict[str, np.ndarray] = {"format": np.array(FORMAT_TAG)}
    for name in ("model_type", "gender"):
        arrays[name] = np.array(getattr(data, name))
    for name in (
        "v_template",
        "faces",
        "shapedirs",
        "posedirs",
        "J_regressor",
        "weights",
        "parents",
        "exprdirs",
        "hands_components_left",
        "hands_components_right",
        "hands_mean_left",
        "hands_mean_right",
        "lmk_faces_idx",
        "lmk_bary_coords",
        "dynamic_lmk_faces_idx",
        "dynamic_lmk_bary_coords",
        "vt",
        "ft",
    ):
        value = getattr(data, name)
        if value is not None:
            arrays[name] = np.asarray(value)
    if data.joint_names:
        arrays["joint_names"] = np.array(data.joint_names)
    if data.extra_joint_names:
        arrays["extra_joint_names"] = np.array(data.extra_joint_names)
        arrays["extra_joint_vertex_ids"] = np.asarray(data.extra_joint_vertex_ids, dtype=np.int64)
    if path.suffix != ".npz":
        raise ValueError(f"path: smplcore model files end in .npz, got {path.name!r}")
    np.savez_compressed(path, **arrays)
    return path


def convert(src: str | Path, dst: str | Path, *, model_type: str | None = None, gender: str | None = None) -> Path:
    """Read any supported model file and write it as a clean smplcore ``.npz``."""
    return save_npz(load_model(src, model_type=model_type, gender=gender), dst)


# --------------------------------------------------------------------------------------------------


class _Checker:
    """Pulls keys out of a raw dict with shape checks that name the file and key."""

    def __init__(self, path: Path, raw: dict[str, Any]):
        self.path, self.raw = path, raw

    def get(self, key: str, *, required: bool = True) -> np.ndarray | None:
        if key not in self.raw:
            if required:
                raise ModelFileError(self.path, f"missing key; the file has {sorted(self.raw)}", key=key)
            return None
        value = self.raw[key]
        if hasattr(value, "toarray"):  # scipy.sparse
            value = value.toarray()
        try:
            value = np.asarray(value)
        except Exception as exc:  # noqa: BLE001 - report anything unusable as a file error
            raise ModelFileError(self.path, f"not an array ({exc})", key=key) from None
        if value.dtype == object:
            raise ModelFileError(self.path, "holds Python objects, expected a numeric array", key=key)
        return value

    def expect(self, key: str, value: np.ndarray, shape: tuple, what: str = "") -> np.ndarray:
        """Check ``value.shape`` against ``shape`` (None entries match anything)."""
        ok = value.ndim == len(shape) and all(e is None or e == s for e, s in zip(shape, value.shape))
        if not ok:
            expected = "(" + ", ".join("*" if e is None else str(e) for e in shape) + ")"
            raise ModelFileError(self.path, f"expected shape {expected}{what}, found {value.shape}", key=key)
        if value.dtype.kind in "fc" and not np.all(np.isfinite(value)):
            raise ModelFileError(self.path, "contains NaN or infinite values", key=key)
        return value


def _infer_model_type(path: Path, num_joints: int, requested: str | None) -> str:
    from_contents = MODEL_TYPE_BY_NUM_JOINTS.get(num_joints)
    if requested is not None:
        requested = get_spec(requested).model_type
        expected_joints = get_spec(requested).num_joints
        if requested != "open" and num_joints != expected_joints:
            found = f"a {num_joints}-joint " + (
                f"{get_spec(from_contents).display_name} model" if from_contents else "model"
            )
            raise ModelFileError(
                path,
                f"model_type={requested!r} needs {expected_joints} joints, but the file holds {found}",
                key="kintree_table",
            )
        return requested
    if from_contents is None:
        raise ModelFileError(
            path, f"cannot tell the model type of a {num_joints}-joint model; pass model_type", key="kintree_table"
        )
    return from_contents


def _parents_from_kintree(kintree: np.ndarray) -> np.ndarray:
    parents = kintree[0].astype(np.int64)
    parents[0] = -1
    return parents


def _from_official(path: Path, raw: dict[str, Any], model_type: str | None, gender: str | None) -> ModelData:
    c = _Checker(path, raw)
    unknown = sorted(set(raw) - _OFFICIAL_KEYS - _KNOWN_UNUSED)
    if unknown:
        warnings.warn(f"{path}: ignoring keys smplcore does not know: {unknown}", stacklevel=3)

    v_template = c.get("v_template")
    c.expect("v_template", v_template, (None, 3))
    num_verts = v_template.shape[0]
    kintree = c.get("kintree_table")
    c.expect("kintree_table", kintree, (2, None))
    num_joints = kintree.shape[1]
    model_type = _infer_model_type(path, num_joints, model_type or model_type_from_name(path))
    spec = get_spec(model_type)
    if spec.num_vertices is not None and num_verts != spec.num_vertices:
        raise ModelFileError(
            path,
            f"expected shape ({spec.num_vertices}, 3) for a {spec.display_name} model, found {v_template.shape}",
            key="v_template",
        )
    vshape = f" [V={num_verts} from v_template]"
    jshape = f" [J={num_joints} from kintree_table]"

    faces = c.expect("f", c.get("f"), (None, 3))
    _check_faces(path, faces, num_verts)
    shapedirs = c.get("shapedirs")
    if shapedirs.ndim == 2:
        shapedirs = shapedirs[:, :, None]
    c.expect("shapedirs", shapedirs, (num_verts, 3, None), vshape)
    posedirs = c.expect("posedirs", c.get("posedirs"), (num_verts, 3, 9 * (num_joints - 1)), vshape + jshape)
    J_regressor = c.expect("J_regressor", c.get("J_regressor"), (num_joints, num_verts), vshape + jshape)
    weights = c.expect("weights", c.get("weights"), (num_verts, num_joints), vshape + jshape)

    exprdirs = None
    if spec.has_expression:
        total = shapedirs.shape[-1]
        if total >= spec.shape_space_dim + spec.expression_space_dim:
            split, stop = spec.shape_space_dim, spec.shape_space_dim + spec.expression_space_dim
        else:  # older layout: 10 shape + 10 expression components
            split, stop = 10, min(total, 20)
        shapedirs, exprdirs = shapedirs[:, :, :split], shapedirs[:, :, split:stop]

    hands: dict[str, np.ndarray | None] = {}
    if model_type in ("smplh", "smplx"):
        for side, suffix in (("left", "l"), ("right", "r")):
            comps = c.get(f"hands_components{suffix}", required=False)
            mean = c.get(f"hands_mean{suffix}", required=False)
            hands[f"hands_components_{side}"] = (
                None if comps is None else c.expect(f"hands_components{suffix}", comps, (None, 45))
            )
            hands[f"hands_mean_{side}"] = (
                None if mean is None else c.expect(f"hands_mean{suffix}", mean.reshape(-1), (45,))
            )
    side = None
    if model_type == "mano":
        side = gender if gender in ("left", "right") else (gender_from_name(path) or "right")
        if side not in ("left", "right"):
            side = "right"
        comps = c.expect("hands_components", c.get("hands_components"), (None, 45))
        mean = c.expect("hands_mean", c.get("hands_mean").reshape(-1), (45,))
        hands[f"hands_components_{side}"], hands[f"hands_mean_{side}"] = comps, mean

    landmarks = _official_landmarks(path, c, model_type, faces.shape[0])
    if side is not None:
        gender = side
    elif gender is None:
        gender = gender_from_name(path) or ("generic" if model_type == "flame" else "neutral")
    return ModelData(
        model_type=model_type,
        gender=gender,
        v_template=v_template,
        faces=faces.astype(np.int64),
        shapedirs=shapedirs,
        posedirs=posedirs,
        J_regressor=J_regressor,
        weights=weights,
        parents=_parents_from_kintree(kintree),
        exprdirs=exprdirs,
        joint_names=spec.joint_names,
        source=str(path),
        **hands,
        **landmarks,
    )


def _official_landmarks(path: Path, c: _Checker, model_type: str, num_faces: int) -> dict[str, np.ndarray]:
    """Static and dynamic landmarks: inside SMPL-X files, in embedding files next to FLAME files."""
    out: dict[str, np.ndarray] = {}
    if model_type == "smplx":
        sources = [(c, "lmk_faces_idx", "lmk_bary_coords", "dynamic_lmk_faces_idx", "dynamic_lmk_bary_coords")]
    elif model_type == "flame":
        sources = []
        static = path.parent / "flame_static_embedding.pkl"
        dynamic = path.parent / "flame_dynamic_embedding.npy"
        if static.exists():
            sources.append((_Checker(static, read_container(static)), "lmk_face_idx", "lmk_b_coords", None, None))
        if dynamic.exists():
            sources.append((_Checker(dynamic, read_container(dynamic)), None, None, "lmk_face_idx", "lmk_b_coords"))
    else:
        return out
    for checker, s_idx, s_bary, d_idx, d_bary in sources:
        if s_idx:
            idx = checker.expect(s_idx, checker.get(s_idx).reshape(-1), (None,))
            bary = checker.expect(s_bary, checker.get(s_bary), (idx.shape[0], 3))
            _check_index(checker.path, s_idx, idx, num_faces)
            out["lmk_faces_idx"], out["lmk_bary_coords"] = idx.astype(np.int64), bary
        if d_idx:
            idx = checker.get(d_idx, required=model_type == "flame")
            if idx is None:
                continue
            idx = checker.expect(d_idx, idx, (79, None))
            bary = checker.expect(d_bary, checker.get(d_bary), (79, idx.shape[1], 3))
            _check_index(checker.path, d_idx, idx, num_faces)
            out["dynamic_lmk_faces_idx"], out["dynamic_lmk_bary_coords"] = idx.astype(np.int64), bary
    return out


def _check_faces(path: Path, faces: np.ndarray, num_verts: int) -> None:
    if faces.dtype.kind not in "iu":
        raise ModelFileError(path, f"expected integer vertex indices, found dtype {faces.dtype}", key="f")
    _check_index(path, "f", faces, num_verts)


def _check_index(path: Path, key: str, index: np.ndarray, size: int) -> None:
    if index.size and (index.min() < 0 or index.max() >= size):
        raise ModelFileError(path, f"indices must lie in [0, {size}), found [{index.min()}, {index.max()}]", key=key)


def _from_smplcore_npz(path: Path, raw: dict[str, Any], model_type: str | None) -> ModelData:
    c = _Checker(path, raw)
    tag = str(raw["format"])
    if tag != FORMAT_TAG:
        raise ModelFileError(
            path, f"unsupported smplcore format {tag!r} (this version reads {FORMAT_TAG!r})", key="format"
        )
    missing = sorted(_OURS_REQUIRED - set(raw))
    if missing:
        raise ModelFileError(path, f"missing key(s) {missing}", key=missing[0])
    extra = sorted(set(raw) - _OURS_REQUIRED - _OURS_OPTIONAL)
    if extra:
        raise ModelFileError(path, f"unknown key(s) {extra} in a smplcore model file", key=extra[0])
    stored_type = str(raw["model_type"])
    if stored_type not in MODEL_TYPES:
        raise ModelFileError(path, f"unknown model type {stored_type!r}", key="model_type")
    if model_type is not None and get_spec(model_type).model_type != stored_type:
        raise ModelFileError(
            path, f"holds a {stored_type!r} model, but model_type={model_type!r} was asked", key="model_type"
        )
    v = c.expect("v_template", c.get("v_template"), (None, 3))
    parents = c.expect("parents", c.get("parents"), (None,)).astype(np.int64)
    nv, nj = v.shape[0], parents.shape[0]
    vj = f" [V={nv}, J={nj}]"
    faces = c.expect("faces", c.get("faces"), (None, 3))
    _check_faces(path, faces, nv)
    arrays: dict[str, Any] = dict(
        v_template=v,
        faces=faces.astype(np.int64),
        parents=parents,
        shapedirs=c.expect("shapedirs", c.get("shapedirs"), (nv, 3, None), vj),
        J_regressor=c.expect("J_regressor", c.get("J_regressor"), (nj, nv), vj),
        weights=c.expect("weights", c.get("weights"), (nv, nj), vj),
    )
    optional_shapes = {
        "posedirs": (nv, 3, 9 * (nj - 1)),
        "exprdirs": (nv, 3, None),
        "hands_components_left": (None, 45),
        "hands_components_right": (None, 45),
        "hands_mean_left": (45,),
        "hands_mean_right": (45,),
        "lmk_faces_idx": (None,),
        "lmk_bary_coords": (None, 3),
        "dynamic_lmk_faces_idx": (79, None),
        "dynamic_lmk_bary_coords": (79, None, 3),
    }
    for key, shape in optional_shapes.items():
        value = c.get(key, required=False)
        arrays[key] = None if value is None else c.expect(key, value, shape, vj)
    for key in ("lmk_faces_idx", "dynamic_lmk_faces_idx"):
        if arrays[key] is not None:
            _check_index(path, key, arrays[key], faces.shape[0])
            arrays[key] = arrays[key].astype(np.int64)
    names = {key: tuple(str(s) for s in raw[key]) for key in ("joint_names", "extra_joint_names") if key in raw}
    extra_ids = tuple(int(i) for i in raw.get("extra_joint_vertex_ids", ()))
    if len(extra_ids) != len(names.get("extra_joint_names", ())):
        raise ModelFileError(
            path, "extra_joint_names and extra_joint_vertex_ids differ in length", key="extra_joint_vertex_ids"
        )
    if extra_ids:
        _check_index(path, "extra_joint_vertex_ids", np.asarray(extra_ids), nv)
    return ModelData(
        model_type=stored_type,
        gender=str(raw["gender"]),
        source=str(path),
        joint_names=names.get("joint_names"),
        extra_joint_names=names.get("extra_joint_names", ()),
        extra_joint_vertex_ids=extra_ids,
        **arrays,
    )
