"""Max |error| (metres) of every path against the oracle (tests/oracle.py), per model: vertices and joints.

python bench/oracle_errors.py        # fake official files (tests/fakes.py) and the open model, float32
"""

from __future__ import annotations

import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import fakes  # noqa: E402
import smplcore  # noqa: E402
from test_oracle import _expected, _model_args, _params  # noqa: E402

MODELS = [
    ("smpl_neutral_pkl", {}),
    ("smplh_neutral_pkl", {"use_pca": True}),
    ("smplx_neutral_npz", {"use_face_contour": True}),
    ("mano_left_pkl", {}),
    ("flame_neutral_pkl", {"use_face_contour": True}),
    ("open", {}),
]


def main() -> None:
    warnings.filterwarnings("ignore")
    files = fakes.write_all(Path(tempfile.mkdtemp()) / "models")
    print("| model | path | max |Δ vertices| | max |Δ joints| |\n|---|---|---|---|")
    for key, options in MODELS:
        args, kwargs = _model_args(files, key, options)
        body = smplcore.BodyModel(*args, **kwargs)
        params = _params(body.setup, 8, seed=0)
        ev, ej = _expected(body.setup, params, kwargs)
        rows = []
        for kernel in ("auto", "reference"):
            out = smplcore.BodyModel(*args, kernel=kernel, **kwargs)(**params)
            rows.append((f"NumPy {kernel}", out.vertices, out.joints))
        module = smplcore.create(*args, **kwargs)
        t = {k: torch.tensor(v, dtype=torch.float32) for k, v in params.items()}
        with torch.no_grad():
            rows.append(("torch blocked", *(x.numpy() for x in (module(**t).vertices, module(**t).joints))))
            rows.append(
                (
                    "torch reference",
                    *(x.numpy() for x in (lambda o: (o.vertices, o.joints))(module(kernel="reference", **t))),
                )
            )
            rows.append(("torch joints only", None, module(return_verts=False, **t).joints.numpy()))
            compiled = torch.compile(module, fullgraph=True, backend="aot_eager")
            o = compiled(**t)
            rows.append(("torch.compile (graph)", o.vertices.numpy(), o.joints.numpy()))
        g = {k: v.clone().requires_grad_(True) for k, v in t.items()}
        o = module(**g)
        rows.append(("torch autograd", o.vertices.detach().numpy(), o.joints.detach().numpy()))
        torch._dynamo.reset()
        name = key.split("_")[0]
        for label, v, j in rows:
            dv = "—" if v is None else f"{np.abs(v - ev).max():.1e}"
            print(f"| {name} | {label} | {dv} | {np.abs(j - ej).max():.1e} |")


if __name__ == "__main__":
    main()
