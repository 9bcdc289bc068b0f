"""``show``: a browser viewer on a model and its parameters in one call (see :class:`~smplcore.view.viewer.Viewer`)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from smplcore.view.sources import Source
from smplcore.view.viewer import Viewer


def show(
    model: Any = None,
    params: Any = None,
    *,
    port: int | None = None,
    keypoints: Any = None,
    block: bool = False,
    **options: Any,
) -> Viewer:
    """Open a browser viewer on ``model`` posed with ``params`` and return it (``viewer.url``; close it with
    ``viewer.close()``).

    Parameters
    ----------
    model : a :class:`smplcore.BodyModel`, a model from :func:`smplcore.create` (its data is viewed with the
        NumPy front end), a model file or folder, or None for the open model.
    params : model keyword arrays (``betas``, ``body_pose``, ... as (n,) / (1, n), or (T, n) for a motion on
        the timeline), a :class:`~smplcore.motion.Motion`, a motion / parameter file, or None (rest pose).
        A list shows several bodies side by side, all on ``model``.
    port : HTTP port (default 8080, or the next free one).
    keypoints : target keypoints (K, 3) / (T, K, 3) or a file, drawn over the first body.
    block : serve until interrupted (Ctrl-C) instead of returning at once.
    options : passed to :class:`Viewer` (``out_dir``, ``host``, ``gender``, ...).
    """
    from smplcore import BodyModel
    from smplcore.motion import Motion
    from smplcore.view.sources import load_source

    items = params if isinstance(params, list) else [params]
    sources: list[Source] = []
    for item in items:
        if item is None:
            sources.append(Source(label="body"))
        elif isinstance(item, Motion):
            sources.append(Source(label=Path(item.source).name, motion=item))
        elif isinstance(item, (str, Path)):
            sources.append(load_source(item))
        else:
            sources.append(Source(label="params", params={k: np.asarray(v) for k, v in dict(item).items()}))
    models = None
    if isinstance(model, (str, Path)):
        options.setdefault("model_path", model)
    elif isinstance(model, BodyModel):
        models = [model] * len(sources)
    elif model is not None and hasattr(model, "model_data"):  # a torch model of smplcore.create
        extra: dict[str, Any] = {}
        if model.num_expression_coeffs:
            extra["num_expression_coeffs"] = model.num_expression_coeffs
        if model.rig.model_type in ("smplh", "smplx", "mano"):
            extra["use_pca"] = False  # every hand joint gets its own rotation control
        numpy_model = BodyModel(data=model.model_data, num_betas=model.num_betas, **extra)
        models = [numpy_model] * len(sources)
    elif model is not None:
        raise ValueError(f"model: expected a smplcore.BodyModel, a smplcore.create model or a path, got {model!r}")
    viewer = Viewer(sources, port=port, keypoints=keypoints, models=models, **options)
    if block:
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            viewer.close()
    return viewer
