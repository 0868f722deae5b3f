"""Colours shared by the plots and the overlays (Okabe-Ito palette: readable with colour blindness), and the
wording of counts in their titles."""

from __future__ import annotations

#: Body side -> RGB (0-255): left limbs blue, right limbs vermillion (orange), torso and head bluish green.
SIDE_RGB: dict[str, tuple[int, int, int]] = {
    "left": (0, 114, 178),
    "right": (213, 94, 0),
    "center": (0, 158, 115),
}
#: Ground-truth skeleton in the overlays.
GT_RGB: tuple[int, int, int] = (240, 228, 66)
#: 2D marker detections (what a marker tracker was given) in the overlays: sky blue.
DETECTION_RGB: tuple[int, int, int] = (86, 180, 233)
#: IK floor in the plots.
IK_RGB: tuple[int, int, int] = (120, 120, 120)


def count(n: int, noun: str) -> str:
    """``1 run``, ``3 runs``: figure titles and notes say the number they know."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def rgb01(c: tuple[int, int, int]) -> tuple[float, float, float]:
    """An RGB 0-255 triple as matplotlib's 0-1 floats."""
    return (c[0] / 255.0, c[1] / 255.0, c[2] / 255.0)


def bgr(c: tuple[int, int, int]) -> tuple[int, int, int]:
    """An RGB triple in OpenCV's BGR order."""
    return (c[2], c[1], c[0])


def joint_side(name: str) -> str:
    """``"left"``, ``"right"`` or ``"center"`` for a joint name of :data:`swarmpose.joints.JOINTS15`."""
    if name.startswith("l_"):
        return "left"
    if name.startswith("r_"):
        return "right"
    return "center"
