"""``install_as_smplx()``: unmodified smplx code (a SPIN-style SMPL subclass) runs on smplcore."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("smplx")

SRC = Path(__file__).resolve().parents[1] / "src"

# Written the way SPIN, VIBE, PARE and others extend smplx: a subclass of smplx.SMPL adding an extra
# joint regressor, passing a legacy keyword (get_skin) and re-mapping joints with smplx.lbs.
USER_CODE = textwrap.dedent("""
    import numpy as np
    import torch
    import smplx
    from smplx import SMPL as _SMPL
    from smplx.utils import ModelOutput
    from smplx.lbs import vertices2joints, batch_rodrigues

    class SMPL(_SMPL):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            rng = np.random.default_rng(0)
            extra = rng.random((9, 6890)) * (rng.random((9, 6890)) > 0.995)
            extra /= extra.sum(axis=1, keepdims=True)
            self.register_buffer("J_regressor_extra", torch.tensor(extra, dtype=torch.float32))
            self.joint_map = torch.tensor([24, 12, 17, 19, 21, 16, 18, 20, 0, 2, 5, 8, 1, 4, 7, 45, 46, 47, 48, 49])

        def forward(self, *args, **kwargs):
            kwargs["get_skin"] = True
            out = super().forward(*args, **kwargs)
            extra_joints = vertices2joints(self.J_regressor_extra, out.vertices)
            joints = torch.cat([out.joints, extra_joints], dim=1)[:, self.joint_map, :]
            return ModelOutput(vertices=out.vertices, global_orient=out.global_orient, joints=joints,
                               full_pose=out.full_pose)

    model = SMPL(MODEL_DIR, batch_size=4, create_transl=False)
    torch.manual_seed(0)
    rotmats = batch_rodrigues(torch.randn(4 * 24, 3) * 0.4).reshape(4, 24, 3, 3)
    with torch.no_grad():
        out = model(betas=torch.randn(4, 10), body_pose=rotmats[:, 1:], global_orient=rotmats[:, :1],
                    pose2rot=False)
    np.savez(OUT, vertices=out.vertices.numpy(), joints=out.joints.numpy(), module=type(model).__mro__[1].__module__)
""")


def _run(code: str, env: dict) -> None:
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=180)
    assert result.returncode == 0, result.stderr


def test_smplx_subclass_runs_on_smplcore_like_on_smplx(fake_models, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(SRC))
    model_dir = str(fake_models["smpl_neutral_pkl"].parent)
    params = f"MODEL_DIR = {model_dir!r}\n"
    _run(params + f"OUT = {str(tmp_path / 'ref.npz')!r}\n" + USER_CODE, env)
    install = "import smplcore\nsmplcore.install_as_smplx()\n"
    _run(install + params + f"OUT = {str(tmp_path / 'ours.npz')!r}\n" + USER_CODE, env)
    ref, ours = np.load(tmp_path / "ref.npz"), np.load(tmp_path / "ours.npz")
    assert str(ref["module"]) == "smplx.body_models" and str(ours["module"]) == "smplcore.torch.smpl"
    assert ours["joints"].shape == (4, 20, 3)
    np.testing.assert_allclose(ours["vertices"], ref["vertices"], atol=1e-5)
    np.testing.assert_allclose(ours["joints"], ref["joints"], atol=1e-5)


def test_install_as_smplx_registers_the_submodules():
    code = textwrap.dedent("""
        import smplcore
        smplcore.install_as_smplx()
        import smplx, smplx.lbs, smplx.utils, smplx.vertex_ids, smplx.joint_names, smplx.body_models
        from smplx.lbs import lbs, blend_shapes, vertices2joints, batch_rodrigues, batch_rigid_transform
        from smplx.lbs import vertices2landmarks, find_dynamic_lmk_idx_and_bcoords
        from smplx.utils import to_tensor, to_np, Struct, SMPLXOutput
        from smplx.vertex_joint_selector import VertexJointSelector
        from smplx.body_models import VertexJointSelector as Selector, lbs as body_models_lbs, VERTEX_IDS
        assert Selector is VertexJointSelector and smplx.vertex_joint_selector.VertexJointSelector is Selector
        assert smplx.SMPLX is smplcore.SMPLX and smplx.lbs.__name__ == "smplcore.smplx_compat.lbs"
        import smplcore.lbs
        assert smplcore.lbs is smplx.lbs
        assert len(smplx.joint_names.JOINT_NAMES) == 144 and smplx.vertex_ids.vertex_ids["smplx"]["nose"] == 9120
        print("ok")
    """)
    env = dict(os.environ, PYTHONPATH=str(SRC))
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr


def test_lbs_functions_match_smplx_lbs(fake_models):
    import torch
    from smplx import lbs as ref

    from smplcore import lbs as ours
    from smplcore.io import load_model

    data = load_model(fake_models["smpl_male_pkl"])
    args = [
        torch.tensor(np.asarray(a), dtype=torch.float32)
        for a in (data.v_template, data.shapedirs, data.posedirs.reshape(-1, 207).T, data.J_regressor, data.weights)
    ]
    parents = torch.tensor(data.parents)
    torch.manual_seed(0)
    betas, pose = torch.randn(2, 10), torch.randn(2, 72) * 0.3
    v_ref, j_ref = ref.lbs(betas, pose, args[0], args[1], args[2], args[3], parents, args[4])
    v, j = ours.lbs(betas, pose, args[0], args[1], args[2], args[3], parents, args[4])
    assert (v - v_ref).abs().max() < 1e-5 and (j - j_ref).abs().max() < 1e-5
    rot = ref.batch_rodrigues(pose.reshape(-1, 3)).reshape(2, 24, 3, 3)
    joints = ref.vertices2joints(args[3], args[0][None].expand(2, -1, -1))
    pj_ref, a_ref = ref.batch_rigid_transform(rot, joints, parents)
    pj, a = ours.batch_rigid_transform(rot, joints, parents)
    assert (pj - pj_ref).abs().max() < 1e-5 and (a - a_ref).abs().max() < 1e-5
    assert (ours.batch_rodrigues(pose.reshape(-1, 3)).reshape(2, 24, 3, 3) - rot).abs().max() < 1e-6
