"""Reading Biovision hierarchy (BVH) motion files and their forward kinematics.

A general reader: any BVH, not only the CMU conversions in ``shared/data/mocap``. The file is
kept in its own units and axes (BVH is conventionally Y up); :mod:`swarmpose.io.mocap` converts
to the swarmpose world (millimetres, Z up).

Conventions (the usual BVH ones, as used by the CMU/cgspeed files):

* A joint's local rotation is the product of the elementary rotations in the order its
  ``CHANNELS`` line lists them, for column vectors, angles in degrees:
  ``Zrotation Yrotation Xrotation`` means ``R = Rz(z) @ Ry(y) @ Rx(x)``. ``Rx, Ry, Rz`` are the
  standard right-handed (active) rotations.
* A joint's local translation is its ``OFFSET``; each position channel (``Xposition`` ...)
  *replaces* the matching ``OFFSET`` component (the root ``OFFSET`` of most files is zero, where
  replacing and adding agree).
* Global rotation ``G_j = G_parent @ R_j``; position ``p_j = p_parent + G_parent @ t_j``;
  an end site sits at ``p_j + G_j @ end_site_offset``.

Shape letters: ``F`` frames, ``J`` joints, ``C`` channels.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError

__all__ = [
    "CHANNEL_NAMES",
    "BvhJoint",
    "BvhClip",
    "read_bvh",
    "parse_bvh",
    "elementary_rotations",
    "forward_kinematics",
    "nominal_frame_rate",
]

#: The six channel names a BVH file may use (matched case-insensitively, stored in this spelling).
CHANNEL_NAMES: tuple[str, ...] = (
    "Xposition",
    "Yposition",
    "Zposition",
    "Xrotation",
    "Yrotation",
    "Zrotation",
)
_CHANNEL_LOOKUP = {name.lower(): name for name in CHANNEL_NAMES}
_AXIS = {"X": 0, "Y": 1, "Z": 2}

# Relative tolerance within which 1 / frame_time is taken to be a rounded print of an integer rate.
_RATE_SNAP_RTOL = 5e-5


@dataclass
class BvhJoint:
    """One joint of a BVH hierarchy.

    Attributes
    ----------
    name : str
        Joint name as written after ``ROOT`` / ``JOINT``.
    parent : int
        Index of the parent joint, ``-1`` for a root. Parents always precede children.
    offset : numpy.ndarray, shape (3,)
        ``OFFSET`` in source units, in the parent's frame.
    channels : tuple of str
        Channel names in file order (spelled as in :data:`CHANNEL_NAMES`).
    channel_start : int
        Column of the joint's first channel in :attr:`BvhClip.motion`.
    end_site : numpy.ndarray of shape (3,) or None
        ``OFFSET`` of the joint's ``End Site`` block, if it has one.
    """

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple[str, ...]
    channel_start: int
    end_site: np.ndarray | None = None


@dataclass
class BvhClip:
    """A parsed BVH file: hierarchy plus motion, in the file's own units and axes.

    Attributes
    ----------
    path : pathlib.Path or None
        File the clip was read from (``None`` for clips built in memory).
    joints : list of BvhJoint
        Joints in file order (depth first, parents before children).
    frame_time : float
        Seconds per frame, as written in the file (``Frame Time:``).
    motion : numpy.ndarray, shape (F, C), float64
        One row of channel values per frame; columns follow the joints' channels in file order.
    """

    path: Path | None
    joints: list[BvhJoint]
    frame_time: float
    motion: np.ndarray = field(repr=False)

    def __post_init__(self) -> None:
        self.motion = np.asarray(self.motion, dtype=np.float64)
        n_channels = sum(len(j.channels) for j in self.joints)
        if self.motion.ndim != 2 or self.motion.shape[1] != n_channels:
            raise ShapeError(
                f"motion must have shape (F, {n_channels}) (the sum of the joints' channels), "
                f"got {self.motion.shape}"
            )
        if not (math.isfinite(self.frame_time) and self.frame_time > 0):
            raise ConfigError(f"frame_time must be finite and > 0, got {self.frame_time!r}")

    # ------------------------------------------------------------------ simple properties
    @property
    def frames(self) -> int:
        """Number of frames ``F``."""
        return int(self.motion.shape[0])

    @property
    def n_channels(self) -> int:
        """Number of channels ``C`` (columns of :attr:`motion`)."""
        return int(self.motion.shape[1])

    @property
    def frame_rate(self) -> float:
        """Frames per second, see :func:`nominal_frame_rate` (120.0 for ``Frame Time: .0083333``)."""
        return nominal_frame_rate(self.frame_time)

    @property
    def duration_s(self) -> float:
        """Duration in seconds, ``frames * frame_time`` (as the CMU index lists it)."""
        return self.frames * self.frame_time

    @property
    def joint_names(self) -> list[str]:
        """Joint names in joint order, length ``J``."""
        return [j.name for j in self.joints]

    @property
    def parents(self) -> np.ndarray:
        """Parent index of every joint, shape (J,), int; ``-1`` for roots; ``parents[j] < j``."""
        return np.array([j.parent for j in self.joints], dtype=np.int64)

    @property
    def offsets(self) -> np.ndarray:
        """All ``OFFSET`` vectors, shape (J, 3), source units."""
        return np.array([j.offset for j in self.joints], dtype=np.float64).reshape(-1, 3)

    @property
    def end_site_offsets(self) -> np.ndarray:
        """End-site ``OFFSET`` per joint, shape (J, 3); NaN rows for joints without an end site."""
        out = np.full((len(self.joints), 3), np.nan)
        for j, joint in enumerate(self.joints):
            if joint.end_site is not None:
                out[j] = joint.end_site
        return out

    def children(self, j: int) -> list[int]:
        """Indices of the direct children of joint ``j``, in file order."""
        if not -len(self.joints) <= j < len(self.joints):
            raise IndexError(f"joint index {j} out of range for {len(self.joints)} joints")
        j = j % len(self.joints)
        return [i for i, joint in enumerate(self.joints) if joint.parent == j]

    def joint_index(self, name: str) -> int:
        """Index of the first joint called ``name``; raises ``KeyError`` if there is none."""
        for i, joint in enumerate(self.joints):
            if joint.name == name:
                return i
        raise KeyError(f"no joint named {name!r}")

    # ------------------------------------------------------------------ kinematics
    def _motion_rows(self, frames: slice | Sequence[int] | np.ndarray | int | None) -> np.ndarray:
        if frames is None:
            return self.motion
        if isinstance(frames, (int, np.integer)):
            return self.motion[[int(frames)]]
        return self.motion[frames]

    def local_rotations(self, frames: slice | Sequence[int] | np.ndarray | int | None = None) -> np.ndarray:
        """Local joint rotations from the rotation channels.

        Parameters
        ----------
        frames : slice, int, sequence of int or None
            Frames to use (``None``: all). An int gives a batch of one.

        Returns
        -------
        numpy.ndarray, shape (F, J, 3, 3)
            ``R_j = E_1 @ E_2 @ ...``: the elementary rotations of the joint's rotation channels
            in the order the ``CHANNELS`` line lists them (column vectors, degrees). Joints
            without rotation channels get the identity.
        """
        motion = self._motion_rows(frames)
        return _local_rotations_from_motion(self.joints, motion)

    def local_translations(self, frames: slice | Sequence[int] | np.ndarray | int | None = None) -> np.ndarray:
        """Local joint translations: ``OFFSET`` with position channels replacing components.

        Returns
        -------
        numpy.ndarray, shape (F, J, 3)
            Source units, in the parent's frame.
        """
        motion = self._motion_rows(frames)
        return _local_translations_from_motion(self.joints, motion)

    def root_translation(self, frames: slice | Sequence[int] | np.ndarray | int | None = None) -> np.ndarray:
        """Translation of the first root joint, shape (F, 3), source units.

        The root's position channels; components without a position channel use its ``OFFSET``.
        """
        return self.local_translations(frames)[:, 0, :]

    def global_positions(self, frames: slice | Sequence[int] | np.ndarray | int | None = None) -> np.ndarray:
        """Joint positions by forward kinematics, shape (F, J, 3), source units and axes."""
        motion = self._motion_rows(frames)
        pos, _, _ = forward_kinematics(
            self.parents,
            _local_rotations_from_motion(self.joints, motion),
            _local_translations_from_motion(self.joints, motion),
        )
        return pos

    def global_rotations(self, frames: slice | Sequence[int] | np.ndarray | int | None = None) -> np.ndarray:
        """Joint orientations (source-world from joint-local), shape (F, J, 3, 3)."""
        motion = self._motion_rows(frames)
        _, rot, _ = forward_kinematics(
            self.parents,
            _local_rotations_from_motion(self.joints, motion),
            _local_translations_from_motion(self.joints, motion),
        )
        return rot

    def end_site_positions(self, frames: slice | Sequence[int] | np.ndarray | int | None = None) -> np.ndarray:
        """End-site positions, shape (F, J, 3), source units; NaN rows for joints without one."""
        motion = self._motion_rows(frames)
        _, _, ends = forward_kinematics(
            self.parents,
            _local_rotations_from_motion(self.joints, motion),
            _local_translations_from_motion(self.joints, motion),
            self.end_site_offsets,
        )
        return ends

    def rest_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint and end-site positions of the rest pose (all channels zero, offsets only).

        Position channels of the rest pose take the ``OFFSET`` values.

        Returns
        -------
        joints : numpy.ndarray, shape (J, 3)
        end_sites : numpy.ndarray, shape (J, 3)
            NaN rows for joints without an end site.
        """
        n = len(self.joints)
        rot = np.broadcast_to(np.eye(3), (1, n, 3, 3))
        trans = self.offsets[None]
        pos, _, ends = forward_kinematics(self.parents, rot, trans, self.end_site_offsets)
        return pos[0], ends[0]


