"""Turning model files (official layouts and smplcore's own .npz) into validated :class:`ModelData`."""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.errors import ModelFileError, warn
from smplcore.family.specs import MODEL_TYPE_BY_NUM_JOINTS, get_spec
from smplcore.io.checks import Checker, check_index, check_parents
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
    # a body's parameters and chumpy's derived arrays, saved with the model by SMPLify and the chumpy SMPL
    # code (``ready_arguments``): recomputed from the parameters at every call, never part of the model
    "betas",
    "pose",
    "trans",
    "v_shaped",
    "v_posed",
    "J_transformed",
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


def _with_file_uv(data: ModelData, path: Path, raw: Mapping[str, Any]) -> ModelData:
    """The UV map (``vt``, ``ft``) the file carries, checked against its faces (see :mod:`smplcore.io.uv`)."""
    from smplcore.io.uv import uv_from_file_arrays

    uv = uv_from_file_arrays(path, raw, data.faces.shape[0])
    return data.replace(**uv) if uv else data


# --------------------------------------------------------------------------------------------------


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


def _from_official(path: Path, raw: Mapping[str, Any], model_type: str | None, gender: str | None) -> ModelData:
    """ModelData from the keys of an official file (or an smplx ``data_struct``)."""
    return Checker(path, raw).run(_official, model_type, gender)


def _official(c: Checker, model_type: str | None, gender: str | None) -> ModelData:
    path, raw = c.path, c.raw
    unknown = sorted(set(raw) - _OFFICIAL_KEYS - _KNOWN_UNUSED)
    if unknown:
        warn(f"{path}: ignoring keys smplcore does not know: {unknown}")

    v_template = c.get("v_template")
    c.expect("v_template", v_template, (None, 3))
    num_verts = v_template.shape[0]
    kintree = c.get("kintree_table")
    c.expect("kintree_table", kintree, (2, None))
    parents = check_parents(path, "kintree_table", kintree[0], root_stored=False)
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
    faces_dtype = str(faces.dtype) if faces.dtype.kind in "iu" else "int64"
    faces = check_index(path, "f", faces, num_verts)
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

    hands: dict[str, Any] = {}  # ModelData's hands_* fields: arrays or None
    if model_type in ("smplh", "smplx"):
        for side, suffix in (("left", "l"), ("right", "r")):
            # Empty arrays (some AMASS SMPL+H downloads) mean "no hand PCA", as in smplx.
            comps = _absent_if_empty(c.get(f"hands_components{suffix}", required=False))
            mean = _absent_if_empty(c.get(f"hands_mean{suffix}", required=False))
            hands[f"hands_components_{side}"] = (
                None if comps is None else c.expect(f"hands_components{suffix}", comps, (None, 45))
            )
            hands[f"hands_mean_{side}"] = (
                None if mean is None else c.expect(f"hands_mean{suffix}", mean.reshape(-1), (45,))
            )
    hand_side: str | None = None
    if model_type == "mano":
        hand_side = gender if gender in ("left", "right") else (gender_from_name(path) or "right")
        if hand_side not in ("left", "right"):
            hand_side = "right"
        comps = c.expect("hands_components", c.get("hands_components"), (None, 45))
        mean = c.expect("hands_mean", c.get("hands_mean").reshape(-1), (45,))
        hands[f"hands_components_{hand_side}"], hands[f"hands_mean_{hand_side}"] = comps, mean

    landmarks = _official_landmarks(path, c, model_type, faces.shape[0])
    if hand_side is not None:
        gender = hand_side
    elif gender is None:
        gender = gender_from_name(path) or ("generic" if model_type == "flame" else "neutral")
    return ModelData(
        model_type=model_type,
        gender=gender,
        v_template=v_template,
        faces=faces,
        faces_dtype=faces_dtype,
        shapedirs=shapedirs,
        posedirs=posedirs,
        J_regressor=J_regressor,
        weights=weights,
        parents=parents,
        exprdirs=exprdirs,
        joint_names=spec.joint_names,
        source=str(path),
        lmk_faces_idx=landmarks.get("lmk_faces_idx"),
        lmk_bary_coords=landmarks.get("lmk_bary_coords"),
        dynamic_lmk_faces_idx=landmarks.get("dynamic_lmk_faces_idx"),
        dynamic_lmk_bary_coords=landmarks.get("dynamic_lmk_bary_coords"),
        **hands,
    )


def _absent_if_empty(value: np.ndarray | None) -> np.ndarray | None:
    return None if value is None or value.size == 0 else value


