"""Real motion capture (BVH) as ground truth: units, axes, HumanEva joints and resampling.

The pipeline: :func:`swarmpose.io.bvh.read_bvh` -> unit scale (:func:`infer_unit_scale`) ->
axes BVH (Y up) -> swarmpose world (Z up, mm) -> CMU skeleton -> the 15 HumanEva joints
(:data:`swarmpose.joints.JOINTS15`), optionally resampled to another frame rate
(:func:`resample`). :func:`load_clip` does all of it.

World from source (BVH) coordinates, a pure similarity transform (no translation)::

    world = s * (x, -z, y)         s = mm_per_unit

i.e. ``world_from_source = [[s, 0, 0, 0], [0, 0, -s, 0], [0, s, 0, 0], [0, 0, 0, 1]]`` (a proper
rotation, det +1, times the unit scale). BVH Y (up) becomes world z, the floor stays at height 0.

Shape letters: ``T`` frames, ``J`` BVH joints.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from swarmpose.body.measurements import SubjectMeasurements
from swarmpose.body.spec import BodySpec, Subject
from swarmpose.body.subject import subject_from_rest_points
from swarmpose.errors import ConfigError, FormatError
from swarmpose.io.bvh import (
    BvhClip,
    _local_rotations_from_motion,
    _local_translations_from_motion,
    forward_kinematics,
    read_bvh,
)
from swarmpose.joints import JOINT_INDEX, JOINTS15

__all__ = [
    "UNIT_SCALES",
    "SkeletonMap",
    "MocapClip",
    "SKELETON_STYLES",
    "cmu_skeleton_map",
    "swarmpose_skeleton_map",
    "auto_skeleton_map",
    "map_skeleton",
    "infer_unit_scale",
    "rest_height",
    "world_from_source_matrix",
    "load_clip",
    "clip_from_bvh",
    "subject_from_clip",
    "resample",
]

#: Candidate source units, millimetres per unit. ``"cmu"`` is the CMU ASF unit kept by the
#: cgspeed/amc2bvh BVH conversions: 1 unit = (1 / 0.45) inch = 56.444 mm (see the mocap README).
UNIT_SCALES: dict[str, float] = {
    "mm": 1.0,
    "cm": 10.0,
    "m": 1000.0,
    "inch": 25.4,
    "cmu": 25.4 / 0.45,
}

_TARGET_HEIGHT_MM = 1700.0
_ZERO_OFFSET = 1e-9


# ---------------------------------------------------------------------- skeleton map
@dataclass(frozen=True)
class SkeletonMap:
    """Which BVH joints (or their end sites) give the 15 HumanEva joints and a few extra points.

    Attributes
    ----------
    style : str
        Skeleton style the map was built for: ``"cmu"`` (the fields as below) or ``"swarmpose"`` (a file
        written by ``swarmpose export``: every point is a joint, see :func:`swarmpose_skeleton_map`).
    joint_index : tuple of 15 int
        For each joint of :data:`swarmpose.joints.JOINTS15`, the BVH joint index.
    from_end_site : tuple of 15 bool
        True where the HumanEva joint is that BVH joint's *end site* (``head_top``).
    l_toe, r_toe : int
        Toe joints (ball of the foot); their end sites are the toe tips.
    l_hand, r_hand : int
        First child of the wrist (the hand joint; at the wrist position in the CMU files), or the
        wrist itself when it has no child.
    l_hand_tip, r_hand_tip : int
        Joint whose end site is the tip of the hand (following first children from ``*_hand``);
        ``"swarmpose"``: the hand-tip joint itself.
    neck : int
        First joint of the neck chain (the ``thorax`` joint's BVH joint).
    head : int
        Head joint (its end site is ``head_top``; ``"swarmpose"``: the joint below ``head_top``).
    """

    style: str
    joint_index: tuple[int, ...]
    from_end_site: tuple[bool, ...]
    l_toe: int
    r_toe: int
    l_hand: int
    r_hand: int
    l_hand_tip: int
    r_hand_tip: int
    neck: int
    head: int

    def __post_init__(self) -> None:
        if len(self.joint_index) != len(JOINTS15) or len(self.from_end_site) != len(JOINTS15):
            raise ConfigError(f"SkeletonMap needs {len(JOINTS15)} entries, got {len(self.joint_index)}")

    def joint(self, name: str) -> int:
        """BVH joint index for a HumanEva joint name (e.g. ``"l_shoulder"``)."""
        return self.joint_index[JOINT_INDEX[name]]

    def joints15(self, positions: np.ndarray, end_sites: np.ndarray) -> np.ndarray:
        """Pick the 15 HumanEva joints.

        Parameters
        ----------
        positions : numpy.ndarray, shape (..., J, 3)
            All BVH joint positions.
        end_sites : numpy.ndarray, shape (..., J, 3)
            All BVH end-site positions (NaN where none).

        Returns
        -------
        numpy.ndarray, shape (..., 15, 3)
            In :data:`swarmpose.joints.JOINTS15` order.
        """
        idx = np.asarray(self.joint_index)
        use_end = np.asarray(self.from_end_site)
        out = positions[..., idx, :].copy()
        out[..., use_end, :] = end_sites[..., idx[use_end], :]
        return out


def _single_chain(start: int, children: list[list[int]]) -> list[int]:
    """Follow single children from ``start``; returns the chain up to the first joint without
    exactly one child (inclusive)."""
    chain = [start]
    while len(children[chain[-1]]) == 1:
        chain.append(children[chain[-1]][0])
    return chain


def _first_child_leaf(start: int, children: list[list[int]]) -> int:
    j = start
    while children[j]:
        j = children[j][0]
    return j


def cmu_skeleton_map(bvh: BvhClip) -> SkeletonMap:
    """Map a CMU-style BVH skeleton to the 15 HumanEva joints by tree position, not by name.

    Works for both cgspeed layouts of ``shared/data/mocap`` ("MB" and "Max", whose joint names
    differ and even clash: ``LeftShoulder`` is the clavicle in one and the shoulder in the other).

    Expected structure (CMU ASF bone names in brackets)::

        root [pelvis]            -> pelvis
          child 0: left leg      [lhipjoint ->] lfemur -> ltibia -> lfoot -> ltoes (+End Site)
          child 1: right leg     mirror
          child 2: spine         lowerback -> upperback -> thorax, which has three children:
            neck chain           lowerneck -> upperneck -> head (+End Site)
            left arm             lclavicle -> lhumerus -> lradius -> lwrist [-> hand, fingers ...]
            right arm            mirror

    * ``l_hip`` = first joint of the leg chain with a non-zero OFFSET (the femur joint; the zero
      OFFSET hip-joint bone of the conversions is skipped), ``l_knee`` and ``l_ankle`` the next two,
      the toe the one after.
    * ``thorax`` = the first joint of the neck chain (CMU ``lowerneck``, "base of the neck").
      amc2bvh gives every child of a multi-child bone OFFSET 0, so this joint sits at the *start*
      of the CMU thorax bone (the upper end of ``upperback``): neck, head and shoulders are about
      0.11 m lower than on the ASF skeleton. The motion is unaffected.
    * ``head_top`` = the End Site of the last joint of the neck chain (CMU ``head``).
    * ``l_shoulder`` = the clavicle's child (humerus joint), ``l_elbow``, ``l_wrist`` the next two.

    Raises
    ------
    FormatError
        ``"skeleton is not CMU-style: ..."`` when the tree does not have this structure, or when
        the rest pose puts the first leg on the body's right (mirrored skeleton).
    """
    path = bvh.path
    n = len(bvh.joints)
    parents = bvh.parents
    children: list[list[int]] = [[] for _ in range(n)]
    for j, p in enumerate(parents):
        if p >= 0:
            children[p].append(j)

    def fail(msg: str) -> FormatError:
        return FormatError(f"skeleton is not CMU-style: {msg}", path=path)

    def nm(j: int) -> str:
        return repr(bvh.joints[j].name)

    roots = [j for j in range(n) if parents[j] < 0]
    if len(roots) != 1:
        raise fail(f"expected one ROOT, found {len(roots)}")
    root = roots[0]
    if len(children[root]) != 3:
        raise fail(f"root {nm(root)} must have 3 children (left leg, right leg, spine), has {len(children[root])}")
    offsets = bvh.offsets

    legs = []
    for side, start in zip(("left", "right"), children[root][:2], strict=True):
        chain = _single_chain(start, children)
        end = chain[-1]
        if children[end] or bvh.joints[end].end_site is None:
            raise fail(f"{side} leg chain from {nm(start)} must be unbranched and end in an End Site "
                       f"(it branches at {nm(end)})")
        nonzero = [k for k, j in enumerate(chain) if np.linalg.norm(offsets[j]) > _ZERO_OFFSET]
        if not nonzero or len(chain) - nonzero[0] < 4:
            raise fail(f"{side} leg chain {[bvh.joints[j].name for j in chain]} needs hip, knee, ankle and "
                       "toe joints after the zero-offset hip-joint bones")
        h = nonzero[0]
        legs.append((chain[h], chain[h + 1], chain[h + 2], chain[h + 3]))

    spine = _single_chain(children[root][2], children)
    thorax = spine[-1]
    if len(children[thorax]) != 3:
        raise fail(f"the spine chain from {nm(children[root][2])} must end in a joint with 3 children "
                   f"(neck, left arm, right arm); {nm(thorax)} has {len(children[thorax])}")
    neck_start, larm, rarm = children[thorax]
    neck = _single_chain(neck_start, children)
    head = neck[-1]
    if len(neck) < 2 or children[head] or bvh.joints[head].end_site is None:
        raise fail(f"the neck chain from {nm(neck_start)} must be unbranched, have >= 2 joints and end in "
                   "a head joint with an End Site")
    arms = []
    for side, clav in (("left", larm), ("right", rarm)):
        chain = [clav]
        for _ in range(3):  # clavicle -> shoulder -> elbow -> wrist
            kids = children[chain[-1]]
            if len(kids) != 1:
                raise fail(f"{side} arm: {nm(chain[-1])} must have exactly one child, has {len(kids)} "
                           "(expected clavicle -> shoulder -> elbow -> wrist)")
            chain.append(kids[0])
        _, shoulder, elbow, wrist = chain
        hand = children[wrist][0] if children[wrist] else wrist
        tip = _first_child_leaf(hand, children)
        if bvh.joints[tip].end_site is None:
            raise fail(f"{side} hand chain ends at {nm(tip)} without an End Site")
        arms.append((shoulder, elbow, wrist, hand, tip))

    (l_hip, l_knee, l_ankle, l_toe), (r_hip, r_knee, r_ankle, r_toe) = legs
    (l_sh, l_el, l_wr, l_hand, l_tip), (r_sh, r_el, r_wr, r_hand, r_tip) = arms
    by_name = {
        "thorax": neck_start, "pelvis": root,
        "l_shoulder": l_sh, "l_elbow": l_el, "l_wrist": l_wr,
        "r_shoulder": r_sh, "r_elbow": r_el, "r_wrist": r_wr,
        "l_hip": l_hip, "l_knee": l_knee, "l_ankle": l_ankle,
        "r_hip": r_hip, "r_knee": r_knee, "r_ankle": r_ankle,
        "head_top": head,
    }
    smap = SkeletonMap(
        style="cmu",
        joint_index=tuple(by_name[n_] for n_ in JOINTS15),
        from_end_site=tuple(n_ == "head_top" for n_ in JOINTS15),
        l_toe=l_toe, r_toe=r_toe, l_hand=l_hand, r_hand=r_hand, l_hand_tip=l_tip, r_hand_tip=r_tip,
        neck=neck_start, head=head,
    )
    _check_left_right(bvh, smap, fail)
    return smap


def _check_left_right(bvh: BvhClip, smap: SkeletonMap, fail: Callable[[str], FormatError]) -> None:
    """Rest pose (BVH, Y up), judged from the feet: it must face +Z, as CMU's does (the subject's limb
    offsets are read in that frame), and the first leg must be on the body's left; the first arm must be
    on the first leg's side."""
    rest, rest_end = bvh.rest_positions()
    hips = rest[smap.joint("l_hip")] - rest[smap.joint("r_hip")]
    if float(np.dot(rest[smap.joint("l_shoulder")] - rest[smap.joint("r_shoulder")], hips)) <= 0:
        raise fail("the thorax's first arm is on the other side from the root's first leg in the rest pose: "
                   "expected the thorax's children in the order neck, left arm, right arm, as in CMU files "
                   "(reordered skeleton?)")
    forward = np.zeros(3)
    for toe, ankle in ((smap.l_toe, smap.joint("l_ankle")), (smap.r_toe, smap.joint("r_ankle"))):
        forward += rest_end[toe] - rest[ankle]
    forward[1] = 0.0  # horizontal part (BVH Y is up)
    if np.linalg.norm(forward) < 1e-9:
        return  # feet point straight down: no facing direction to judge by
    forward /= np.linalg.norm(forward)
    if forward[2] < np.cos(np.radians(10.0)):  # CMU files: within 0.5 degrees
        heading = np.degrees(np.arctan2(forward[0], forward[2]))
        raise fail(f"the rest pose faces {heading:+.0f} degrees from +Z (judged from the feet); a CMU-style "
                   "skeleton must stand Y up facing +Z")
    left = np.cross([0.0, 1.0, 0.0], forward)  # left = up x forward (right-handed)
    if float(np.dot(hips, left)) <= 0:
        raise fail("the root's first leg is on the body's right in the rest pose (mirrored skeleton?)")


