"""Facts about the real files: sizes, the vertex ids smplx uses for extra joints, seed codes."""

from __future__ import annotations

# Real sizes.
SMPL_VERTS, SMPL_FACES = 6890, 13776
SMPLX_VERTS, SMPLX_FACES = 10475, 20908
SMPLX_UVS = 11313
SMPL_UVS = 7576
MANO_VERTS, MANO_FACES = 778, 1538
FLAME_VERTS, FLAME_FACES = 5023, 9976
HAND_COEFF_ROWS = 1554
ROOT_PARENT = 4294967295  # what the official kintree_table stores as the root's parent

# Vertex ids smplx uses for extra joints (facts about the real meshes' topology).
_SMPLH_VERTEX_IDS = {
    "nose": 332,
    "reye": 6260,
    "leye": 2800,
    "rear": 4071,
    "lear": 583,
    "rthumb": 6191,
    "rindex": 5782,
    "rmiddle": 5905,
    "rring": 6016,
    "rpinky": 6133,
    "lthumb": 2746,
    "lindex": 2319,
    "lmiddle": 2445,
    "lring": 2556,
    "lpinky": 2673,
    "LBigToe": 3216,
    "LSmallToe": 3226,
    "LHeel": 3387,
    "RBigToe": 6617,
    "RSmallToe": 6624,
    "RHeel": 6787,
}
_SMPLX_VERTEX_IDS = {
    "nose": 9120,
    "reye": 9929,
    "leye": 9448,
    "rear": 616,
    "lear": 6,
    "rthumb": 8079,
    "rindex": 7669,
    "rmiddle": 7794,
    "rring": 7905,
    "rpinky": 8022,
    "lthumb": 5361,
    "lindex": 4933,
    "lmiddle": 5058,
    "lring": 5169,
    "lpinky": 5286,
    "LBigToe": 5770,
    "LSmallToe": 5780,
    "LHeel": 8846,
    "RBigToe": 8463,
    "RSmallToe": 8474,
    "RHeel": 8635,
}
_MANO_VERTEX_IDS = {"thumb": 744, "index": 320, "middle": 443, "ring": 554, "pinky": 671}

_GENDER_CODE = {"neutral": 0, "male": 1, "female": 2}
_GENDER_SCALE = {"neutral": 1.0, "male": 1.05, "female": 0.95}
_MODEL_CODE = {"smpl": 11, "smplh": 12, "smplx": 13, "mano": 14, "flame": 15}