# ---------------------------------------------------------------------- kinematics helpers
def nominal_frame_rate(frame_time: float) -> float:
    """Frame rate for a BVH ``Frame Time``.

    BVH files print the frame time rounded (``.0083333`` for 120 Hz, ``0.033333`` for 30 Hz), so
    ``1 / frame_time`` is snapped to the nearest integer when it lies within a relative 5e-5 of
    it; otherwise ``1 / frame_time`` is returned unchanged (e.g. 29.97 Hz stays 29.97).

    Parameters
    ----------
    frame_time : float
        Seconds per frame, > 0.

    Returns
    -------
    float
        Frames per second.
    """
    rate = 1.0 / float(frame_time)
    nearest = round(rate)
    if nearest > 0 and abs(rate - nearest) <= _RATE_SNAP_RTOL * rate:
        return float(nearest)
    return rate


def elementary_rotations(axis: str, angles_deg: np.ndarray) -> np.ndarray:
    """Right-handed rotation matrices about a coordinate axis.

    Parameters
    ----------
    axis : {"X", "Y", "Z"}
    angles_deg : numpy.ndarray, shape (...)
        Angles in degrees.

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        ``Rx = [[1,0,0],[0,c,-s],[0,s,c]]``, ``Ry = [[c,0,s],[0,1,0],[-s,0,c]]``,
        ``Rz = [[c,-s,0],[s,c,0],[0,0,1]]``.
    """
    theta = np.deg2rad(np.asarray(angles_deg, dtype=np.float64))
    c, s = np.cos(theta), np.sin(theta)
    out = np.zeros(theta.shape + (3, 3))
    i = _AXIS[axis.upper()]
    j, k = (i + 1) % 3, (i + 2) % 3
    out[..., i, i] = 1.0
    out[..., j, j] = c
    out[..., k, k] = c
    out[..., j, k] = -s
    out[..., k, j] = s
    return out


