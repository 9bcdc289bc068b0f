"""smplx's ``vertex_joint_selector`` module: ``VertexJointSelector``."""

from smplcore.torch.selector import VertexJointSelector  # noqa: F401
