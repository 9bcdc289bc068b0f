"""Build smplcore's own keypoint regressors for the open model: src/smplcore/data/open_regressors.npz.

Every row is a fixed linear function of the open model's vertices, made from things the open
model itself names (no learned regressor, no data from SMPL, Human3.6M or any dataset):

* a skeleton joint: that joint's row of the open model's ``J_regressor`` (so on a posed mesh the
  point follows the vertices around the joint, as SPIN's regressors do);
* a surface point: one of the open model's named extra-joint vertices (nose, eyes, ears, toes,
  heels) or the top of the head (the highest vertex on the head's mid-line in the template);
* a midpoint: the mean of two such rows (OpenPose's neck and mid-hip, H36M's spine).

Run from the repository root: ``python tools/build_open_regressors.py`` (a few seconds).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import scipy.sparse as sp

import smplcore
from smplcore.keypoints import names

OUT = Path(__file__).resolve().parents[1] / "src" / "smplcore" / "data" / "open_regressors.npz"


def _rows(model: smplcore.BodyModel) -> dict[str, np.ndarray]:
    """Vocabulary name -> (V,) row for every point the conventions below use."""
    data = model.setup.data
    regressor = np.asarray(data.J_regressor, dtype=np.float64)
    num_vertices = regressor.shape[1]
    rows = {name: regressor[i] for i, name in enumerate(model.skeleton_joint_names)}

    def vertex(i: int) -> np.ndarray:
        row = np.zeros(num_vertices)
        row[int(i)] = 1.0
        return row

    for name, i in zip(data.extra_joint_names, data.extra_joint_vertex_ids, strict=True):
        rows[str(name)] = vertex(i)
    template = np.asarray(data.v_template, dtype=np.float64)
    head = np.flatnonzero(np.asarray(data.weights)[:, model.skeleton_joint_names.index("head")] > 0.9)
    mid = head[np.abs(template[head, 0]) < 0.01]
    rows["head_top"] = vertex(mid[np.argmax(template[mid, 1])])

    def mean(a: str, b: str) -> np.ndarray:
        return 0.5 * (rows[a] + rows[b])

    rows["openpose25:neck"] = mean("left_shoulder", "right_shoulder")
    rows["mid_hip"] = mean("left_hip", "right_hip")
    rows["spine_h36m"] = mean("pelvis", "neck")
    return rows


#: Per convention: which row makes each point where it is not the row of the same name.
_CHOICES = {
    "coco17": {},
    "openpose25": {"neck": "openpose25:neck"},
    "h36m17": {"spine": "spine_h36m", "thorax": "neck", "neck_nose": "head"},
}


def build(out: Path = OUT) -> dict[str, np.ndarray]:
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    rows = _rows(model)
    arrays: dict[str, np.ndarray] = {"num_vertices": np.asarray(model.setup.data.J_regressor.shape[1])}
    for convention, choices in _CHOICES.items():
        matrix = np.stack([rows[choices.get(n, n)] for n in names(convention)])
        matrix[np.abs(matrix) < 1e-9] = 0.0
        csr = sp.csr_matrix(matrix.astype(np.float32))
        arrays[f"{convention}.data"] = csr.data
        arrays[f"{convention}.indices"] = csr.indices.astype(np.int32)
        arrays[f"{convention}.indptr"] = csr.indptr.astype(np.int32)
        arrays[f"{convention}.shape"] = np.asarray(csr.shape, dtype=np.int64)
        arrays[f"{convention}.names"] = np.asarray(names(convention))
    np.savez_compressed(out, **arrays)
    return arrays


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    arrays = build(args.out)
    sizes = {k.split(".")[0]: int(arrays[k].size) for k in arrays if k.endswith(".data")}
    print(f"wrote {args.out} ({args.out.stat().st_size} bytes); non-zero weights per regressor: {sizes}")


if __name__ == "__main__":
    main()