def swarmpose_skeleton_map(bvh: BvhClip) -> SkeletonMap:
    """Map a skeleton written by ``swarmpose export`` (a body model's joint tree) by joint *name*.

    Every name of :data:`swarmpose.joints.JOINTS15` must be a joint (``head_top`` included: the
    exporter writes it as a joint). Toes and hand tips are the ``l_toe`` / ``l_hand_tip`` *joints*
    where the model has them (``full45``), else the ankle and wrist; the exporter's End Sites are
    made-up bone continuations and never used. The head is the ``head`` joint, else ``head_top``'s
    parent. The rest pose must stand Y up and face +Z with the subject's left on +X, as the exporter
    writes it by default and as CMU files stand.

    Raises
    ------
    FormatError
        A name is missing, or the rest pose is not Y up facing +Z (``--z-up`` or ``--rest-facing +x``).
    """
    names = list(bvh.joint_names)
    missing = [n for n in JOINTS15 if n not in names]
    if missing:
        raise FormatError(f"skeleton is not a swarmpose export: no joint named {', '.join(missing)}", path=bvh.path)
    idx = {n: i for i, n in enumerate(names)}

    def first(*candidates: str) -> int:
        return next(idx[c] for c in candidates if c in idx)

    rest, _ = bvh.rest_positions()
    up = rest[idx["head_top"]] - rest[idx["pelvis"]]
    if not up[1] > 0.9 * np.linalg.norm(up):
        raise FormatError("swarmpose export whose rest pose is not Y up (written with --z-up?): export it "
                          "again without --z-up", path=bvh.path)
    left = rest[idx["l_hip"]] - rest[idx["r_hip"]]
    if not left[0] > 0.9 * np.linalg.norm(left):
        raise FormatError("swarmpose export whose rest pose does not face +Z (left hip not on +X): "
                          "export it again with the default --rest-facing +z", path=bvh.path)
    head_top = idx["head_top"]
    return SkeletonMap(
        style="swarmpose",
        joint_index=tuple(idx[n] for n in JOINTS15),
        from_end_site=(False,) * len(JOINTS15),
        l_toe=first("l_toe", "l_ankle"), r_toe=first("r_toe", "r_ankle"),
        l_hand=idx["l_wrist"], r_hand=idx["r_wrist"],
        l_hand_tip=first("l_hand_tip", "l_wrist"), r_hand_tip=first("r_hand_tip", "r_wrist"),
        neck=first("neck", "thorax"),
        head=idx.get("head", max(int(bvh.parents[head_top]), 0)),
    )


