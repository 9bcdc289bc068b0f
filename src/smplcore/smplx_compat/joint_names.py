"""smplx's ``joint_names`` module: names of the output joints of SMPL-X and SMPL+H, and per model."""

from smplcore.family.names import (
    EXTRA_JOINTS,
    FACE_CONTOUR,
    FACE_LANDMARKS,
    FLAME_JOINTS,
    MANO_JOINTS,
    SMPL_JOINTS,
    SMPLH_JOINTS,
    SMPLX_JOINTS,
)

#: SMPL-X output joints with the face contour (144).
JOINT_NAMES = list(SMPLX_JOINTS + EXTRA_JOINTS + FACE_LANDMARKS + FACE_CONTOUR)
#: SMPL+H output joints (73).
SMPLH_JOINT_NAMES = list(SMPLH_JOINTS + EXTRA_JOINTS)
#: SMPL output joints (45).
SMPL_JOINT_NAMES = list(SMPL_JOINTS + EXTRA_JOINTS)
MANO_JOINT_NAMES = list(MANO_JOINTS)
FLAME_JOINT_NAMES = list(FLAME_JOINTS + FACE_LANDMARKS + FACE_CONTOUR)
