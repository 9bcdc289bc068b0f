"""VPoser v2 as a pose prior: the torch-free checkpoint reader, the NumPy network against a torch
reference with the same random weights, the prior in fit_keypoints, errors naming the file and key."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import smplcore
from fakes_fit2d import CAMERA, natural_poses, scene
from fakes_vposer import HIDDEN, LATENT, reference, state_arrays, write_checkpoint, write_folder
from smplcore import fit
from smplcore.errors import ModelFileError, ShapeError
from smplcore.io import load_torch_file

torch = pytest.importorskip("torch")  # to write the fake checkpoints; reading them needs no torch


@pytest.fixture(scope="module")
def net():
    return reference(seed=0)


@pytest.fixture(scope="module")
def ckpt(net, tmp_path_factory):
    return write_checkpoint(tmp_path_factory.mktemp("vposer") / "V02_05_epoch=13_val_loss=0.03.ckpt", net)


@pytest.fixture(scope="module")
def prior(ckpt):
    return fit.VPoserPrior.load(ckpt)


@pytest.fixture(scope="module")
def open_model():
    return smplcore.BodyModel(model_type="open", dtype=np.float64)


# -- the checkpoint reader -----------------------------------------------------------------------------


def test_lightning_checkpoint_is_read_without_running_its_objects(ckpt, net):
    data = load_torch_file(ckpt)
    assert not ckpt.with_suffix(".ran").exists()  # the hyper-parameters' __reduce__ (open a file) never ran
    assert data["epoch"] == 13 and data["pytorch-lightning_version"] == "1.2.0"
    weights = data["state_dict"]
    for key, value in state_arrays(net).items():
        np.testing.assert_array_equal(weights[f"vp_model.{key}"], value)
    assert weights["vp_model.encoder_net.1.num_batches_tracked"].dtype == np.int64
    assert "Opaque" in type(data["hyper_parameters"]).__mro__[1].__name__  # a placeholder, never constructed
    assert data["optimizer_states"][0]["param_groups"][0]["lr"] == pytest.approx(1e-3)


def test_tensors_keep_strides_offsets_shared_storage_and_dtypes(tmp_path):
    base = torch.arange(24, dtype=torch.float64).reshape(4, 6)
    values = {
        "transposed": base.t(),
        "sliced": base[1:3, 2:5],
        "same_storage": base,
        "half": torch.tensor([1.5, -2.0], dtype=torch.float16),
        "bf16": torch.tensor([1.5, -2.0], dtype=torch.bfloat16),
        "long": torch.tensor([[1, 2]], dtype=torch.int64),
        "flag": torch.tensor([True, False]),
        "scalar": torch.tensor(3.25),
        "parameter": torch.nn.Parameter(torch.ones(2, 2)),
        "empty": torch.zeros(0, 3),
    }
    path = tmp_path / "t.pt"
    torch.save(values, path)
    data = load_torch_file(path)
    for key, value in values.items():
        expected = value.detach().float().numpy() if key == "bf16" else value.detach().numpy()
        np.testing.assert_array_equal(data[key], expected)
        assert data[key].shape == tuple(value.shape)


def _torch_zip(path: Path, pickled: bytes, storages: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as archive:
        archive.writestr("archive/data.pkl", pickled)
        archive.writestr("archive/byteorder", "little")
        for key, raw in storages.items():
            archive.writestr(f"archive/data/{key}", raw)
    return path


def _text(value: str) -> bytes:
    return b"X" + len(value.encode()).to_bytes(4, "little") + value.encode()


def _tensor_pickle(numel: int, offset: int, size: tuple[int, ...], stride: tuple[int, ...]) -> bytes:
    """A hand-written pickle of ``_rebuild_tensor_v2`` on FloatStorage '0' of ``numel`` elements."""

    def ints(values):
        return b"(" + b"".join(b"K" + bytes([v]) for v in values) + b"t"

    storage = b"(" + _text("storage") + b"ctorch\nFloatStorage\n" + _text("0") + _text("cpu") + b"K" + bytes([numel])
    return (
        b"\x80\x02ctorch._utils\n_rebuild_tensor_v2\n("
        + storage
        + b"tQ"
        + b"K"
        + bytes([offset])
        + ints(size)
        + ints(stride)
        + b"\x89}t"
        + b"R."
    )


def test_a_tensor_outside_its_storage_is_refused(tmp_path):
    raw = np.arange(6, dtype="<f4").tobytes()
    ok = load_torch_file(_torch_zip(tmp_path / "ok.pt", _tensor_pickle(6, 1, (2, 2), (2, 1)), {"0": raw}))
    np.testing.assert_array_equal(ok, [[1.0, 2.0], [3.0, 4.0]])
    with pytest.raises(ModelFileError, match=r"bad\.pt.*reaches element 6"):
        load_torch_file(_torch_zip(tmp_path / "bad.pt", _tensor_pickle(6, 3, (2, 2), (2, 1)), {"0": raw}))
    with pytest.raises(ModelFileError, match=r"short\.pt.*data/0.*holds 20 bytes"):
        load_torch_file(_torch_zip(tmp_path / "short.pt", _tensor_pickle(6, 0, (2,), (1,)), {"0": raw[:20]}))


def test_calls_to_unknown_functions_become_inert_placeholders(tmp_path):
    marker = tmp_path / "ran"
    pickled = b"\x80\x02cbuiltins\nopen\n(" + _text(str(marker)) + _text("w") + b"tR."  # open(marker, "w")
    value = load_torch_file(_torch_zip(tmp_path / "evil.pt", pickled, {}))
    assert not marker.exists() and repr(value) == "<opaque builtins.open>"


def test_legacy_and_foreign_files_are_refused_by_name(tmp_path):
    legacy = tmp_path / "legacy.pt"
    torch.save({"a": torch.ones(2)}, legacy, _use_new_zipfile_serialization=False)
    with pytest.raises(ModelFileError, match=r"legacy\.pt.*legacy \(torch < 1.6\) format"):
        load_torch_file(legacy)
    text = tmp_path / "notes.ckpt"
    text.write_text("hello")
    with pytest.raises(ModelFileError, match=r"notes\.ckpt.*not a PyTorch checkpoint"):
        load_torch_file(text)
    plain = tmp_path / "plain.zip"
    with zipfile.ZipFile(plain, "w") as archive:
        archive.writestr("readme.txt", "no pickle here")
    with pytest.raises(ModelFileError, match=r"plain\.zip.*data\.pkl"):
        load_torch_file(plain)


def test_the_reader_needs_no_torch(ckpt):
    code = (
        "import sys; sys.modules['torch'] = None\n"  # any import of torch fails
        "from smplcore.fit import VPoserPrior\n"
        f"p = VPoserPrior.load({str(ckpt)!r})\n"
        "print(p.encode([[0.1] * 63]).shape, 'torch' in sys.modules and sys.modules['torch'] is not None)\n"
    )
    env = dict(os.environ, PYTHONPATH=str(Path(smplcore.__file__).parents[1]))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "(1, 32) False"


# -- the network ---------------------------------------------------------------------------------------


def test_encoder_mean_matches_the_torch_reference(net, prior):
    pose = np.random.default_rng(1).normal(0, 0.4, (16, 63))
    with torch.no_grad():
        expected = net.encode(torch.as_tensor(pose, dtype=torch.float32)).numpy()
    got = prior.encode(pose)
    assert got.shape == (16, LATENT) and prior.enc_in.shape == (HIDDEN, 63)
    np.testing.assert_allclose(got, expected, atol=1e-5)
    assert np.abs(expected).max() > 0.05  # not trivially zero


def test_decoder_matches_the_torch_reference(net, prior):
    from scipy.spatial.transform import Rotation

    z = np.random.default_rng(2).normal(0, 1, (8, LATENT))
    with torch.no_grad():
        expected = net.decode_rotations(torch.as_tensor(z, dtype=torch.float32)).numpy()
    rot = prior.decode_rotations(z)
    np.testing.assert_allclose(rot, expected, atol=1e-5)
    np.testing.assert_allclose(rot @ np.swapaxes(rot, -1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)
    pose = prior.decode(z)
    assert pose.shape == (8, 63) and np.linalg.norm(pose.reshape(-1, 3), axis=1).max() <= np.pi + 1e-9
    np.testing.assert_allclose(
        Rotation.from_rotvec(pose.reshape(-1, 3)).as_matrix(), expected.reshape(-1, 3, 3), atol=1e-5
    )


def test_residual_jacobian_matches_finite_differences(prior):
    pose = np.random.default_rng(3).normal(0, 0.3, (3, 63))
    mean, jac = prior.residuals(pose)
    np.testing.assert_allclose(mean, prior.encode(pose), atol=1e-12)
    eps = 1e-6
    num = np.stack([(prior.encode(pose + eps * e) - prior.encode(pose - eps * e)) / (2 * eps) for e in np.eye(63)], -1)
    np.testing.assert_allclose(jac, num, atol=1e-6)


@pytest.mark.parametrize("layout", ["state_dict_pt", "folder", "npz", "arrays"])
def test_every_layout_gives_the_same_prior(layout, net, prior, tmp_path):
    if layout == "state_dict_pt":
        path = tmp_path / "vposer.pt"
        torch.save(net.state_dict(), path)
        other = fit.VPoserPrior.load(path)
    elif layout == "folder":
        other = fit.VPoserPrior.load(write_folder(tmp_path / "V02_05", net))
        assert not (tmp_path / "V02_05" / "ran").exists()
    elif layout == "npz":
        np.savez(tmp_path / "vposer.npz", **state_arrays(net))
        other = fit.VPoserPrior.load(tmp_path / "vposer.npz")
    else:
        other = fit.VPoserPrior.from_state_dict(dict(net.state_dict()))  # torch tensors
    pose = np.random.default_rng(4).normal(0, 0.3, (2, 63))
    np.testing.assert_allclose(other.encode(pose), prior.encode(pose), atol=1e-12)


def test_wrong_checkpoints_are_named_with_the_key(net, tmp_path):
    arrays = {f"vp_model.{k}": v for k, v in state_arrays(net).items()}
    missing = dict(arrays)
    del missing["vp_model.decoder_net.3.bias"]
    np.savez(tmp_path / "missing.npz", **missing)
    with pytest.raises(ModelFileError, match=r"missing\.npz \[key 'vp_model\.decoder_net\.3\.bias'\]: missing"):
        fit.VPoserPrior.load(tmp_path / "missing.npz")
    bad = dict(arrays)
    bad["vp_model.decoder_net.5.weight"] = np.zeros((120, HIDDEN), np.float32)
    np.savez(tmp_path / "shape.npz", **bad)
    with pytest.raises(
        ModelFileError, match=r"decoder_net\.5\.weight.*expected shape \(126, 512\), found \(120, 512\)"
    ):
        fit.VPoserPrior.load(tmp_path / "shape.npz")
    torch.save({"bodyprior_enc_bn1.weight": torch.ones(63)}, tmp_path / "TR00_E096.pt")
    with pytest.raises(ModelFileError, match=r"TR00_E096\.pt.*VPoser v1.*not supported"):
        fit.VPoserPrior.load(tmp_path / "TR00_E096.pt")
    torch.save([torch.ones(2)], tmp_path / "list.ckpt")
    with pytest.raises(ModelFileError, match=r"list\.ckpt.*state_dict"):
        fit.VPoserPrior.load(tmp_path / "list.ckpt")
    (tmp_path / "empty" / "snapshots").mkdir(parents=True)
    with pytest.raises(ModelFileError, match=r"empty.*no VPoser checkpoint"):
        fit.VPoserPrior.load(tmp_path / "empty")
    with pytest.raises(ModelFileError, match=r"nowhere.*no such file or folder"):
        fit.VPoserPrior.load(tmp_path / "nowhere")
    nan = dict(arrays)
    nan["vp_model.encoder_net.2.bias"] = np.full(HIDDEN, np.nan, np.float32)
    with pytest.raises(ModelFileError, match=r"encoder_net\.2\.bias.*NaN"):
        fit.VPoserPrior.from_state_dict(nan, "nan-weights")


def test_pose_shapes_are_checked(prior):
    with pytest.raises(ShapeError, match="pose.*63"):
        prior.encode(np.zeros((2, 69)))
    with pytest.raises(ShapeError, match="z.*32"):
        prior.decode(np.zeros((2, 16)))


# -- in fit_keypoints ----------------------------------------------------------------------------------


def test_fit_with_vposer_lowers_the_prior_term(open_model, ckpt, prior):
    rng = np.random.default_rng(6)
    params = natural_poses(open_model, 3, rng)
    keypoints, exact, _ = scene(open_model, params, rng, noise=1.0)
    plain = fit.fit_keypoints(open_model, keypoints, camera=CAMERA)
    weight = 1e-2
    with_prior = fit.fit_keypoints(open_model, keypoints, camera=CAMERA, vposer=ckpt, vposer_weight=weight)

    def term(r):
        return np.sum(prior.encode(np.asarray(r.params["body_pose"])[:, :63]) ** 2, axis=1)

    # every body lower, the batch clearly so (the upright prior of the plain fit already lowers it somewhat)
    assert np.all(term(with_prior) < term(plain)), (term(with_prior), term(plain))
    assert term(with_prior).mean() < 0.9 * term(plain).mean(), (term(with_prior), term(plain))
    assert np.all(with_prior.reprojection_error < 4.0)  # the data still fit (pixels)
    again = fit.fit_keypoints(open_model, keypoints, camera=CAMERA, vposer=prior, vposer_weight=weight)
    np.testing.assert_allclose(again.params["body_pose"], with_prior.params["body_pose"], atol=1e-9)


def test_the_prior_term_decreases_along_the_solver(open_model, prior):
    from smplcore.fit import keypoints2d, reprojection
    from smplcore.fit.body import FitBody

    body = FitBody.from_model(open_model)
    kmap = keypoints2d.keypoint_map(body, open_model, "coco17")
    width = body.num_pose + body.num_coeffs + 3
    free = np.zeros(width, bool)
    free[3:72] = True  # body pose only
    keypoints = np.zeros((2, 17, 3))  # no data: the prior alone
    terms = keypoints2d._terms(
        body,
        kmap,
        CAMERA,
        keypoints[..., :2],
        keypoints[..., 2],
        np.full(2, 0.004),
        100.0,
        free,
        np.zeros(width, bool),
        vposer=prior,
        vposer_prior=1.0,
    )
    x = np.zeros((2, width))
    x[:, 3:72] = np.random.default_rng(7).normal(0, 0.5, (2, 69))
    costs = [reprojection.evaluate(body, terms, x, system=False)[0]]
    for _ in range(4):
        x = reprojection.solve_flat(body, terms, x, max_iter=1, tol=0.0)[0]
        costs.append(reprojection.evaluate(body, terms, x, system=False)[0])
    costs = np.array(costs)
    assert np.all(np.diff(costs, axis=0) <= 1e-15) and np.all(costs[-1] < 0.5 * costs[0]), costs


def test_objective_gradient_with_vposer_matches_finite_differences(open_model, prior):
    from smplcore.fit import keypoints2d, reprojection
    from smplcore.fit.body import FitBody

    body = FitBody.from_model(open_model)
    kmap = keypoints2d.keypoint_map(body, open_model, "coco17")
    width = body.num_pose + body.num_coeffs + 3
    rng = np.random.default_rng(8)
    params = natural_poses(open_model, 2, rng)
    keypoints, _, _ = scene(open_model, params, rng)
    terms = keypoints2d._terms(
        body,
        kmap,
        CAMERA,
        keypoints[..., :2],
        keypoints[..., 2],
        np.full(2, 0.004),
        50.0,
        np.ones(width, bool),
        np.zeros(width, bool),
        vposer=prior,
        vposer_prior=1e-3,
    )
    x = np.concatenate([params["global_orient"], params["body_pose"], params["betas"], params["transl"]], 1)
    _, _, grad = reprojection.evaluate(body, terms, x)
    eps = 1e-6
    num = np.empty_like(grad)
    for i in range(width):
        step = np.zeros(width)
        step[i] = eps
        up = reprojection.evaluate(body, terms, x + step, system=False)[0]
        down = reprojection.evaluate(body, terms, x - step, system=False)[0]
        num[:, i] = (up - down) / (4 * eps)  # cost = Σ r², grad = Jᵀ r
    np.testing.assert_allclose(grad, num, rtol=1e-4, atol=1e-8)


def test_smplx_bodies_use_all_63_values(fake_models, prior):
    model = smplcore.BodyModel(fake_models["smplx_neutral_npz"], model_type="smplx", dtype=np.float64)
    rng = np.random.default_rng(9)
    params = {
        "global_orient": np.array([[np.pi, 0.1, 0.0]]),
        "body_pose": rng.normal(0, 0.05, (1, 63)),
        "transl": np.array([[0.0, 0.1, 4.0]]),
    }
    keypoints, _, _ = scene(model, params, rng, noise=0.5)
    r = fit.fit_keypoints(model, keypoints, camera=CAMERA, min_points=5, vposer=prior)
    assert np.asarray(r.params["body_pose"]).shape == (1, 63) and np.isfinite(r.reprojection_error).all()


def test_vposer_argument_errors(open_model, tmp_path):
    rng = np.random.default_rng(10)
    keypoints, _, _ = scene(open_model, natural_poses(open_model, 1, rng), rng)
    with pytest.raises(TypeError, match="vposer"):
        fit.fit_keypoints(open_model, keypoints, camera=CAMERA, vposer=42)
    with pytest.raises(ModelFileError, match="no such file"):
        fit.fit_keypoints(open_model, keypoints, camera=CAMERA, vposer=tmp_path / "V02_05")