def auto_skeleton_map(bvh: BvhClip) -> SkeletonMap:
    """A swarmpose export's map when every HumanEva joint name is a joint (CMU files never use those
    names; some model trees would also pass the CMU structure test, with ``head_top`` misread), else
    the CMU map."""
    if all(n in bvh.joint_names for n in JOINTS15):
        return swarmpose_skeleton_map(bvh)
    return cmu_skeleton_map(bvh)


#: Skeleton styles by name -> function building a :class:`SkeletonMap` from a :class:`BvhClip`.
SKELETON_STYLES: dict[str, Callable[[BvhClip], SkeletonMap]] = {
    "cmu": cmu_skeleton_map, "swarmpose": swarmpose_skeleton_map, "auto": auto_skeleton_map}


def map_skeleton(bvh: BvhClip, style: str = "cmu") -> SkeletonMap:
    """Build the :class:`SkeletonMap` of ``bvh`` with a style from :data:`SKELETON_STYLES`."""
    if style not in SKELETON_STYLES:
        raise ConfigError(f"unknown skeleton style {style!r}; known: {sorted(SKELETON_STYLES)}")
    return SKELETON_STYLES[style](bvh)


# ---------------------------------------------------------------------- units and axes
def rest_height(bvh: BvhClip) -> float:
    """Vertical (BVH Y) extent of the rest pose over all joints and end sites, source units.

    For a standing skeleton this is head end site to the lowest foot point.
    """
    pos, ends = bvh.rest_positions()
    pts = np.concatenate([pos, ends[~np.isnan(ends[:, 0])]])
    return float(pts[:, 1].max() - pts[:, 1].min())


