"""fit.convert: model-to-itself identity, official deformation-transfer files, computed and cached maps."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import scipy.sparse as sp

import smplcore
from smplcore import fit
from smplcore.errors import ModelFileError


@pytest.fixture(scope="module")
def mano(fake_models):
    return smplcore.BodyModel(fake_models["root"], model_type="mano", use_pca=False, dtype=np.float64)


def _hand_params(batch, seed):
    rng = np.random.default_rng(seed)
    return {
        "global_orient": rng.normal(0, 0.5, (batch, 3)),
        "hand_pose": rng.normal(0, 0.3, (batch, 45)),
        "betas": rng.normal(0, 1, (batch, 10)),
        "transl": rng.normal(0, 0.2, (batch, 3)),
    }


def test_model_to_itself_is_the_identity_within_a_millimetre(mano):
    params = _hand_params(2, 0)
    r = fit.convert(params, mano, mano)
    assert r.vertex_error.max() < 1e-3
    np.testing.assert_allclose(mano(**r.params).vertices, mano(**params).vertices, atol=1e-3)


def test_open_model_to_itself(fake_models):
    model = smplcore.BodyModel(model_type="open")
    params = {"body_pose": np.full((1, 69), 0.1), "betas": np.ones((1, 10))}
    r = fit.convert(params, model, model)
    assert r.vertex_error.max() < 1e-3
    assert np.abs(model(**r.params).vertices - model(**params).vertices).max() < 1e-3


def test_deformation_transfer_file_is_read_safely(mano, tmp_path):
    n = mano.setup.data.v_template.shape[0]
    rng = np.random.default_rng(1)
    perm = rng.permutation(n)
    mtx = sp.csr_matrix((np.ones(n), (np.arange(n), perm)), shape=(n, 2 * n))  # vertex half, then normals
    path = tmp_path / "mano2mano_deftrafo_setup.pkl"
    with open(path, "wb") as fh:
        pickle.dump({"mtx": mtx}, fh, protocol=2)
    corr = fit.correspondence(mano, mano, deformation_transfer=path)
    assert corr.kind == "file"
    verts = mano(**_hand_params(1, 2)).vertices
    np.testing.assert_allclose(corr.apply(verts), verts[:, perm])
    with open(tmp_path / "bad.pkl", "wb") as fh:
        pickle.dump({"mtx": sp.csr_matrix((3, 3))}, fh, protocol=2)
    with pytest.raises(ModelFileError, match="mtx"):
        fit.correspondence(mano, mano, deformation_transfer=tmp_path / "bad.pkl")


def test_computed_correspondence_is_barycentric_and_cached(fake_models, tmp_path):
    source = smplcore.BodyModel(model_type="open")
    target = smplcore.BodyModel(fake_models["root"], model_type="smpl")
    corr = fit.correspondence(source, target, cache_dir=tmp_path)
    assert corr.kind == "templates"
    assert corr.indices.shape == (target.setup.data.v_template.shape[0], 3)
    np.testing.assert_allclose(corr.weights.sum(1), 1.0)
    assert (corr.weights >= -1e-12).all()
    assert len(list((tmp_path / "correspondences").glob("*.npz"))) == 1
    again = fit.correspondence(source, target, cache_dir=tmp_path)
    assert again.kind == "templates (cached)"
    np.testing.assert_array_equal(again.indices, corr.indices)


def test_joint_fallback(mano):
    params = _hand_params(1, 3)
    r = fit.convert(params, mano, mano, method="joints", pose_prior=1e-9, shape_prior=0.0)
    assert r.joint_error.max() < 1e-4
    with pytest.raises(ValueError, match="method"):
        fit.convert(params, mano, mano, method="nearest")


def test_bad_params(mano):
    with pytest.raises(ValueError, match="params\\['hand_pose'\\]"):
        fit.convert({"hand_pose": np.full((1, 45), np.nan)}, mano, mano)


def test_converting_between_open_model_genders_fits_a_subset_and_measures_every_vertex():
    """A different shape space on the same mesh: the male model cannot reproduce the neutral body exactly.
    Fitting 2,000 spread vertices (the default) lands within a few hundredths of a millimetre of the fit
    to all of them; the error reported is over every vertex either way."""
    source = smplcore.BodyModel(model_type="open", dtype=np.float32)
    target = smplcore.BodyModel(model_type="open", gender="male", dtype=np.float32)
    rng = np.random.default_rng(5)
    params = {"body_pose": rng.normal(0, 0.2, (4, 69)), "betas": rng.normal(0, 1, (4, 10))}
    subset = fit.convert(params, source, target)
    whole = fit.convert(params, source, target, points=None)
    mapped = source(**params).vertices
    for r in (subset, whole):
        measured = np.linalg.norm(target(**r.params).vertices - mapped, axis=-1).mean(1)
        np.testing.assert_allclose(r.vertex_error, measured, rtol=1e-4)
        assert r.converged.all()
    assert 0.0005 < whole.vertex_error.mean() < 0.02  # the shape spaces differ: not zero, not far
    assert np.all(subset.vertex_error <= whole.vertex_error + 2e-4)


@pytest.mark.parametrize("protocol", [2, 4])
def test_a_full_size_smpl_to_smplx_map_reads_as_a_sparse_matrix(tmp_path, protocol):
    """The official smpl2smplx map is (10475, 2 x 6890): 144 million entries if made dense, which a model
    file's budget refuses; a deformation-transfer file's matrix stays sparse and is charged by its entries."""
    from smplcore.fit.convert import read_deformation_transfer

    rng = np.random.default_rng(6)
    rows = np.repeat(np.arange(10475), 3)
    cols = rng.integers(0, 6890, rows.size)
    weights = rng.dirichlet(np.ones(3), 10475).reshape(-1)
    mtx = sp.csc_matrix((weights, (rows, cols)), shape=(10475, 13780))
    path = tmp_path / "smpl2smplx_deftrafo_setup.pkl"
    with open(path, "wb") as fh:
        pickle.dump({"mtx": mtx}, fh, protocol=protocol)
    corr = read_deformation_transfer(path, 6890, 10475)
    verts = rng.normal(size=(2, 6890, 3))
    np.testing.assert_allclose(corr.apply(verts), np.stack([mtx[:, :6890] @ v for v in verts]), atol=1e-12)


def test_a_small_deformation_transfer_file_cannot_take_gigabytes(tmp_path):
    """A 0.5 MB file whose one row holds 6,890 weights used to widen every row's table to 6,890 columns
    (1.7 GB for 10,475 rows); each target vertex comes from a few source vertices, so wide rows are refused
    and memory stays a small multiple of the file (measured in a subprocess)."""
    import subprocess
    import sys
    import textwrap

    rows = np.concatenate([np.zeros(6890, np.int64), np.arange(1, 10475)])
    cols = np.concatenate([np.arange(6890), np.zeros(10474, np.int64)])
    mtx = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(10475, 13780))
    path = tmp_path / "wide_deftrafo_setup.pkl"
    with open(path, "wb") as fh:
        pickle.dump({"mtx": mtx}, fh, protocol=2)
    assert path.stat().st_size < 600_000
    script = textwrap.dedent(
        f"""
        import resource
        from smplcore.errors import ModelFileError
        from smplcore.fit.convert import read_deformation_transfer
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        try:
            read_deformation_transfer({str(path)!r}, 6890, 10475)
            print("read", end=" ")
        except ModelFileError as exc:
            print("refused" if "row 0" in str(exc) else "other", end=" ")
        print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) // 1024)
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    assert out[0] == "refused"
    assert int(out[1]) < 100  # MB above the interpreter with smplcore imported
