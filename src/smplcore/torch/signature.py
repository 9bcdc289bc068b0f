"""The torch classes' ``forward`` signature: smplx's parameters of each class, in smplx's order, so that code
that introspects it (``inspect.signature``) or passes arguments by position sees what it sees in smplx."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any, Optional

import torch

# smplx's flags and their defaults; every other parameter of its forwards is a tensor defaulting to None
_FLAGS = {"return_verts": True, "return_full_pose": False, "pose2rot": True, "return_shaped": True}
# smplcore's keywords (keyword-only, None: the model's setting)
_OWN = (
    ("dmpls", Optional[torch.Tensor]),  # noqa: UP045 (runtime annotations, shown as smplx shows its own)
    ("v_template", Optional[torch.Tensor]),  # noqa: UP045
    ("kernel", Optional[str]),  # noqa: UP045
    ("check_finite", Optional[bool]),  # noqa: UP045
    ("check_rotations", Optional[bool]),  # noqa: UP045
)


def forward_signature(forward_args: tuple[str, ...], output: type) -> inspect.Signature:
    """``self``, smplx's parameters ``forward_args`` (positional or keyword), smplcore's keywords (keyword
    only), then ``**kwargs`` (keywords of other smplx classes are accepted; unknown ones warn)."""
    param = inspect.Parameter
    tensor = Optional[torch.Tensor]  # noqa: UP045
    params = [param("self", param.POSITIONAL_OR_KEYWORD)]
    for name in forward_args:
        default = _FLAGS.get(name)
        annotation = tensor if default is None else bool
        params.append(param(name, param.POSITIONAL_OR_KEYWORD, default=default, annotation=annotation))
    params += [param(name, param.KEYWORD_ONLY, default=None, annotation=a) for name, a in _OWN]
    params.append(param("kwargs", param.VAR_KEYWORD))
    return inspect.Signature(params, return_annotation=output)


def with_signature(cls: type, forward: Callable[..., Any]) -> Callable[..., Any]:
    """``forward`` (the one implementation) under ``cls``'s name, with ``cls``'s signature; marked as ours, so
    that subclasses that do not define their own forward get theirs."""

    def named(self: Any, *args: Any, **kwargs: Any) -> Any:
        return forward(self, *args, **kwargs)

    named.__signature__ = forward_signature(cls.FORWARD_ARGS, cls.OUTPUT)  # type: ignore[attr-defined]
    named.__doc__ = forward.__doc__
    named.__name__ = "forward"
    named.__qualname__ = f"{cls.__qualname__}.forward"
    named.__module__ = cls.__module__
    named._smplcore_forward = True  # type: ignore[attr-defined]
    return named


def mark(cls: type, forward: Callable[..., Any]) -> None:
    """Give the root class's own ``forward`` its signature and mark it as ours."""
    forward.__signature__ = forward_signature(cls.FORWARD_ARGS, cls.OUTPUT)  # type: ignore[attr-defined]
    forward._smplcore_forward = True  # type: ignore[attr-defined]


def is_ours(forward: Any) -> bool:
    """Whether ``forward`` is smplcore's (not a user subclass's own)."""
    return bool(getattr(forward, "_smplcore_forward", False))