def infer_unit_scale(
    clip: BvhClip, target_height_mm: float = _TARGET_HEIGHT_MM
) -> tuple[float, str]:
    """Guess the length unit of a BVH skeleton.

    Among :data:`UNIT_SCALES` (mm, cm, m, inch, cmu = 56.444 mm) choose the one whose scale makes
    the rest pose's height (:func:`rest_height`: the vertical extent of all joints and end sites
    with every channel at zero, i.e. head end site to the lowest foot point for a standing
    skeleton) closest to ``target_height_mm`` in ratio (``|log(height * s / target)|``).

    The CMU files give 24.3-26.0 units = 1.37-1.47 m in "cmu" units: shorter than the
    performers because the thorax bone is missing (README quirk) and the head end site is short of
    the top of the skull; the next candidates (inch: 0.62-0.66 m) are much further off.

    Parameters
    ----------
    clip : BvhClip
    target_height_mm : float, default 1700

    Returns
    -------
    mm_per_unit : float
    unit_name : str
        Key of :data:`UNIT_SCALES`.

    Raises
    ------
    FormatError
        The rest pose has no vertical extent.
    """
    height = rest_height(clip)
    if not (height > 0 and math.isfinite(height)):
        raise FormatError("cannot infer the unit scale: the rest pose has no vertical extent", path=clip.path)
    name = min(UNIT_SCALES, key=lambda k: abs(math.log(height * UNIT_SCALES[k] / target_height_mm)))
    return UNIT_SCALES[name], name


