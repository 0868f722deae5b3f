"""The 15 standard joints of the HumanEva 3D error, in HumanEva's order.

See ``shared/reference/humaneva-facts.md`` §4.3. Every ``(..., 15, 3)`` joint array in swarmpose
(ground truth, tracked estimates, body-model output) uses this order, in millimetres.
"""

from __future__ import annotations

__all__ = ["JOINTS15", "JOINT_INDEX", "LEFT_JOINTS", "RIGHT_JOINTS", "BONES15", "SWAP15"]

JOINTS15: tuple[str, ...] = (
    "thorax",          # 0  thorax / neck base (torsoProximal, headProximal)
    "pelvis",          # 1  torsoDistal
    "l_shoulder",      # 2
    "l_elbow",         # 3
    "l_wrist",         # 4
    "r_shoulder",      # 5
    "r_elbow",         # 6
    "r_wrist",         # 7
    "l_hip",           # 8
    "l_knee",          # 9
    "l_ankle",         # 10
    "r_hip",           # 11
    "r_knee",          # 12
    "r_ankle",         # 13
    "head_top",        # 14 headDistal
)

JOINT_INDEX: dict[str, int] = {name: i for i, name in enumerate(JOINTS15)}
LEFT_JOINTS = tuple(i for i, n in enumerate(JOINTS15) if n.startswith("l_"))
RIGHT_JOINTS = tuple(i for i, n in enumerate(JOINTS15) if n.startswith("r_"))
#: The permutation that exchanges left and right: ``joints[..., SWAP15, :]`` is the mirrored labelling
#: (``l_elbow`` takes ``r_elbow``'s place and back; the middle joints stay). ``SWAP15[SWAP15]`` is the identity.
SWAP15: tuple[int, ...] = tuple(
    JOINT_INDEX[("r_" + n[2:]) if n.startswith("l_") else ("l_" + n[2:]) if n.startswith("r_") else n]
    for n in JOINTS15)

# Segments of the 15-joint stick figure (for plots and bone-length checks).
BONES15: tuple[tuple[int, int], ...] = (
    (1, 0), (0, 14),
    (0, 2), (2, 3), (3, 4),
    (0, 5), (5, 6), (6, 7),
    (1, 8), (8, 9), (9, 10),
    (1, 11), (11, 12), (12, 13),
)
