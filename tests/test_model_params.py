"""The one coefficient rule (smplcore.model.params), the call's plan (engine.kernels.select.plan) and the one
error base class."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import smplcore
from smplcore.engine.kernels.select import Plan, plan
from smplcore.errors import ModelFileError, ShapeError, SmplcoreError
from smplcore.model.params import fit_width

torch = pytest.importorskip("torch")


@pytest.mark.parametrize("make", [np.asarray, torch.as_tensor])
def test_fewer_coefficients_are_zero_padded(make):
    value = make(np.array([[1.0, 2.0], [3.0, 4.0]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = fit_width("betas", value, 4, from_file=False)
    np.testing.assert_array_equal(np.asarray(out), [[1, 2, 0, 0], [3, 4, 0, 0]])
    assert type(out) is type(value)


def test_more_coefficients_in_a_call_are_an_error_naming_the_option():
    with pytest.raises(ShapeError, match=r"betas: expected shape \(B, <=10\), got \(1, 16\).*num_betas=16"):
        fit_width("betas", np.zeros((1, 16)), 10, from_file=False)


def test_more_coefficients_from_a_file_are_dropped_with_a_warning_and_a_note():
    notes: list[str] = []
    value = np.zeros((2, 12))
    value[1, 11] = -0.5
    with pytest.warns(UserWarning, match=r"expression: the input has 12 coefficients but the model takes 10; "):
        out = fit_width("expression", value, 10, notes=notes)
    assert out.shape == (2, 10) and len(notes) == 1 and "0.5" in notes[0] and "num_expression_coeffs=12" in notes[0]
    with warnings.catch_warnings():  # zeros dropped: nothing is lost, nothing to say
        warnings.simplefilter("error")
        assert fit_width("dmpls", np.zeros((3, 9)), 8).shape == (3, 8)


def test_the_forward_pads_short_betas_and_refuses_long_ones():
    model = smplcore.BodyModel(model_type="open", dtype=np.float64)
    short = model(betas=np.ones((1, 3)))
    full = model(betas=np.concatenate([np.ones((1, 3)), np.zeros((1, 7))], axis=1))
    np.testing.assert_array_equal(short.vertices, full.vertices)
    with pytest.raises(ShapeError, match="betas"):
        model(betas=np.ones((1, 11)))


def test_the_plan_is_decided_once_from_the_arrays():
    assert plan("auto", np.zeros((1, 1)), gradients=False) == Plan("blocked", False, False)
    small = torch.zeros(1, 1)
    assert plan("auto", small, gradients=False, batch=4) == Plan("blocked", False, True)
    assert plan("auto", small, gradients=False, batch=1000) == Plan("blocked", False, False)
    assert plan("auto", small, gradients=True, batch=4) == Plan("autograd", False, False)
    assert plan("reference", small, gradients=False, batch=4) == Plan("reference", False, False)
    assert plan("auto", small, gradients=False, trainable_model=True) == Plan("reference", False, False)
    with pytest.raises(ValueError, match="kernel='blocked' records no gradients"):
        plan("blocked", small, gradients=True)


def test_every_error_shares_one_base_class():
    from smplcore._deps import MissingDependencyError
    from smplcore.io import UnsafePickleError
    from smplcore.motion.process.options import ProcessError

    for cls, builtin in (
        (ModelFileError, ValueError),
        (ShapeError, ValueError),
        (ProcessError, ValueError),
        (MissingDependencyError, ImportError),
        (UnsafePickleError, Exception),
    ):
        assert issubclass(cls, SmplcoreError) and issubclass(cls, builtin), cls
    with pytest.raises(SmplcoreError):
        smplcore.BodyModel(model_type="open")(betas=np.ones((1, 11)))