def world_from_source_matrix(mm_per_unit: float) -> np.ndarray:
    """Similarity transform from BVH coordinates (Y up, source units) to the world (Z up, mm).

    Returns
    -------
    numpy.ndarray, shape (4, 4)
        ``[[s, 0, 0, 0], [0, 0, -s, 0], [0, s, 0, 0], [0, 0, 0, 1]]``: ``world = s * (x, -z, y)``.
    """
    s = float(mm_per_unit)
    if not (math.isfinite(s) and s > 0):
        raise ConfigError(f"mm_per_unit must be finite and > 0, got {mm_per_unit!r}")
    m = np.zeros((4, 4))
    m[0, 0] = s
    m[1, 2] = -s
    m[2, 1] = s
    m[3, 3] = 1.0
    return m


def _resolve_unit(bvh: BvhClip, unit_scale: float | str | None) -> tuple[float, str]:
    if unit_scale is None:
        return infer_unit_scale(bvh)
    if isinstance(unit_scale, str):
        if unit_scale not in UNIT_SCALES:
            raise ConfigError(f"unknown unit {unit_scale!r}; known: {sorted(UNIT_SCALES)} or a number (mm per unit)")
        return UNIT_SCALES[unit_scale], unit_scale
    s = float(unit_scale)
    if not (math.isfinite(s) and s > 0):
        raise ConfigError(f"unit_scale must be finite and > 0, got {unit_scale!r}")
    name = next((k for k, v in UNIT_SCALES.items() if v == s), "custom")
    return s, name


