"""Mocap (``.mat`` cache / ``.c3d``), the subject's measurements and HumanEva's ground truth (the
``cur_frame`` rule, facts section 4.2)."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.body.measurements import SubjectMeasurements, limb_table
from swarmpose.datasets.humaneva.calibration import mp_value
from swarmpose.datasets.humaneva.files import _loadmat
from swarmpose.datasets.humaneva.layout import MOCAP_RATE
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError

HEAD_LENGTH_MM = 316.103
PELVIS_SHIFT_MM = -50.0

#: The 39 Plug-in-Gait markers that must be present for a valid frame (alternatives in a tuple).
VALIDITY_MARKERS: tuple[tuple[str, ...], ...] = tuple(
    (m,) if isinstance(m, str) else m for m in (
        "RASI", "LASI", "LPSI", "RELB", "STRN", "LTHI", "LWRA", "LELB", "T10", "RWRA", "RUPA", "RKNE",
        "RBAK", "LKNE", "CLAV", "RSHO", "LSHO", "C7", "RTIB", "LTIB", "LBHD", "RBHD", "RFHD", "LFHD",
        "LANK", "LHEE", "RANK", "LTOE", "RTOE", "RHEE", "LFIN", ("RFRM", "RFRA"), ("LFRM", "LFRA"),
        "RWRB", "RFIN", "LWRB", "RTHI", "LUPA", "RPSI"))

#: Virtual-marker groups whose ``...O`` label is followed by the z, x and y axis points.
SEGMENT_GROUPS: tuple[str, ...] = ("PELO", "TRXO", "HEDO", "LFEO", "LTIO", "RFEO", "RTIO", "LHUO", "LRAO",
                                   "RHUO", "RRAO")
#: Joint-centre labels used as positions.
JOINT_LABELS: tuple[str, ...] = ("PELO", "TRXO", "LFEP", "RFEP", "LFEO", "RFEO", "LTIO", "RTIO", "LCLO", "RCLO",
                                 "LHUO", "RHUO", "LRAO", "RRAO")

#: The 20 points of HumanEva's ``body_pose`` in the order used by :attr:`GroundTruth.points20`.
BODY_POSE20: tuple[str, ...] = (
    "torsoProximal", "torsoDistal",
    "upperLArmProximal", "upperLArmDistal", "lowerLArmProximal", "lowerLArmDistal",
    "upperRArmProximal", "upperRArmDistal", "lowerRArmProximal", "lowerRArmDistal",
    "upperLLegProximal", "upperLLegDistal", "lowerLLegProximal", "lowerLLegDistal",
    "upperRLegProximal", "upperRLegDistal", "lowerRLegProximal", "lowerRLegDistal",
    "headProximal", "headDistal",
)
_P20 = {n: i for i, n in enumerate(BODY_POSE20)}
#: JOINTS15 order -> the one or two body_pose points it is made of (midpoint of two).
JOINTS15_FROM_20: tuple[tuple[str, ...], ...] = (
    ("torsoProximal", "headProximal"), ("torsoDistal",),
    ("upperLArmProximal",), ("upperLArmDistal", "lowerLArmProximal"), ("lowerLArmDistal",),
    ("upperRArmProximal",), ("upperRArmDistal", "lowerRArmProximal"), ("lowerRArmDistal",),
    ("upperLLegProximal",), ("upperLLegDistal", "lowerLLegProximal"), ("lowerLLegDistal",),
    ("upperRLegProximal",), ("upperRLegDistal", "lowerRLegProximal"), ("lowerRLegDistal",),
    ("headDistal",),
)


# ---------------------------------------------------------------------- mocap (.mat / .c3d)
@dataclass(frozen=True, eq=False)
class MocapMarkers:
    """Marker trajectories of one C3D trial, as the support code sees them.

    Attributes
    ----------
    labels : tuple of str
        ``M`` marker labels (trailing blanks stripped).
    markers : numpy.ndarray, shape (T, M, 3)
        Positions in mm, frame-major; a lost marker is (0, 0, 0).
    frame_rate : float
        Mocap frames per second (120 for HumanEva).
    path : pathlib.Path or None
    """

    labels: tuple[str, ...]
    markers: np.ndarray
    frame_rate: float = MOCAP_RATE
    path: Path | None = None

    @property
    def n_frames(self) -> int:
        """``T``."""
        return int(self.markers.shape[0])

    def find(self, name: str) -> int | None:
        """0-based index of the first label containing ``name`` (MATLAB ``findstr``), or None."""
        for i, lab in enumerate(self.labels):
            if name in lab:
                return i
        return None

    def index(self, name: str) -> int:
        """Like :meth:`find`, raising :class:`FormatError` (naming the file) when absent."""
        i = self.find(name)
        if i is None:
            raise FormatError(f"no marker label contains {name!r}", path=self.path, field=name)
        return i

    def missing_labels(self) -> list[str]:
        """Labels the ground truth needs that this trial lacks (validity, virtual and joint markers)."""
        missing = [" or ".join(alt) for alt in VALIDITY_MARKERS if all(self.find(a) is None for a in alt)]
        missing += [n for n in (*SEGMENT_GROUPS, *JOINT_LABELS) if self.find(n) is None]
        for g in SEGMENT_GROUPS:
            i = self.find(g)
            if i is not None and i + 3 >= len(self.labels):
                missing.append(f"the 3 axis markers after {g}")
        return sorted(set(missing), key=missing.index)


def _mat_strings(obj: Any) -> list[str]:
    """Flatten a loadmat value (str, char/object arrays, nested cells) into a list of strings."""
    if isinstance(obj, str):
        return [obj]
    if isinstance(obj, bytes):
        return [obj.decode("latin-1")]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind == "U":
            return [str(x) for x in obj.ravel()]
        if obj.dtype == object:
            out: list[str] = []
            for x in obj.ravel():
                out.extend(_mat_strings(x))
            return out
    return []


def _mat_list(obj: Any) -> list[Any]:
    if isinstance(obj, np.ndarray) and obj.dtype == object:
        return list(obj.ravel())
    if obj is None or (isinstance(obj, np.ndarray) and obj.size == 0):
        return []
    return [obj]


def _point_labels(pg: Any, path: Path) -> list[str]:
    groups = _mat_list(pg)
    point = None
    for g in groups:
        name = "".join(_mat_strings(getattr(g, "name", None)))
        if "POINT" in name:
            point = g  # the support code keeps the last match
    if point is None:
        raise FormatError("ParameterGroup has no 'POINT' group (marker labels)", path=path, field="ParameterGroup")
    params = {}
    for prm in _mat_list(getattr(point, "Parameter", None)):
        pname = "".join(_mat_strings(getattr(prm, "name", None))).strip()
        if pname.startswith("LABELS"):
            params[pname] = prm
    if not params:
        raise FormatError("POINT group has no LABELS parameter", path=path, field="ParameterGroup.POINT.LABELS")

    def order(k: str) -> int:
        suffix = k[len("LABELS"):]
        return int(suffix) if suffix.isdigit() else (1 if suffix == "" else 10_000)

    labels: list[str] = []
    for k in sorted(params, key=order):
        labels.extend(s.strip() for s in _mat_strings(getattr(params[k], "data", None)))
    if not labels:
        raise FormatError("POINT:LABELS holds no strings", path=path, field="ParameterGroup.POINT.LABELS")
    return labels


def _markers_array(raw: Any, n_labels: int, path: Path) -> np.ndarray:
    try:
        m = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormatError("'Markers' must be a numeric array", path=path, field="Markers") from None
    if m.ndim == 2 and m.shape[1] == 3:  # a single marker squeezed away
        m = m[:, None, :]
    if m.ndim != 3 or m.shape[2] != 3:
        raise FormatError(f"'Markers' must have shape (frames, markers, 3), got {m.shape}", path=path, field="Markers")
    if m.shape[1] != n_labels and m.shape[0] == n_labels:
        m = m.transpose(1, 0, 2)  # markers x frames x 3, as the reader's comment claims
    if m.shape[0] < 1:
        raise FormatError("'Markers' has no frames", path=path, field="Markers")
    if not np.isfinite(m).all():
        raise FormatError("'Markers' holds non-finite values (lost markers must be 0, 0, 0)", path=path,
                          field="Markers")
    return np.ascontiguousarray(m)


def _fit_labels(labels: list[str], n: int) -> tuple[str, ...]:
    return tuple(labels[:n]) + ("",) * max(0, n - len(labels))


def read_mocap_mat(path: str | os.PathLike[str]) -> MocapMarkers:
    """Read the support code's ``.mat`` cache of a C3D trial (``scipy.io.loadmat``, no pickles).

    Needs ``Markers`` (frames x markers x 3, mm) and ``ParameterGroup`` with ``POINT``/``LABELS``;
    ``VideoFrameRate`` (the mocap rate) defaults to 120.

    Raises
    ------
    DataError
        Missing or unreadable file.
    FormatError
        Not a readable MATLAB v4-v7 file (v7.3/HDF5 is not supported), or missing/malformed fields.
    """

    p = Path(path)
    data = _loadmat(p, "mocap file (.mat)", " (or remove it so that the .c3d beside it is read)")
    for key in ("Markers", "ParameterGroup"):
        if key not in data:
            raise FormatError(f"missing variable {key!r}", path=p, field=key)
    labels = _point_labels(data["ParameterGroup"], p)
    markers = _markers_array(data["Markers"], len(labels), p)
    rate = MOCAP_RATE
    if "VideoFrameRate" in data:
        try:
            rate = float(np.asarray(data["VideoFrameRate"], dtype=np.float64).ravel()[0])
        except (TypeError, ValueError, IndexError):
            raise FormatError("'VideoFrameRate' must be a number", path=p, field="VideoFrameRate") from None
        if not (math.isfinite(rate) and rate > 0):
            raise FormatError(f"'VideoFrameRate' must be > 0, got {rate!r}", path=p, field="VideoFrameRate")
    return MocapMarkers(_fit_labels(labels, markers.shape[1]), markers, rate, p)


def read_c3d(path: str | os.PathLike[str]) -> MocapMarkers:
    """Read a Vicon C3D trial with ``ezc3d`` or the ``c3d`` package; invalid points become (0, 0, 0).

    ``ezc3d`` is used when installed, else ``c3d`` (pure Python; what ``swarmpose[humaneva]``
    installs). Labels of ``POINT:LABELS`` (and ``LABELS2``...) are stripped of padding.

    Raises
    ------
    DataError
        Missing file, or neither reader is installed (install ``swarmpose[humaneva]``, or place the
        support code's ``.mat`` cache beside the ``.c3d``).
    FormatError
        The C3D file cannot be parsed.
    """
    p = Path(path)
    if not p.is_file():
        raise DataError(f"{p}: missing mocap file (.c3d)")
    try:
        import ezc3d  # type: ignore[import-not-found]
    except ImportError:
        ezc3d = None
    if ezc3d is not None:
        try:
            c = ezc3d.c3d(str(p))
            pts = np.asarray(c["data"]["points"], dtype=np.float64)  # (4, M, T)
            labels = [str(s).strip() for s in c["parameters"]["POINT"]["LABELS"]["value"]]
            for extra in ("LABELS2", "LABELS3"):
                if extra in c["parameters"]["POINT"]:
                    labels += [str(s).strip() for s in c["parameters"]["POINT"][extra]["value"]]
            rate = float(np.ravel(c["parameters"]["POINT"]["RATE"]["value"])[0])
        except Exception as exc:  # ezc3d raises RuntimeError/IndexError/KeyError on bad input
            raise FormatError(f"cannot parse C3D ({type(exc).__name__}: {exc})", path=p) from None
        xyz = np.transpose(pts[:3], (2, 1, 0))
        xyz = np.where(np.isfinite(xyz), xyz, 0.0)  # ezc3d marks invalid points NaN; HumanEva uses 0
        return MocapMarkers(_fit_labels(labels, xyz.shape[1]), np.ascontiguousarray(xyz), rate, p)
    try:
        import c3d as c3dpkg  # type: ignore[import-not-found]
    except ImportError:
        raise DataError(f"{p}: reading .c3d needs a C3D reader (the 'c3d' or 'ezc3d' package): pip install "
                        f"'swarmpose[humaneva]' (or put the HumanEva support code's cached "
                        f"{p.with_suffix('.mat').name} beside it)") from None
    try:
        with open(p, "rb") as fh:
            reader = c3dpkg.Reader(fh)
            labels = [str(s).strip() for s in reader.point_labels]
            rate = float(reader.point_rate)
            frames = []
            for _, points, _ in reader.read_frames():
                xyz = np.array(points[:, :3], dtype=np.float64)
                xyz[points[:, 3] < 0] = 0.0  # residual -1 = invalid point
                frames.append(xyz)
    except Exception as exc:
        raise FormatError(f"cannot parse C3D ({type(exc).__name__}: {exc})", path=p) from None
    if not frames:
        raise FormatError("C3D file holds no frames", path=p)
    m = np.stack(frames)
    return MocapMarkers(_fit_labels(labels, m.shape[1]), m, rate, p)


def read_mocap(path: str | os.PathLike[str]) -> MocapMarkers:
    """Read a trial from ``.mat`` (preferred when it sits beside the ``.c3d``) or ``.c3d``."""
    p = Path(path)
    if p.suffix.lower() == ".mat":
        return read_mocap_mat(p)
    mat = p.with_suffix(".mat")
    if mat.is_file():
        return read_mocap_mat(mat)
    return read_c3d(p)


# ---------------------------------------------------------------------- ground truth
def _zero(points: np.ndarray) -> np.ndarray:
    """True where a marker is (0, 0, 0) (lost)."""
    return np.all(points == 0.0, axis=-1)


def limb_lengths(mocap: MocapMarkers) -> np.ndarray:
    """The 18 limb lengths of ``ComputeLimbLengths`` (mm), mean over frames with both markers present.

    Slots (1-based as in the facts, section 5.1): 1 torso, 2 left asis, 3 L thigh, 4 L shank, 5 L foot
    (0), 6-9 right side, 10 L thorax-clavicle, 11 L upper arm, 12 L forearm, 13 L hand (0), 14-17
    right side, 18 head (316.103). NaN where a pair is never seen together.
    """
    pairs = [("TRXO", "PELO"), ("PELO", "LFEP"), ("LFEP", "LFEO"), ("LFEO", "LTIO"), None,
             ("PELO", "RFEP"), ("RFEP", "RFEO"), ("RFEO", "RTIO"), None,
             ("TRXO", "LCLO"), ("LCLO", "LHUO"), ("LHUO", "LRAO"), None,
             ("TRXO", "RCLO"), ("RCLO", "RHUO"), ("RHUO", "RRAO"), None]
    out = np.zeros(18)
    m = mocap.markers
    for k, pair in enumerate(pairs):
        if pair is None:
            continue
        a, b = m[:, mocap.index(pair[0])], m[:, mocap.index(pair[1])]
        ok = ~(_zero(a) | _zero(b))
        out[k] = float(np.linalg.norm(a[ok] - b[ok], axis=1).mean()) if ok.any() else np.nan
    out[17] = HEAD_LENGTH_MM
    return out


def subject_measurements(static: MocapMarkers, mp: Mapping[str, float], mp_path: object = None
                         ) -> SubjectMeasurements:
    """The subject's measurements: marker distances from ``static`` and the ``.mp`` widths and offsets.

    Marker distances are means over every frame of ``static`` (as the support code; a lost marker
    counts as 0).
    """
    m = static.markers

    def mean_dist(a: str, b: str) -> float:
        return float(np.linalg.norm(m[:, static.index(a)] - m[:, static.index(b)], axis=1).mean())

    def val(n: str) -> float:
        return mp_value(mp, n, mp_path)

    try:
        return SubjectMeasurements(
            shoulder_markers=mean_dist("LSHO", "RSHO"), sternum_t10=mean_dist("STRN", "T10"),
            l_knee_width=val("LKneeWidth"), r_knee_width=val("RKneeWidth"),
            l_ankle_width=val("LAnkleWidth"), r_ankle_width=val("RAnkleWidth"),
            l_elbow_width=val("LElbowWidth"), r_elbow_width=val("RElbowWidth"),
            l_wrist_width=val("LWristWidth"), r_wrist_width=val("RWristWidth"),
            l_shoulder_offset=val("LShoulderOffset"), r_shoulder_offset=val("RShoulderOffset"),
            head_diagonal=mean_dist("LBHD", "RFHD"), head_front=mean_dist("LFHD", "RFHD"),
            head_offset_deg=val("HeadOffset"),
            source=f"{static.path} (markers), {mp_path} (.mp)")
    except FormatError as exc:
        raise FormatError(f"{exc} (static trial {static.path}, subject file {mp_path})") from None


def limb_parameters(static: MocapMarkers, mp: Mapping[str, float], mp_path: object = None) -> np.ndarray:
    """The 10 x 5 cone parameters of ``ComputeLimbParameters`` (facts section 5.2).

    Rows: torso, L thigh, L calf, R thigh, R calf, L upper arm, L lower arm, R upper arm, R lower arm,
    head; columns: proximal radius, distal radius, x-scale, y-scale, (head only) head offset in rad.
    The rules are :func:`swarmpose.body.measurements.limb_table`.
    """
    return limb_table(subject_measurements(static, mp, mp_path))


def _yrot_t(theta: np.ndarray) -> np.ndarray:
    """The support code's ``yRotation(theta)``: the *transposed* rotation about y, shape (..., 3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, z, -s], -1), np.stack([z, o, z], -1), np.stack([s, z, c], -1)], -2)


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """HumanEva ground truth at fractional mocap positions.

    Attributes
    ----------
    positions : numpy.ndarray, shape (F,)
        1-based fractional mocap positions.
    points20 : numpy.ndarray, shape (F, 20, 3)
        The :data:`BODY_POSE20` points, mm; NaN rows where invalid.
    joints15 : numpy.ndarray, shape (F, 15, 3)
        :data:`swarmpose.joints.JOINTS15`, mm (double joints = midpoints); NaN rows where invalid.
    valid : numpy.ndarray, shape (F,), bool
    """

    positions: np.ndarray
    points20: np.ndarray
    joints15: np.ndarray
    valid: np.ndarray


def joints15_from_points20(points20: np.ndarray) -> np.ndarray:
    """``(..., 20, 3)`` :data:`BODY_POSE20` points -> ``(..., 15, 3)`` JOINTS15 (double joints: midpoints)."""
    p = np.asarray(points20, dtype=np.float64)
    if p.shape[-2:] != (20, 3):
        raise ShapeError(f"points20 must have shape (..., 20, 3), got {p.shape}")
    return np.stack([np.mean([p[..., _P20[n], :] for n in names], axis=0) for names in JOINTS15_FROM_20], axis=-2)


def humaneva_ground_truth(mocap: MocapMarkers, positions: np.ndarray, *, torso_radius: float,
                          l_shoulder_offset: float, r_shoulder_offset: float) -> GroundTruth:
    """The ``cur_frame`` ground truth at fractional mocap positions (facts section 4.2).

    Parameters
    ----------
    mocap : MocapMarkers
        The trial (Plug-in-Gait virtual markers and the 39 validity markers).
    positions : array_like, shape (F,)
        1-based fractional mocap positions (:meth:`SyncInfo.mocap_position`), in ``[1, T]``.
    torso_radius : float
        ``Params(1, 1)`` of :func:`limb_parameters` (mm): tilts the torso by ``atan2(r/2, L_torso)``.
    l_shoulder_offset, r_shoulder_offset : float
        ``LShoulderOffset``/``RShoulderOffset`` from the ``.mp`` file (mm): tilt the upper arms.

    Returns
    -------
    GroundTruth

    Raises
    ------
    FormatError
        A needed marker label is missing from the trial.
    ConfigError
        A position outside ``[1, T]``.
    """
    from scipy.spatial.transform import Rotation

    missing = mocap.missing_labels()
    if missing:
        raise FormatError(f"missing marker labels {missing}", path=mocap.path, field="POINT:LABELS")
    p = np.asarray(positions, dtype=np.float64).reshape(-1)
    T = mocap.n_frames
    if p.size and (not np.isfinite(p).all() or p.min() < 1 or p.max() > T):
        raise ConfigError(f"mocap positions must lie in [1, {T}], got {p.min():.3f}..{p.max():.3f}")
    m = mocap.markers
    f0 = np.floor(p).astype(np.int64) - 1  # 0-based floor(p)
    alpha = p - np.floor(p)
    c0 = np.where(alpha > 0, f0 + 1, f0)  # floor(p) + 1 (only when it has weight)
    cl0 = np.ceil(p).astype(np.int64) - 1  # ceil(p), used for lengths and validity
    c0 = np.minimum(c0, T - 1)
    cl0 = np.minimum(cl0, T - 1)
    F = p.size
    if F == 0:
        return GroundTruth(positions=p, points20=np.zeros((0, 20, 3)), joints15=np.zeros((0, 15, 3)),
                           valid=np.zeros(0, dtype=bool))
    valid = np.ones(F, dtype=bool)

    for alt in VALIDITY_MARKERS:  # sum of coordinates == 0 counts as lost (support-code test)
        i = min(mocap.index(a) for a in alt if mocap.find(a) is not None)
        valid &= (m[f0, i].sum(-1) != 0) & (m[cl0, i].sum(-1) != 0)

    def pos(label: str) -> np.ndarray:
        i = mocap.index(label)
        a, b = m[f0, i], m[c0, i]
        valid[:] &= ~(_zero(a) | _zero(b))
        return (1.0 - alpha)[:, None] * a + alpha[:, None] * b

    def length(la: str, lb: str) -> np.ndarray:  # LimbLength over frames floor(p), ceil(p)
        ia, ib = mocap.index(la), mocap.index(lb)
        d, n = np.zeros(F), np.zeros(F)
        for fr in (f0, cl0):
            a, b = m[fr, ia], m[fr, ib]
            ok = ~(_zero(a) | _zero(b))
            d += np.where(ok, np.linalg.norm(a - b, axis=-1), 0.0)
            n += ok
        valid[:] &= n > 0
        return d / np.maximum(n, 1)

    def frame(group: str) -> np.ndarray:  # global_from_local rotations (F, 3, 3)
        i = mocap.index(group)
        mats = []
        for fr in (f0, c0):
            o, pz, px, py = m[fr, i], m[fr, i + 1], m[fr, i + 2], m[fr, i + 3]
            bad = _zero(o) | _zero(pz) | _zero(px) | _zero(py)
            axes = []
            for q in (px, py, pz):
                v = q - o
                n = np.linalg.norm(v, axis=-1, keepdims=True)
                bad |= n[:, 0] == 0
                axes.append(v / np.where(n == 0, 1.0, n))
            x, y, z = axes
            ortho = np.maximum.reduce([np.abs((x * y).sum(-1)), np.abs((x * z).sum(-1)), np.abs((y * z).sum(-1))])
            R = np.stack([x, y, z], axis=-1)  # columns = local axes in world
            bad |= (ortho > 1e-4) | ~(np.linalg.det(R) > 0)
            R[bad] = np.eye(3)
            valid[:] &= ~bad
            mats.append(R)
        Rf = Rotation.from_matrix(mats[0])
        Rc = Rotation.from_matrix(mats[1])
        rel = (Rf.inv() * Rc).as_rotvec()
        return (Rf * Rotation.from_rotvec(rel * alpha[:, None])).as_matrix()  # slerp(Rf, Rc, alpha)

    def apply(R: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.einsum("fij,fj->fi", R, v)

    zeros = np.zeros(F)

    def vec(x: Any, y: Any, z: Any) -> np.ndarray:
        return np.stack(np.broadcast_arrays(np.asarray(x, float) + zeros, np.asarray(y, float) + zeros,
                                            np.asarray(z, float) + zeros), axis=-1)

    L1 = length("TRXO", "PELO")
    L3, L4 = length("LFEP", "LFEO"), length("LFEO", "LTIO")
    L7, L8 = length("RFEP", "RFEO"), length("RFEO", "RTIO")
    L11, L12 = length("LCLO", "LHUO"), length("LHUO", "LRAO")
    L15, L16 = length("RCLO", "RHUO"), length("RHUO", "RRAO")

    pts = np.zeros((F, 20, 3))
    # torso: pelvis frame moved -50 mm along local x, tilted by yRotation(atan2(r_t / 2, L1))
    R_pel = frame("PELO")
    o_pel = pos("PELO") + apply(R_pel, vec(PELVIS_SHIFT_MM, 0, 0))
    R_tilt = R_pel @ _yrot_t(np.arctan2(torso_radius / 2.0, L1))
    pts[:, _P20["torsoDistal"]] = o_pel
    pts[:, _P20["torsoProximal"]] = o_pel + apply(R_tilt, vec(0, 0, L1))
    # head: thorax origin, head frame's +z for 316.103 mm
    trx = pos("TRXO")
    R_head = frame("HEDO")
    pts[:, _P20["headProximal"]] = trx
    pts[:, _P20["headDistal"]] = trx + apply(R_head, vec(0, 0, HEAD_LENGTH_MM))
    # legs: frames flipped 180 deg about y, so the distal points lie along -z of the PiG frames
    for side, La, Lb in (("L", L3, L4), ("R", L7, L8)):
        hip, knee = pos(f"{side}FEP"), pos(f"{side}FEO")
        R_fe, R_ti = frame(f"{side}FEO"), frame(f"{side}TIO")
        pts[:, _P20[f"upper{side}LegProximal"]] = hip
        pts[:, _P20[f"upper{side}LegDistal"]] = hip + apply(R_fe, vec(0, 0, -La))
        pts[:, _P20[f"lower{side}LegProximal"]] = knee
        pts[:, _P20[f"lower{side}LegDistal"]] = knee + apply(R_ti, vec(0, 0, -Lb))
    # arms: upper arm tilted by yRotation(-atan2(offset / 2, L)), forearm re-attached and tilted back
    for side, La, Lb, off in (("L", L11, L12, l_shoulder_offset), ("R", L15, L16, r_shoulder_offset)):
        sho, elb = pos(f"{side}CLO"), pos(f"{side}HUO")
        R_hu, R_ra = frame(f"{side}HUO"), frame(f"{side}RAO")
        theta = np.arctan2(off / 2.0, La)
        diff = elb - (sho + apply(R_hu, vec(0, 0, -La)))
        R_hu2 = R_hu @ _yrot_t(-theta)
        upper_distal = sho + apply(R_hu2, vec(0, 0, -La))
        elbow = upper_distal + diff
        R_ra2 = R_ra @ _yrot_t(theta)
        pts[:, _P20[f"upper{side}ArmProximal"]] = sho
        pts[:, _P20[f"upper{side}ArmDistal"]] = upper_distal
        pts[:, _P20[f"lower{side}ArmProximal"]] = elbow
        pts[:, _P20[f"lower{side}ArmDistal"]] = elbow + apply(R_ra2, vec(0, 0, -Lb))
    valid &= np.isfinite(pts).all(axis=(1, 2))
    pts[~valid] = np.nan
    return GroundTruth(positions=p, points20=pts, joints15=joints15_from_points20(pts), valid=valid)
