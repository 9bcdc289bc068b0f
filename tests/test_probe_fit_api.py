"""Every hostile value of tests/probe_fit_api.py (fitting API, camera, priors, keypoint readers, front-end
options and forward inputs) ends in a clear error naming the argument, a flagged result or a correct one:
no raw exception, no silent NaN / inf (issue 27, items 5 and 7)."""

from __future__ import annotations

import pytest

from probe_fit_api import CASES, outcome


@pytest.mark.parametrize("case", CASES, ids=[f"{c.surface}: {c.label}" for c in CASES])
def test_hostile_value_ends_clearly(case, tmp_path):
    kind, detail = outcome(case, tmp_path)
    assert kind in ("clear", "flagged", "clean"), f"{kind}: {detail}"