# ---------------------------------------------------------------------- the clip
@dataclass
class MocapClip:
    """A motion-capture clip in swarmpose world coordinates (mm, Z up).

    Attributes
    ----------
    name : str
        File stem (e.g. ``"cmu_16_16_walk"``).
    source_path : pathlib.Path or None
    frame_rate : float
        Frames per second (120.0 for the CMU files; the target rate after :func:`resample`).
    frame_times : numpy.ndarray, shape (T,)
        Seconds from the first frame, ``k / frame_rate``.
    joints : numpy.ndarray, shape (T, 15, 3)
        The HumanEva joints (:data:`swarmpose.joints.JOINTS15` order), world mm.
    positions : numpy.ndarray, shape (T, J, 3)
        All BVH joints, world mm.
    end_sites : numpy.ndarray, shape (T, J, 3)
        End sites, world mm; NaN rows for joints without one.
    parents : numpy.ndarray, shape (J,)
    joint_names : list of str
    skeleton_map : SkeletonMap
    world_from_source : numpy.ndarray, shape (4, 4)
        The rigid transform with unit scale from the source's own world coordinates (BVH units,
        Y up) to the world the results use (mm, Z up): a similarity transform, rotation times
        ``mm_per_unit``, no translation; ``world = M[:3, :3] @ p`` (see :func:`world_from_source_matrix`).
    mm_per_unit : float
    unit_name : str
        Key of :data:`UNIT_SCALES`, or ``"custom"``.
    bvh : BvhClip
        The source clip (after :func:`resample`: the resampled clip, Euler angles re-derived).
    """

    name: str
    source_path: Path | None
    frame_rate: float
    frame_times: np.ndarray = field(repr=False)
    joints: np.ndarray = field(repr=False)
    positions: np.ndarray = field(repr=False)
    end_sites: np.ndarray = field(repr=False)
    parents: np.ndarray = field(repr=False)
    joint_names: list[str] = field(repr=False)
    skeleton_map: SkeletonMap = field(repr=False)
    world_from_source: np.ndarray = field(repr=False)
    mm_per_unit: float
    unit_name: str
    bvh: BvhClip = field(repr=False)

    @property
    def frames(self) -> int:
        """Number of frames ``T``."""
        return int(self.joints.shape[0])

    @property
    def duration_s(self) -> float:
        """``frames / frame_rate`` seconds."""
        return self.frames / self.frame_rate


def _to_world(points: np.ndarray, world_from_source: np.ndarray) -> np.ndarray:
    return points @ world_from_source[:3, :3].T


def _build_clip(
    bvh: BvhClip,
    local_rot: np.ndarray,
    local_trans: np.ndarray,
    frame_rate: float,
    unit: tuple[float, str],
    smap: SkeletonMap,
    name: str,
    source_path: Path | None,
) -> MocapClip:
    pos, _, ends = forward_kinematics(bvh.parents, local_rot, local_trans, bvh.end_site_offsets)
    m = world_from_source_matrix(unit[0])
    positions = _to_world(pos, m)
    end_sites = _to_world(ends, m)
    return MocapClip(
        name=name,
        source_path=source_path,
        frame_rate=float(frame_rate),
        frame_times=np.arange(positions.shape[0]) / float(frame_rate),
        joints=smap.joints15(positions, end_sites),
        positions=positions,
        end_sites=end_sites,
        parents=bvh.parents,
        joint_names=bvh.joint_names,
        skeleton_map=smap,
        world_from_source=m,
        mm_per_unit=unit[0],
        unit_name=unit[1],
        bvh=bvh,
    )


def clip_from_bvh(
    bvh: BvhClip,
    fps: float | None = None,
    unit_scale: float | str | None = None,
    style: str = "cmu",
    name: str | None = None,
) -> MocapClip:
    """Build a :class:`MocapClip` from a parsed BVH (see :func:`load_clip`)."""
    if bvh.frames < 1:
        raise FormatError("the clip has no frames", path=bvh.path)
    unit = _resolve_unit(bvh, unit_scale)
    smap = map_skeleton(bvh, style)
    if name is None:
        name = bvh.path.stem if bvh.path is not None else "clip"
    if fps is not None:
        new_bvh, rot, trans = _resample_bvh(bvh, fps)
        return _build_clip(new_bvh, rot, trans, float(fps), unit, smap, name, bvh.path)
    motion = bvh.motion
    return _build_clip(
        bvh,
        _local_rotations_from_motion(bvh.joints, motion),
        _local_translations_from_motion(bvh.joints, motion),
        bvh.frame_rate,
        unit,
        smap,
        name,
        bvh.path,
    )