def forward_kinematics(
    parents: np.ndarray,
    local_rotations: np.ndarray,
    local_translations: np.ndarray,
    end_site_offsets: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Forward kinematics of a joint tree, vectorised over frames.

    Parameters
    ----------
    parents : numpy.ndarray, shape (J,)
        Parent indices with ``parents[j] < j``; ``-1`` for roots.
    local_rotations : numpy.ndarray, shape (F, J, 3, 3)
        ``parent_from_joint`` rotations.
    local_translations : numpy.ndarray, shape (F, J, 3)
        Joint origins in the parent's frame (for a root: in the source world).
    end_site_offsets : numpy.ndarray of shape (J, 3) or None
        End-site offsets in the joint's frame, NaN rows where there is none.

    Returns
    -------
    positions : numpy.ndarray, shape (F, J, 3)
    rotations : numpy.ndarray, shape (F, J, 3, 3)
        ``world_from_joint`` rotations.
    end_sites : numpy.ndarray of shape (F, J, 3), or None if ``end_site_offsets`` is None
    """
    local_rotations = np.asarray(local_rotations, dtype=np.float64)
    local_translations = np.asarray(local_translations, dtype=np.float64)
    n_frames = max(local_rotations.shape[0], local_translations.shape[0])
    n_joints = len(parents)
    pos = np.empty((n_frames, n_joints, 3))
    rot = np.empty((n_frames, n_joints, 3, 3))
    for j, p in enumerate(parents):
        if p < 0:
            rot[:, j] = local_rotations[:, j]
            pos[:, j] = local_translations[:, j]
        else:
            rot[:, j] = rot[:, p] @ local_rotations[:, j]
            pos[:, j] = pos[:, p] + np.einsum("fab,fb->fa", rot[:, p], local_translations[:, j])
    ends = None
    if end_site_offsets is not None:
        end_site_offsets = np.asarray(end_site_offsets, dtype=np.float64)
        ends = pos + np.einsum("fjab,jb->fja", rot, end_site_offsets)
    return pos, rot, ends


def _local_rotations_from_motion(joints: Sequence[BvhJoint], motion: np.ndarray) -> np.ndarray:
    n_frames = motion.shape[0]
    out = np.empty((n_frames, len(joints), 3, 3))
    out[:] = np.eye(3)
    for j, joint in enumerate(joints):
        mat = None
        for c, name in enumerate(joint.channels):
            if name.endswith("rotation"):
                e = elementary_rotations(name[0], motion[:, joint.channel_start + c])
                mat = e if mat is None else mat @ e
        if mat is not None:
            out[:, j] = mat
    return out


def _local_translations_from_motion(joints: Sequence[BvhJoint], motion: np.ndarray) -> np.ndarray:
    n_frames = motion.shape[0]
    out = np.empty((n_frames, len(joints), 3))
    for j, joint in enumerate(joints):
        out[:, j] = joint.offset
        for c, name in enumerate(joint.channels):
            if name.endswith("position"):
                out[:, j, _AXIS[name[0]]] = motion[:, joint.channel_start + c]
    return out


# ---------------------------------------------------------------------- parsing
_FRAMES_RE = re.compile(r"^frames\s*:\s*(.*)$", re.IGNORECASE)
_FRAME_TIME_RE = re.compile(r"^frame\s+time\s*:\s*(.*)$", re.IGNORECASE)


def read_bvh(path: str | Path) -> BvhClip:
    """Read a BVH file.

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    BvhClip

    Raises
    ------
    DataError
        The file does not exist or cannot be read.
    FormatError
        The file is malformed; the message names the file and the line number (1-based).
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DataError(f"cannot read BVH file {path}: {exc}") from exc
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return parse_bvh(text, path=path)


def parse_bvh(text: str, path: str | Path | None = None) -> BvhClip:
    """Parse BVH text (see :func:`read_bvh`); ``path`` is only used in messages and the result."""
    lines = text.splitlines()
    parser = _HierarchyParser(lines, path)
    joints, motion_line = parser.parse()
    n_channels = sum(len(j.channels) for j in joints)
    frame_time, motion = _parse_motion(lines, motion_line, n_channels, path)
    return BvhClip(path=Path(path) if path is not None else None, joints=joints, frame_time=frame_time,
                   motion=motion)


class _HierarchyParser:
    """Token-by-token parser of the HIERARCHY section (keeps 1-based line numbers)."""

    def __init__(self, lines: list[str], path: str | Path | None):
        self.lines = lines
        self.path = path
        self.joints: list[BvhJoint] = []
        self.has_offset: list[bool] = []
        # stack entries: ("joint", index, open_line) or ("end", joint index, open_line)
        self.stack: list[tuple[str, int, int]] = []
        self.pending: tuple[str, int, int] | None = None
        self.channel_count = 0

    def error(self, message: str, line: int | None) -> FormatError:
        return FormatError(message, path=self.path, line=line)

    def parse(self) -> tuple[list[BvhJoint], int]:
        lines = self.lines
        first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
        if first is None:
            raise self.error("empty file: expected 'HIERARCHY'", None)
        if lines[first].split()[0].upper() != "HIERARCHY":
            raise self.error(f"expected 'HIERARCHY', got {lines[first].strip()[:40]!r}", first + 1)
        rest = lines[first].split()[1:]
        if rest:
            raise self.error(f"unexpected text after 'HIERARCHY': {' '.join(rest)!r}", first + 1)
        for i in range(first + 1, len(lines)):
            tokens = lines[i].split()
            if tokens and tokens[0].upper() == "MOTION":
                self._finish(i + 1)
                if len(tokens) > 1:
                    raise self.error(f"unexpected text after 'MOTION': {' '.join(tokens[1:])!r}", i + 1)
                return self.joints, i
            self._line(tokens, i + 1)
        self._finish(len(lines), eof=True)
        raise self.error("missing 'MOTION' section", len(lines))

    def _finish(self, line: int, eof: bool = False) -> None:
        if self.pending is not None:
            kind, j, open_line = self.pending
            what = "End Site" if kind == "end" else f"joint {self.joints[j].name!r}"
            raise self.error(f"unbalanced braces: expected '{{' after {what} (line {open_line})", line)
        if self.stack:
            kind, j, open_line = self.stack[-1]
            what = "End Site" if kind == "end" else f"joint {self.joints[j].name!r}"
            where = "end of file" if eof else "'MOTION'"
            raise self.error(
                f"unbalanced braces: the block of {what} (line {open_line}) is not closed before {where}",
                line,
            )
        if not self.joints:
            raise self.error("no ROOT joint in HIERARCHY", line)

    def _line(self, tokens: list[str], line: int) -> None:
        k = 0
        while k < len(tokens):
            tok = tokens[k]
            key = tok.upper()
            if key in ("ROOT", "JOINT"):
                name_tokens = tokens[k + 1:]
                trailing_brace = bool(name_tokens) and name_tokens[-1] == "{"
                if trailing_brace:
                    name_tokens = name_tokens[:-1]
                if not name_tokens:
                    raise self.error(f"{tok} without a name", line)
                self._open_joint(key, " ".join(name_tokens), line)
                if trailing_brace:
                    self._open_brace(line)
                return
            if key == "END":
                if k + 1 >= len(tokens) or tokens[k + 1].upper() != "SITE":
                    raise self.error("expected 'End Site'", line)
                if not self.stack or self.stack[-1][0] != "joint" or self.pending is not None:
                    raise self.error("'End Site' outside a joint block", line)
                j = self.stack[-1][1]
                if self.joints[j].end_site is not None:
                    raise self.error(f"joint {self.joints[j].name!r} has two End Sites", line)
                self.pending = ("end", j, line)
                # some exporters name the end site ("End Site LeftToe_End"): ignore the name
                if tokens[-1] == "{" and len(tokens) > k + 2:
                    self._open_brace(line)
                return
            if tok == "{":
                self._open_brace(line)
                k += 1
                continue
            if tok == "}":
                self._close_brace(line)
                k += 1
                continue
            if key == "OFFSET":
                self._offset(tokens[k + 1:k + 4], line)
                k += 4
                continue
            if key == "CHANNELS":
                self._channels(tokens[k + 1:], line)
                return
            raise self.error(f"unexpected token {tok!r} in HIERARCHY", line)

    def _open_joint(self, key: str, name: str, line: int) -> None:
        self._expect_brace(f"{key} {name!r}", line)
        if key == "ROOT":
            if self.stack:
                raise self.error(f"ROOT {name!r} inside another joint's block", line)
            parent = -1
        else:
            if not self.stack or self.stack[-1][0] != "joint":
                raise self.error(f"JOINT {name!r} outside a joint block", line)
            parent = self.stack[-1][1]
        self.joints.append(BvhJoint(name=name, parent=parent, offset=np.zeros(3), channels=(),
                                    channel_start=self.channel_count, end_site=None))
        self.has_offset.append(False)
        self.pending = ("joint", len(self.joints) - 1, line)

    def _open_brace(self, line: int) -> None:
        if self.pending is None:
            raise self.error("unbalanced braces: '{' without ROOT, JOINT or End Site", line)
        self.stack.append(self.pending)
        self.pending = None

    def _close_brace(self, line: int) -> None:
        self._expect_brace("'}'", line)
        if not self.stack:
            raise self.error("unbalanced braces: '}' without a matching '{'", line)
        kind, j, open_line = self.stack.pop()
        if kind == "joint":
            if not self.has_offset[j]:
                raise self.error(f"joint {self.joints[j].name!r} (line {open_line}) has no OFFSET", line)
        elif self.joints[j].end_site is None:
            raise self.error(f"End Site of joint {self.joints[j].name!r} has no OFFSET", line)

    def _expect_brace(self, what: str, line: int) -> None:
        if self.pending is not None:
            kind, j, open_line = self.pending
            owner = "End Site" if kind == "end" else repr(self.joints[j].name)
            raise self.error(f"unbalanced braces: expected '{{' after {owner} (line {open_line}), got {what}", line)

    def _offset(self, values: list[str], line: int) -> None:
        self._expect_brace("OFFSET", line)
        if not self.stack:
            raise self.error("OFFSET outside a joint or End Site block", line)
        if len(values) != 3:
            raise self.error(f"OFFSET needs 3 numbers, got {len(values)}", line)
        vec = np.array([_to_float(v, self.path, line, "OFFSET") for v in values])
        kind, j, _ = self.stack[-1]
        if kind == "end":
            if self.joints[j].end_site is not None:
                raise self.error("End Site has two OFFSET lines", line)
            self.joints[j].end_site = vec
        else:
            if self.has_offset[j]:
                raise self.error(f"joint {self.joints[j].name!r} has two OFFSET lines", line)
            self.joints[j].offset = vec
            self.has_offset[j] = True

    def _channels(self, tokens: list[str], line: int) -> None:
        self._expect_brace("CHANNELS", line)
        if not self.stack:
            raise self.error("CHANNELS outside a joint block", line)
        kind, j, _ = self.stack[-1]
        if kind == "end":
            raise self.error("CHANNELS inside an End Site", line)
        joint = self.joints[j]
        if joint.channels:
            raise self.error(f"joint {joint.name!r} has two CHANNELS lines", line)
        if not tokens:
            raise self.error("CHANNELS without a count", line)
        try:
            count = int(tokens[0])
        except ValueError:
            raise self.error(f"CHANNELS count {tokens[0]!r} is not an integer", line) from None
        names = tokens[1:]
        if count < 0 or count != len(names):
            raise self.error(f"CHANNELS declares {count} channels but lists {len(names)}", line)
        canonical = []
        for name in names:
            c = _CHANNEL_LOOKUP.get(name.lower())
            if c is None:
                raise self.error(
                    f"unknown channel name {name!r} (expected one of {', '.join(CHANNEL_NAMES)})", line
                )
            canonical.append(c)
        if len(set(canonical)) != len(canonical):
            raise self.error(f"repeated channel in CHANNELS: {' '.join(names)}", line)
        joint.channels = tuple(canonical)
        joint.channel_start = self.channel_count
        self.channel_count += count


def _to_float(token: str, path: str | Path | None, line: int, what: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise FormatError(f"{what}: {token!r} is not a number", path=path, line=line) from None
    if not math.isfinite(value):
        raise FormatError(f"{what}: non-finite value {token!r}", path=path, line=line)
    return value


def _parse_motion(
    lines: list[str], motion_line: int, n_channels: int, path: str | Path | None
) -> tuple[float, np.ndarray]:
    i = motion_line + 1
    n = len(lines)

    def next_nonempty(k: int) -> int:
        while k < n and not lines[k].strip():
            k += 1
        return k

    i = next_nonempty(i)
    if i >= n:
        raise FormatError("missing 'Frames:' after MOTION", path=path, line=n)
    m = _FRAMES_RE.match(lines[i].strip())
    if m is None:
        raise FormatError(f"expected 'Frames: <count>', got {lines[i].strip()[:40]!r}", path=path, line=i + 1)
    try:
        frames = int(m.group(1).strip())
    except ValueError:
        raise FormatError(f"Frames count {m.group(1).strip()!r} is not an integer", path=path,
                          line=i + 1) from None
    if frames < 0:
        raise FormatError(f"Frames count must be >= 0, got {frames}", path=path, line=i + 1)
    i = next_nonempty(i + 1)
    if i >= n:
        raise FormatError("missing 'Frame Time:' after Frames", path=path, line=n)
    m = _FRAME_TIME_RE.match(lines[i].strip())
    if m is None:
        raise FormatError(f"expected 'Frame Time: <seconds>', got {lines[i].strip()[:40]!r}", path=path,
                          line=i + 1)
    frame_time = _to_float(m.group(1).strip(), path, i + 1, "Frame Time")
    if frame_time <= 0:
        raise FormatError(f"Frame Time must be > 0, got {frame_time!r}", path=path, line=i + 1)

    motion = np.empty((frames, n_channels))
    row = 0
    last_line = i + 1
    for k in range(i + 1, n):
        tokens = lines[k].split()
        if not tokens:
            continue
        if row >= frames:
            raise FormatError(f"more data lines than Frames: {frames}", path=path, line=k + 1)
        if len(tokens) != n_channels:
            raise FormatError(
                f"frame {row}: expected {n_channels} values (sum of CHANNELS), got {len(tokens)}",
                path=path, line=k + 1,
            )
        try:
            values = np.array(tokens, dtype=np.float64)
        except ValueError:
            bad = next((t for t in tokens if not _is_float(t)), tokens[0])
            col = tokens.index(bad)
            raise FormatError(f"frame {row}: value {col + 1} {bad!r} is not a number", path=path,
                              line=k + 1) from None
        finite = np.isfinite(values)
        if not finite.all():
            col = int(np.argmin(finite))
            raise FormatError(f"frame {row}: value {col + 1} {tokens[col]!r} is not finite", path=path,
                              line=k + 1)
        motion[row] = values
        row += 1
        last_line = k + 1
    if row < frames:
        raise FormatError(
            f"truncated motion: Frames says {frames} but there are only {row} data lines",
            path=path, line=max(last_line, len(lines)),
        )
    return frame_time, motion


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True
