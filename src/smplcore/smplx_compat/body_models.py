"""smplx's ``body_models`` module: the model classes, ``create``, ``build_layer`` and output classes, and the
names smplx's module imports and so offers to its clients (``lbs``, ``VertexJointSelector``, ``to_tensor``, ...)."""

from smplcore.smplx_compat.lbs import (  # noqa: F401
    blend_shapes,
    find_dynamic_lmk_idx_and_bcoords,
    lbs,
    vertices2landmarks,
)
from smplcore.smplx_compat.utils import Array, Struct, Tensor, find_joint_kin_chain, to_np, to_tensor  # noqa: F401
from smplcore.smplx_compat.vertex_ids import vertex_ids as VERTEX_IDS  # noqa: F401
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
from smplcore.torch.selector import VertexJointSelector  # noqa: F401, E402
