"""smplx's ``vertex_ids`` module: the vertices used as extra joints, per mesh."""

from smplcore.family.names import VERTEX_IDS_MANO, VERTEX_IDS_SMPLH, VERTEX_IDS_SMPLX

vertex_ids = {"smplh": dict(VERTEX_IDS_SMPLH), "smplx": dict(VERTEX_IDS_SMPLX), "mano": dict(VERTEX_IDS_MANO)}