def load_clip(
    path: str | Path,
    fps: float | None = None,
    unit_scale: float | str | None = None,
    style: str = "cmu",
) -> MocapClip:
    """Load a BVH clip as ground truth in the swarmpose world.

    Parameters
    ----------
    path : str or pathlib.Path
        BVH file.
    fps : float, optional
        Resample to this frame rate (:func:`resample`); ``None`` keeps the file's rate.
    unit_scale : float, str or None
        ``None``: :func:`infer_unit_scale`; a key of :data:`UNIT_SCALES`; or millimetres per unit.
    style : str, default "cmu"
        Skeleton style (:data:`SKELETON_STYLES`).

    Returns
    -------
    MocapClip

    Raises
    ------
    DataError
        The file cannot be read.
    FormatError
        Malformed BVH, or the skeleton does not match the style.
    ConfigError
        Bad ``fps`` or ``unit_scale``.
    """
    return clip_from_bvh(read_bvh(path), fps=fps, unit_scale=unit_scale, style=style)


# ---------------------------------------------------------------------- the subject of a clip
def subject_from_clip(spec: BodySpec, clip: MocapClip, measurements: SubjectMeasurements | None = None) -> Subject:
    """Measure a subject for ``spec`` (``balan31`` or ``full45`` layout) from a clip's skeleton.

    The rest pose of ``clip.bvh`` gives the points of :func:`swarmpose.body.subject.subject_from_rest_points`;
    ``measurements`` (optional) size the cones.

    Raises
    ------
    ConfigError
        A file written by ``swarmpose export`` lacks joints the model needs.
    """
    pos, ends = clip.bvh.rest_positions()
    sm = clip.skeleton_map
    if sm.style == "swarmpose":  # an exported file: its tips are joints, its End Sites made up
        ends = pos
        needed = {"l_foot": "l_toe", "l_hand": "l_hand_tip", "neck_to_head": "head"}
        missing = [j for o, j in needed.items() if o in spec.default_subject.offsets and j not in clip.joint_names]
        if missing:
            raise ConfigError(f"{clip.source_path}: the {spec.name} model needs the joints {', '.join(missing)}, "
                              "which this exported file has not (export a model that has them, e.g. full45)")

    def point(name: str) -> np.ndarray:
        j = sm.joint(name)
        return ends[j] if sm.from_end_site[sm.joint_index.index(j)] and name == "head_top" else pos[j]

    points = {name: point(name) for name in JOINTS15}
    points.update(head=pos[sm.head], l_toe=pos[sm.l_toe], r_toe=pos[sm.r_toe], l_hand_tip=ends[sm.l_hand_tip],
                  r_hand_tip=ends[sm.r_hand_tip])
    return subject_from_rest_points(spec, points, clip.mm_per_unit, name=clip.name,
                                    source=f"rest pose of {clip.source_path}", measurements=measurements)


# ---------------------------------------------------------------------- resampling
def _sample_positions(n_frames: int, source_rate: float, fps: float) -> np.ndarray:
    """Fractional source-frame positions ``s_k = k * source_rate / fps`` of the target frames
    ``t_k = k / fps`` inside the captured span ``[0, (n_frames - 1) / source_rate]``."""
    ratio = source_rate / fps
    ratio_int = round(ratio)
    if abs(ratio - ratio_int) <= 1e-9 * ratio and ratio_int >= 1:
        # integer step: exact subsampling (no rounding in k * ratio)
        return np.arange(0, n_frames, ratio_int, dtype=np.float64)
    count = int(math.floor((n_frames - 1) / ratio + 1e-9)) + 1
    s = np.arange(count) * source_rate / fps  # s_k = k * rate / fps (exact where it is an integer)
    nearest = np.round(s)
    s = np.where(np.abs(s - nearest) <= 1e-9, nearest, s)
    return np.minimum(s, n_frames - 1)


def _euler_from_matrices(mats: np.ndarray, seq: str, ref_deg: np.ndarray) -> np.ndarray:
    """Euler angles (degrees, intrinsic ``seq`` = channel order) of ``mats`` (K, 3, 3), choosing of the
    two solutions the one closest to ``ref_deg`` (K, 3) and unwrapping each angle to within 180 deg
    of it."""
    rot = Rotation.from_matrix(mats)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gimbal lock: the rotation is still exact
        a = rot.as_euler(seq.upper(), degrees=True)
    b = np.stack([a[:, 0] + 180.0, 180.0 - a[:, 1], a[:, 2] + 180.0], axis=1)  # the other solution

    def near(x: np.ndarray) -> np.ndarray:
        return ref_deg + (x - ref_deg + 180.0) % 360.0 - 180.0

    a, b = near(a), near(b)
    use_b = np.abs(b - ref_deg).sum(axis=1) < np.abs(a - ref_deg).sum(axis=1)
    return np.where(use_b[:, None], b, a)


