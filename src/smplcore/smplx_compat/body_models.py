"""smplx's ``body_models`` module: the model classes, ``create``, ``build_layer`` and output classes."""

from smplcore.torch.factory import build_layer, create  # noqa: F401
from smplcore.torch.models import (  # noqa: F401
    FLAME,
    MANO,
    SMPL,
    SMPLH,
    SMPLX,
    FLAMELayer,
    MANOLayer,
    SMPLHLayer,
    SMPLLayer,
    SMPLXLayer,
)
from smplcore.torch.outputs import (  # noqa: F401
    FLAMEOutput,
    MANOOutput,
    ModelOutput,
    SMPLHOutput,
    SMPLOutput,
    SMPLXOutput,
)
