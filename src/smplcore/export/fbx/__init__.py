"""FBX 7.4 binary export: a small clean-room writer of the node-record container (:mod:`.binary`), the
document around the objects (:mod:`.document`) and the rigged, animated body (:mod:`.writer`)."""

from smplcore.export.fbx.writer import ROTATION_ORDERS, save_fbx

__all__ = ["ROTATION_ORDERS", "save_fbx"]