def _resample_bvh(bvh: BvhClip, fps: float) -> tuple[BvhClip, np.ndarray, np.ndarray]:
    fps = float(fps)
    if not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"fps must be finite and > 0, got {fps!r}")
    if bvh.frames < 1:
        raise FormatError("cannot resample a clip without frames", path=bvh.path)
    n = bvh.frames
    s = _sample_positions(n, bvh.frame_rate, fps)
    i0 = np.minimum(np.floor(s).astype(np.int64), n - 1)
    frac = s - i0
    i1 = np.minimum(i0 + 1, n - 1)
    exact = frac == 0.0

    # channels: linear interpolation (positions; also the fallback for odd rotation channels)
    src = bvh.motion
    motion = src[i0] + frac[:, None] * (src[i1] - src[i0])
    motion[exact] = src[i0[exact]]

    src_rot = _local_rotations_from_motion(bvh.joints, src)  # (F, J, 3, 3)
    rot = src_rot[i0].copy()
    inexact = ~exact
    linear_joints = []
    if inexact.any():
        times = np.arange(n, dtype=np.float64)
        for j, joint in enumerate(bvh.joints):
            cols = [joint.channel_start + k for k, c in enumerate(joint.channels) if c.endswith("rotation")]
            if not cols:
                continue
            axes = "".join(joint.channels[c - joint.channel_start][0] for c in cols)
            if len(axes) != 3 or len(set(axes)) != 3:
                # fewer than three distinct rotation axes: keep the linearly interpolated channel
                # values and the rotation they describe, so the clip and its angles agree
                linear_joints.append(j)
                continue
            # slerp between the neighbouring source frames
            rot[inexact, j] = Slerp(times, Rotation.from_matrix(src_rot[:, j]))(s[inexact]).as_matrix()
            sub = np.ix_(inexact, cols)
            motion[sub] = _euler_from_matrices(rot[inexact, j], axes, motion[sub])
        if linear_joints:
            lin_rot = _local_rotations_from_motion(bvh.joints, motion[inexact])
            for j in linear_joints:
                rot[inexact, j] = lin_rot[:, j]
    trans = _local_translations_from_motion(bvh.joints, motion)  # position channels: linear
    new = BvhClip(path=bvh.path, joints=bvh.joints, frame_time=1.0 / fps, motion=motion)
    return new, rot, trans


def resample(clip: MocapClip | BvhClip, fps: float) -> MocapClip | BvhClip:
    """Resample a clip to another frame rate.

    Target times are ``t_k = k / fps`` inside the captured span ``[0, (F - 1) / rate]`` (a sample
    needs a frame on each side; ``rate`` is the source's :attr:`~swarmpose.io.bvh.BvhClip.frame_rate`,
    120.0 for ``Frame Time: .0083333``). Each joint's local rotation is interpolated by quaternion
    slerp between the two neighbouring source frames, position channels (root translation)
    linearly, then forward kinematics. When ``rate / fps`` is an integer the result is exactly the
    subsampled source (every ``rate / fps``-th frame, starting at frame 0).

    Parameters
    ----------
    clip : MocapClip or BvhClip
    fps : float
        Target frame rate, > 0 (60, 30, 25, 20, 12, ... ; upsampling works too).

    Returns
    -------
    MocapClip or BvhClip
        Same type as ``clip``. A returned :class:`BvhClip` has ``frame_time = 1 / fps`` and its
        rotation channels re-derived from the interpolated rotations as Euler angles in each joint's
        channel order (the solution nearest the linearly interpolated angles; frames that coincide
        with source frames are copied unchanged). Joints with fewer than three distinct rotation
        channels are interpolated linearly in their channel values.
    """
    if isinstance(clip, MocapClip):
        new_bvh, rot, trans = _resample_bvh(clip.bvh, fps)
        return _build_clip(new_bvh, rot, trans, float(fps), (clip.mm_per_unit, clip.unit_name),
                           clip.skeleton_map, clip.name, clip.source_path)
    if isinstance(clip, BvhClip):
        return _resample_bvh(clip, fps)[0]
    raise ConfigError(f"resample expects a MocapClip or BvhClip, got {type(clip).__name__}")