def _official_landmarks(path: Path, c: Checker, model_type: str, num_faces: int) -> dict[str, np.ndarray]:
    """Static and dynamic landmarks: inside SMPL-X files, in embedding files next to FLAME files."""
    out: dict[str, np.ndarray] = {}
    # (checker, (static face key, bary key) or None, (dynamic face key, bary key) or None)
    sources: list[tuple[Checker, tuple[str, str] | None, tuple[str, str] | None]]
    if model_type == "smplx":
        sources = [(c, ("lmk_faces_idx", "lmk_bary_coords"), ("dynamic_lmk_faces_idx", "dynamic_lmk_bary_coords"))]
    elif model_type == "flame":
        sources = []
        static = path.parent / "flame_static_embedding.pkl"
        dynamic = path.parent / "flame_dynamic_embedding.npy"
        if static.exists():
            sources.append((Checker(static, read_container(static)), ("lmk_face_idx", "lmk_b_coords"), None))
        if dynamic.exists():
            sources.append((Checker(dynamic, read_container(dynamic)), None, ("lmk_face_idx", "lmk_b_coords")))
    else:
        return out
    for checker, static_keys, dynamic_keys in sources:
        if static_keys:
            s_idx, s_bary = static_keys
            idx = checker.expect(s_idx, checker.get(s_idx).reshape(-1), (None,))
            bary = checker.expect(s_bary, checker.get(s_bary), (idx.shape[0], 3))
            out["lmk_faces_idx"], out["lmk_bary_coords"] = check_index(checker.path, s_idx, idx, num_faces), bary
        if dynamic_keys:
            d_idx, d_bary = dynamic_keys
            found = checker.get(d_idx, required=model_type == "flame")
            if found is None:
                continue
            idx = checker.expect(d_idx, found, (79, None))
            bary = checker.expect(d_bary, checker.get(d_bary), (79, idx.shape[1], 3))
            idx = check_index(checker.path, d_idx, idx, num_faces)
            out["dynamic_lmk_faces_idx"], out["dynamic_lmk_bary_coords"] = idx, bary
    return out


def _from_smplcore_npz(path: Path, raw: Mapping[str, Any], model_type: str | None) -> ModelData:
    return Checker(path, raw).run(_smplcore_npz, model_type)


def _smplcore_npz(c: Checker, model_type: str | None) -> ModelData:
    path, raw = c.path, c.raw
    tag = c.text("format")
    if tag != FORMAT_TAG:
        raise c.error(f"unsupported smplcore format {tag!r} (this version reads {FORMAT_TAG!r})", "format")
    missing = sorted(_OURS_REQUIRED - set(raw))
    if missing:
        raise c.error(f"missing key(s) {missing}", missing[0])
    extra = sorted(set(raw) - _OURS_REQUIRED - _OURS_OPTIONAL)
    if extra:
        raise c.error(f"unknown key(s) {extra} in a smplcore model file", extra[0])
    stored_type = c.text("model_type")
    if stored_type not in MODEL_TYPES:
        raise c.error(f"expected one of {list(MODEL_TYPES)}, found {stored_type[:40]!r}", "model_type")
    if model_type is not None and get_spec(model_type).model_type != stored_type:
        raise c.error(f"holds a {stored_type!r} model, but model_type={model_type!r} was asked", "model_type")
    gender = c.text("gender")
    spec = get_spec(stored_type)
    v = c.expect("v_template", c.get("v_template"), (spec.num_vertices, 3), f" for a {spec.display_name} model")
    parents = c.expect("parents", c.get("parents"), (None if stored_type == "open" else spec.num_joints,))
    parents = check_parents(path, "parents", parents)
    nv, nj = v.shape[0], parents.shape[0]
    vj = f" [V={nv}, J={nj}]"
    faces = check_index(path, "faces", c.expect("faces", c.get("faces"), (None, 3)), nv)
    arrays: dict[str, Any] = dict(
        v_template=v,
        faces=faces,
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
        if key.startswith("hands_"):
            value = _absent_if_empty(value)
        arrays[key] = None if value is None else c.expect(key, value, shape, vj)
    for key in ("lmk_faces_idx", "dynamic_lmk_faces_idx"):
        if arrays[key] is not None:
            arrays[key] = check_index(path, key, arrays[key], faces.shape[0])
    joint_names = c.names("joint_names", nj) if "joint_names" in raw else None
    extra_names = c.names("extra_joint_names") if "extra_joint_names" in raw else ()
    extra_ids: tuple[int, ...] = ()
    if "extra_joint_vertex_ids" in raw:
        ids = c.expect("extra_joint_vertex_ids", c.get("extra_joint_vertex_ids"), (len(extra_names),))
        extra_ids = tuple(int(i) for i in check_index(path, "extra_joint_vertex_ids", ids, nv))
    if len(extra_ids) != len(extra_names):
        raise c.error(
            f"expected {len(extra_names)} vertex ids (one per extra joint name), found {len(extra_ids)}",
            "extra_joint_vertex_ids",
        )
    return ModelData(
        model_type=stored_type,
        gender=gender,
        source=str(path),
        joint_names=joint_names,
        extra_joint_names=extra_names,
        extra_joint_vertex_ids=extra_ids,
        **arrays,
    )


#: The reader of official arrays (a dict of the file's keys, e.g. smplx's ``data_struct``), for the front ends.
from_official_arrays = _from_official
