"""smplx's ``body_models`` module: the model classes, ``create``, ``build_layer`` and output classes."""

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
    build_layer,
    create,
)
from smplcore.torch.outputs import (  # noqa: F401
    FLAMEOutput,
    MANOOutput,
    ModelOutput,
    SMPLHOutput,
    SMPLOutput,
    SMPLXOutput,
)
