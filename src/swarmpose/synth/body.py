"""The observation body: a detailed mesh person driven by a motion-capture skeleton.

This is the body the synthetic cameras *see*. It is deliberately **not** the tracker's cone
model (``balan31``): if observations were rendered from the model the tracker fits, every
tracker would look perfect (``shared/design.md`` §4). Shape and sizes are documented in
``docs/observation-body.md``; in short:

* torso = three ellipsoids that follow the spine chain (pelvis, abdomen, chest) plus a
  shoulder "yoke" capsule between the two shoulder joints (balan31: one elliptical cone from the
  pelvis joint to the thorax);
* neck capsule and a head ellipsoid with hair (balan31: an elliptical head cone, no neck);
* limbs = tapered capsules (a cone with a hemisphere on each end) with radii that differ from the
  cones (see the table in the docs);
* hands and feet = ellipsoids (balan31 has neither);
* optional clothing bulk (``BodySettings.clothing_mm``) added to shirt- and trouser-covered parts.

Every part hangs on the clip's BVH joints: a point fixed to joint ``j`` moves as

    p(t) = P_j(t) + Rw_j(t) @ (p_rest - P_j_rest)

where ``P_j(t)`` is the joint's world position (mm, z up), ``p_rest``/``P_j_rest`` are rest-pose
positions (all channels zero) in world axes and ``Rw_j(t) = A @ R_j(t) @ A.T`` is the joint's
global BVH rotation ``R_j(t)`` (``world_from_joint`` in source axes; the identity in the rest pose)
expressed in world axes (``A`` = the rotation part of ``clip.world_from_source``). Joint *positions*
therefore coincide exactly with the clip's ground truth.

Shape letters: ``T`` frames, ``J`` BVH joints, ``V`` mesh vertices, ``F`` triangles, ``P`` parts.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from swarmpose.body.measurements import HALF_MARKER_MM, SubjectMeasurements
from swarmpose.errors import ConfigError, ShapeError
from swarmpose.io.mocap import MocapClip

__all__ = ["BodySettings", "BodyPart", "ObservationBody", "MATERIALS", "REFERENCE_LEG_MM"]

#: Material names, in the order of :attr:`BodySettings.albedo`.
MATERIALS: tuple[str, ...] = ("shirt", "trousers", "skin", "hair", "shoes")

#: Leg length (hip-knee + knee-ankle) for which the sizes in the part table are given, mm.
REFERENCE_LEG_MM = 830.0

_UP = np.array([0.0, 0.0, 1.0])
_LEFT = np.array([1.0, 0.0, 0.0])  # CMU rest pose: +x_source (left) -> +x world
_FWD = np.array([0.0, -1.0, 0.0])  # CMU rest pose: +z_source (forward) -> -y world


@dataclass(frozen=True)
class BodySettings:
    """Size, clothing and mesh resolution of the observation body.

    Parameters
    ----------
    clothing_mm : float, default 10.0
        Extra thickness (mm) added to every semi-axis / radius of shirt- and trouser-covered parts
        (torso, shoulder yoke, upper arms, pelvis, thighs, calves). 0 gives a tight-fitting suit.
    radius_scale : float or None, default None
        Factor on every size of the part table; ``None`` scales by the clip's leg length over
        :data:`REFERENCE_LEG_MM`.
    rings : int, default 9
        Latitude rings of an ellipsoid mesh (poles excluded); capsules get ``rings // 2 + 1``
        rings per end cap.
    segments : int, default 18
        Vertices around each ring.
    albedo : dict, default shirt 0.34, trousers 0.29, skin 0.28, hair 0.20, shoes 0.21
        Grey reflectance per material (fraction of white).
    """

    clothing_mm: float = 10.0
    radius_scale: float | None = None
    rings: int = 9
    segments: int = 18
    albedo: dict[str, float] = field(default_factory=lambda: {
        "shirt": 0.34, "trousers": 0.29, "skin": 0.28, "hair": 0.20, "shoes": 0.21})

    def __post_init__(self) -> None:
        if not (math.isfinite(self.clothing_mm) and 0.0 <= self.clothing_mm <= 100.0):
            raise ConfigError(f"BodySettings.clothing_mm must be in [0, 100] mm, got {self.clothing_mm!r}")
        if self.radius_scale is not None and not (math.isfinite(self.radius_scale) and self.radius_scale > 0):
            raise ConfigError(f"BodySettings.radius_scale must be > 0 or None, got {self.radius_scale!r}")
        if int(self.rings) < 3 or int(self.segments) < 6:
            raise ConfigError(f"BodySettings: rings >= 3 and segments >= 6 needed, got {self.rings}, {self.segments}")
        missing = set(MATERIALS) - set(self.albedo)
        if missing:
            raise ConfigError(f"BodySettings.albedo misses materials {sorted(missing)}")
        for k, v in self.albedo.items():
            if not (0.0 <= float(v) <= 1.0):
                raise ConfigError(f"BodySettings.albedo[{k!r}] must be in [0, 1], got {v!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (for provenance)."""
        return asdict(self)


@dataclass(frozen=True)
class BodyPart:
    """One mesh piece of the observation body (all lengths mm, world axes, rest pose).

    Attributes
    ----------
    name : str
    kind : {"ellipsoid", "capsule"}
    material : str
        One of :data:`MATERIALS`.
    joint : int
        BVH joint whose rotation carries the part (ellipsoid) or the cross-section frame (capsule).
    centre : (3,) float, rest-pose centre (ellipsoid).
    axes : (3, 3) float, rest-pose unit semi-axis directions as *columns* (ellipsoid).
    semi : (3,) float, semi-axis lengths (ellipsoid).
    a_joint, b_joint : int, joints carrying the capsule's end points.
    a_offset, b_offset : (3,) float, rest-pose offset of each end point from its joint.
    radii : (2,) float, capsule radius at ``a`` and at ``b``.
    ref : (3,) float, rest-pose direction that fixes the capsule mesh's roll (not along the axis).
    """

    name: str
    kind: str
    material: str
    joint: int
    centre: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axes: np.ndarray = field(default_factory=lambda: np.eye(3))
    semi: np.ndarray = field(default_factory=lambda: np.ones(3))
    a_joint: int = -1
    b_joint: int = -1
    a_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    b_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    radii: np.ndarray = field(default_factory=lambda: np.ones(2))
    ref: np.ndarray = field(default_factory=lambda: _FWD.copy())

    def describe(self) -> dict[str, Any]:
        """Sizes of the part, JSON-safe (mm)."""
        if self.kind == "ellipsoid":
            return {"name": self.name, "kind": self.kind, "material": self.material,
                    "semi_axes_mm": [round(float(s), 1) for s in self.semi]}
        return {"name": self.name, "kind": self.kind, "material": self.material,
                "radii_mm": [round(float(r), 1) for r in self.radii]}


# ---------------------------------------------------------------------- mesh templates
def _orient_outward(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Flip faces whose normal points towards the origin (templates are star-shaped about it)."""
    v0, v1, v2 = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    n = np.cross(v1 - v0, v2 - v0)
    c = (v0 + v1 + v2) / 3.0
    flip = np.einsum("fi,fi->f", n, c) < 0
    out = faces.copy()
    out[flip] = out[flip][:, [0, 2, 1]]
    return out


def _ring_faces(rings: list[np.ndarray], poles: tuple[int, int]) -> np.ndarray:
    """Triangles joining consecutive vertex rings and the two poles."""
    faces = []
    south, north = poles
    seg = len(rings[0])
    for s in range(seg):
        s2 = (s + 1) % seg
        faces.append((south, rings[0][s2], rings[0][s]))
        faces.append((north, rings[-1][s], rings[-1][s2]))
    for r0, r1 in zip(rings[:-1], rings[1:], strict=True):
        for s in range(seg):
            s2 = (s + 1) % seg
            faces.append((r0[s], r0[s2], r1[s2]))
            faces.append((r0[s], r1[s2], r1[s]))
    return np.array(faces, dtype=np.int64)


def sphere_template(rings: int, segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit UV sphere about the z axis.

    Returns
    -------
    verts : (V, 3) float64, unit vectors.
    faces : (F, 3) int64, outward (counter-clockwise seen from outside).
    """
    lat = -np.pi / 2 + np.pi * np.arange(1, rings + 1) / (rings + 1)
    lon = 2 * np.pi * np.arange(segments) / segments
    verts = [np.array([0.0, 0.0, -1.0])]
    ring_idx = []
    for la in lat:
        idx = np.arange(len(verts), len(verts) + segments)
        ring_idx.append(idx)
        verts.extend(np.stack([np.cos(la) * np.cos(lon), np.cos(la) * np.sin(lon),
                               np.full(segments, np.sin(la))], axis=1))
    verts.append(np.array([0.0, 0.0, 1.0]))
    v = np.array(verts)
    return v, _orient_outward(v, _ring_faces(ring_idx, (0, len(v) - 1)))


def capsule_template(cap_rings: int, segments: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit capsule directions: a hemisphere at end ``a`` (z <= 0) and one at end ``b`` (z >= 0).

    A world vertex is ``end_point[e] + radius[e] * (M @ d)`` with ``M = [e1, e2, u]`` the capsule
    frame, so equal radii give a capsule and unequal radii a tapered one.

    Returns
    -------
    dirs : (V, 3) float64, unit directions.
    end : (V,) int64, 0 for the ``a`` cap, 1 for the ``b`` cap.
    faces : (F, 3) int64, outward.
    """
    lon = 2 * np.pi * np.arange(segments) / segments
    lat_a = -np.pi / 2 + (np.pi / 2) * np.arange(1, cap_rings + 1) / cap_rings  # ... up to 0
    lat_b = (np.pi / 2) * np.arange(0, cap_rings) / cap_rings  # 0 ... below pi/2
    verts = [np.array([0.0, 0.0, -1.0])]
    end = [0]
    ring_idx = []
    for e, lats in ((0, lat_a), (1, lat_b)):
        for la in lats:
            idx = np.arange(len(verts), len(verts) + segments)
            ring_idx.append(idx)
            verts.extend(np.stack([np.cos(la) * np.cos(lon), np.cos(la) * np.sin(lon),
                                   np.full(segments, np.sin(la))], axis=1))
            end.extend([e] * segments)
    verts.append(np.array([0.0, 0.0, 1.0]))
    end.append(1)
    d = np.array(verts)
    e = np.array(end, dtype=np.int64)
    # orient with a proper capsule (ends at z = -1 and +1) so the equator band is well defined
    shape = d + np.where(e[:, None] == 1, 1.0, -1.0) * _UP
    faces = _orient_outward(shape, _ring_faces(ring_idx, (0, len(d) - 1)))
    return d, e, faces


# ---------------------------------------------------------------------- helpers
def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _frame(primary: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Orthonormal columns ``(p, q, p x q)`` with ``p = primary`` and ``q`` = ``ref`` made orthogonal."""
    p = _unit(primary)
    q = ref - np.dot(ref, p) * p
    if np.linalg.norm(q) < 1e-6:
        q = np.cross(p, _LEFT if abs(p[0]) < 0.9 else _FWD)
    q = _unit(q)
    return np.stack([p, q, np.cross(p, q)], axis=1)


def _spine_chain(parents: np.ndarray, thorax_joint: int) -> list[int]:
    """Joints from the root's child up to the thorax joint's parent (the spine)."""
    chain = []
    j = int(parents[thorax_joint])
    while j >= 0 and parents[j] >= 0:
        chain.append(j)
        j = int(parents[j])
    chain.reverse()
    return chain  # may be empty if the thorax hangs directly off the root


# ---------------------------------------------------------------------- the body
class ObservationBody:
    """A triangle-mesh person that follows a :class:`~swarmpose.io.mocap.MocapClip` frame by frame.

    Build it with :meth:`from_clip`. The mesh topology (``faces``, ``face_part``, ``vertex_part``,
    ``vertex_albedo``) is fixed; :meth:`mesh` gives vertex positions and normals of one frame.

    Attributes
    ----------
    parts : tuple of BodyPart
    part_names : tuple of str
    faces : numpy.ndarray, shape (F, 3), int32
        Outward-oriented triangles (counter-clockwise seen from outside).
    face_part : numpy.ndarray, shape (F,), int16
    vertex_part : numpy.ndarray, shape (V,), int16
    vertex_albedo : numpy.ndarray, shape (V,), float32
    settings : BodySettings
    scale : float
        The size factor applied to the part table.
    """

    def __init__(self, parts: list[BodyPart], positions: np.ndarray, rotations: np.ndarray,
                 rest_positions: np.ndarray, settings: BodySettings, scale: float):
        positions = np.asarray(positions, dtype=np.float64)
        rotations = np.asarray(rotations, dtype=np.float64)
        if positions.ndim != 3 or positions.shape[2] != 3:
            raise ShapeError(f"positions must have shape (T, J, 3), got {positions.shape}")
        if rotations.shape != positions.shape[:2] + (3, 3):
            raise ShapeError(f"rotations must have shape {positions.shape[:2] + (3, 3)}, got {rotations.shape}")
        self.parts = tuple(parts)
        self.part_names = tuple(p.name for p in parts)
        self.settings = settings
        self.scale = float(scale)
        self._pos = positions
        self._rot = rotations
        self._rest = np.asarray(rest_positions, dtype=np.float64)
        self.rest_positions = self._rest  # (J, 3) rest pose, world axes, mm
        self._build_topology()

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_clip(cls, clip: MocapClip, settings: BodySettings | None = None) -> ObservationBody:
        """Dress a CMU-style clip's skeleton in the observation body.

        Parameters
        ----------
        clip : MocapClip
            From :func:`swarmpose.io.mocap.load_clip`.
        settings : BodySettings, optional

        Returns
        -------
        ObservationBody
        """
        settings = settings or BodySettings()
        bvh = clip.bvh
        A = clip.world_from_source[:3, :3] / clip.mm_per_unit  # proper rotation, source -> world axes
        rot_src = bvh.global_rotations()  # (T, J, 3, 3) world_from_joint in source axes
        if rot_src.shape[0] != clip.frames:
            raise ShapeError(f"clip.bvh has {rot_src.shape[0]} frames but the clip {clip.frames}")
        rotations = np.einsum("ab,tjbc,dc->tjad", A, rot_src, A)  # A R A^T
        rest_src, rest_end_src = bvh.rest_positions()
        rest = rest_src @ clip.world_from_source[:3, :3].T
        rest_end = rest_end_src @ clip.world_from_source[:3, :3].T
        parts, scale = _build_parts(clip, rest, rest_end, settings)
        return cls(parts, clip.positions, rotations, rest, settings, scale)

    def _build_topology(self) -> None:
        s = self.settings
        sv, sf = sphere_template(int(s.rings), int(s.segments))
        cd, ce, cf = capsule_template(int(s.rings) // 2 + 1, int(s.segments))
        self._sphere = sv
        self._cap_dir, self._cap_end = cd, ce
        ell = [i for i, p in enumerate(self.parts) if p.kind == "ellipsoid"]
        cap = [i for i, p in enumerate(self.parts) if p.kind == "capsule"]
        self._ell, self._cap = np.array(ell, dtype=np.int64), np.array(cap, dtype=np.int64)
        faces, fpart, vpart, albedo = [], [], [], []
        base = 0
        order = ell + cap  # vertex layout: all ellipsoids, then all capsules
        for i in order:
            p = self.parts[i]
            tv, tf = (sv, sf) if p.kind == "ellipsoid" else (cd, cf)
            faces.append(tf + base)
            fpart.append(np.full(len(tf), i))
            vpart.append(np.full(len(tv), i))
            alb = np.full(len(tv), s.albedo[p.material], dtype=np.float64)
            if p.name == "head":  # hair: top and back of the head
                up, fwd = tv[:, 2], tv[:, 1]  # template axes: (lateral, forward, up)
                hair = (up > 0.25) | ((fwd < -0.2) & (up > -0.35))
                alb[hair] = s.albedo["hair"]
            albedo.append(alb)
            base += len(tv)
        self.faces = np.ascontiguousarray(np.concatenate(faces), dtype=np.int32)
        self.face_part = np.concatenate(fpart).astype(np.int16)
        self.vertex_part = np.concatenate(vpart).astype(np.int16)
        self.vertex_albedo = np.concatenate(albedo).astype(np.float32)
        # ellipsoid arrays (E, ...)
        P = self.parts
        self._e_joint = np.array([P[i].joint for i in ell], dtype=np.int64)
        self._e_centre = np.array([P[i].centre for i in ell]).reshape(-1, 3)
        self._e_axes = np.array([P[i].axes for i in ell]).reshape(-1, 3, 3)
        self._e_semi = np.array([P[i].semi for i in ell]).reshape(-1, 3)
        # capsule arrays (K, ...)
        self._c_a = np.array([P[i].a_joint for i in cap], dtype=np.int64)
        self._c_b = np.array([P[i].b_joint for i in cap], dtype=np.int64)
        self._c_aoff = np.array([P[i].a_offset for i in cap]).reshape(-1, 3)
        self._c_boff = np.array([P[i].b_offset for i in cap]).reshape(-1, 3)
        self._c_joint = np.array([P[i].joint for i in cap], dtype=np.int64)
        self._c_ref = np.array([P[i].ref for i in cap]).reshape(-1, 3)
        self._c_radii = np.array([P[i].radii for i in cap]).reshape(-1, 2)

    # ------------------------------------------------------------------ queries
    @property
    def n_frames(self) -> int:
        """Number of frames ``T``."""
        return int(self._pos.shape[0])

    @property
    def n_vertices(self) -> int:
        """Number of mesh vertices ``V``."""
        return int(self.vertex_part.shape[0])

    def part_index(self, name: str) -> int:
        """Index of the part called ``name``."""
        try:
            return self.part_names.index(name)
        except ValueError:
            raise KeyError(f"observation body has no part {name!r} (parts: {', '.join(self.part_names)})") from None

    def describe(self) -> list[dict[str, Any]]:
        """Sizes of every part (JSON-safe), for provenance and the documentation."""
        return [p.describe() for p in self.parts]

    def measurements(self) -> SubjectMeasurements:
        """Measure this body as a motion-capture lab measures a subject (Vicon Plug-in Gait protocol).

        On the rest pose, over the clothing (markers and calipers go on the outer surface):

        * ``LSHO``/``RSHO`` sit on top of the shoulder yoke straight above each shoulder joint, their
          centres 7 mm (half a marker) off the surface, so ``|LSHO - RSHO|`` is the distance of the
          shoulder joints and the shoulder offset is the yoke's radius (surface to joint centre);
        * ``STRN``/``T10`` sit on the front and back of the chest at its deepest point, 7 mm off
          the surface: ``|STRN - T10|`` = the chest's depth + 14 mm;
        * knee, ankle, elbow and wrist widths are caliper widths across the limb at the joint (the
          wider of the two parts meeting there).

        No head band is measured, so the tracker keeps its reference head cone.
        """
        def part(name: str) -> BodyPart:
            return self.parts[self.part_index(name)]

        yoke, chest = part("shoulders"), part("chest")
        shoulders = float(np.linalg.norm(self._rest[yoke.a_joint] + yoke.a_offset
                                         - self._rest[yoke.b_joint] - yoke.b_offset))

        def width(upper: str, lower: str) -> float:
            return 2.0 * max(float(part(upper).radii[1]), float(part(lower).radii[0]))

        return SubjectMeasurements(
            shoulder_markers=shoulders,
            sternum_t10=2.0 * float(chest.semi[2]) + 2.0 * HALF_MARKER_MM,
            l_knee_width=width("l_thigh", "l_calf"), r_knee_width=width("r_thigh", "r_calf"),
            l_ankle_width=2.0 * float(part("l_calf").radii[1]), r_ankle_width=2.0 * float(part("r_calf").radii[1]),
            l_elbow_width=width("l_upper_arm", "l_forearm"), r_elbow_width=width("r_upper_arm", "r_forearm"),
            l_wrist_width=2.0 * float(part("l_forearm").radii[1]),
            r_wrist_width=2.0 * float(part("r_forearm").radii[1]),
            l_shoulder_offset=float(yoke.radii[0]), r_shoulder_offset=float(yoke.radii[1]),
            source="synthetic observation body (rest pose, over clothing)")

    def carry(self, k: int, joints: np.ndarray, offsets_rest: np.ndarray) -> np.ndarray:
        """World positions at frame ``k`` of points fixed to BVH joints.

        Parameters
        ----------
        k : int
            Frame index.
        joints : numpy.ndarray, shape (n,), int
            BVH joint of each point.
        offsets_rest : numpy.ndarray, shape (n, 3)
            Rest-pose offset of each point from its joint, world axes, mm.

        Returns
        -------
        numpy.ndarray, shape (n, 3)
            ``P_j(k) + Rw_j(k) @ offset`` (see the module docstring).
        """
        joints = np.asarray(joints, dtype=np.int64)
        R = self._rot[k, joints]
        return self._pos[k, joints] + np.einsum("nab,nb->na", R, offsets_rest)

    def mesh(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Vertex positions and normals of frame ``k``.

        Parameters
        ----------
        k : int
            Frame index in ``[0, T)``.

        Returns
        -------
        vertices : numpy.ndarray, shape (V, 3)
            World mm.
        normals : numpy.ndarray, shape (V, 3)
            Unit outward normals (exact for ellipsoids and capsule caps; the cap's radial direction
            on the tapered band).
        """
        if not 0 <= k < self.n_frames:
            raise IndexError(f"frame {k} outside [0, {self.n_frames})")
        # ellipsoids: c = P_j + Rw_j (c_rest - P_j_rest); axes = Rw_j axes_rest
        Rj = self._rot[k, self._e_joint]  # (E, 3, 3)
        c = self.carry(k, self._e_joint, self._e_centre - self._rest[self._e_joint])
        axes = Rj @ self._e_axes  # (E, 3, 3), columns = semi-axis directions
        T = self._sphere  # (v, 3)
        ev = c[:, None, :] + np.einsum("eij,evj->evi", axes, self._e_semi[:, None, :] * T[None])
        en = _unit(np.einsum("eij,evj->evi", axes, T[None] / self._e_semi[:, None, :]))
        # capsules: end points carried by their joints, roll by the frame joint's rotation
        a = self.carry(k, self._c_a, self._c_aoff)
        b = self.carry(k, self._c_b, self._c_boff)
        u = _unit(b - a)
        ref = np.einsum("kab,kb->ka", self._rot[k, self._c_joint], self._c_ref)
        e1 = ref - np.einsum("ki,ki->k", ref, u)[:, None] * u
        bad = np.linalg.norm(e1, axis=1) < 1e-6
        if bad.any():  # ref along the axis: any perpendicular will do
            e1[bad] = np.cross(u[bad], np.where(np.abs(u[bad, :1]) < 0.9, _LEFT, _FWD))
        e1 = _unit(e1)
        e2 = np.cross(u, e1)
        M = np.stack([e1, e2, u], axis=2)  # (K, 3, 3) columns
        d = self._cap_dir
        end = self._cap_end
        cn = np.einsum("kij,vj->kvi", M, d)
        ends = np.where(end[None, :, None] == 1, b[:, None, :], a[:, None, :])
        radius = np.where(end[None, :] == 1, self._c_radii[:, 1:2], self._c_radii[:, 0:1])
        cv = ends + radius[..., None] * cn
        verts = np.concatenate([ev.reshape(-1, 3), cv.reshape(-1, 3)])
        normals = np.concatenate([en.reshape(-1, 3), cn.reshape(-1, 3)])
        return verts, normals


# ---------------------------------------------------------------------- the part table
def _build_parts(clip: MocapClip, rest: np.ndarray, rest_end: np.ndarray,
                 s: BodySettings) -> tuple[list[BodyPart], float]:
    """The observation body's parts for a CMU-style skeleton (sizes: docs/observation-body.md)."""
    sm = clip.skeleton_map
    parents = np.asarray(clip.parents)

    def J(name: str) -> int:
        return sm.joint(name)

    def R(name: str) -> np.ndarray:
        return rest[J(name)]

    leg = 0.5 * sum(np.linalg.norm(R(f"{x}_knee") - R(f"{x}_hip")) + np.linalg.norm(R(f"{x}_ankle") - R(f"{x}_knee"))
                    for x in ("l", "r"))
    sc = float(s.radius_scale) if s.radius_scale is not None else float(leg / REFERENCE_LEG_MM)
    cloth = float(s.clothing_mm)

    def extra(material: str) -> float:
        return cloth if material in ("shirt", "trousers") else 0.0

    parts: list[BodyPart] = []

    def ellipsoid(name: str, material: str, joint: int, centre: np.ndarray, axes: np.ndarray,
                  semi: tuple[float, float, float]) -> None:
        semi_mm = np.array(semi) * sc + extra(material)
        parts.append(BodyPart(name=name, kind="ellipsoid", material=material, joint=int(joint),
                              centre=np.asarray(centre, float), axes=np.asarray(axes, float), semi=semi_mm))

    def capsule(name: str, material: str, a: int, b: int, r0: float, r1: float, frame_joint: int | None = None,
                a_offset: np.ndarray | None = None, b_offset: np.ndarray | None = None) -> None:
        axis = rest[b] - rest[a]
        ref = _FWD if abs(np.dot(_unit(axis), _FWD)) < 0.9 else _UP
        parts.append(BodyPart(
            name=name, kind="capsule", material=material, joint=int(a if frame_joint is None else frame_joint),
            a_joint=int(a), b_joint=int(b),
            a_offset=np.zeros(3) if a_offset is None else np.asarray(a_offset, float),
            b_offset=np.zeros(3) if b_offset is None else np.asarray(b_offset, float),
            radii=np.array([r0 * sc, r1 * sc]) + extra(material), ref=ref.copy()))

    root = J("pelvis")
    thorax = J("thorax")
    spine = _spine_chain(parents, thorax) or [root]
    chest_joint = int(parents[thorax]) if parents[thorax] >= 0 else root

    # --- torso: pelvis, abdomen, chest ellipsoids along the spine, shoulder yoke
    hips_mid = 0.5 * (R("l_hip") + R("r_hip"))
    hip_half = 0.5 * float(np.linalg.norm(R("l_hip") - R("r_hip")))
    up_torso = _unit(rest[thorax] - rest[root])
    frame_t = _frame(_LEFT, up_torso)  # columns: lateral (left), up, left x up = forward
    ellipsoid("pelvis", "trousers", root, hips_mid + 20.0 * sc * up_torso, frame_t,
              (hip_half / sc + 80.0, 115.0, 100.0))
    spine_len = float(np.linalg.norm(rest[thorax] - rest[root]))
    abd_centre = rest[root] + 0.5 * spine_len * up_torso
    # the spine joint carrying the abdomen: the last chain joint at or below its centre
    heights = [float(np.dot(rest[j] - rest[root], up_torso)) for j in spine]
    abd_joint = spine[0]
    for j, h in zip(spine, heights, strict=True):
        if h <= 0.5 * spine_len + 1e-9:
            abd_joint = j
    ellipsoid("abdomen", "shirt", abd_joint, abd_centre + 5.0 * sc * _FWD, frame_t, (130.0, 110.0, 95.0))
    sh_half = 0.5 * float(np.linalg.norm(R("l_shoulder") - R("r_shoulder")))
    ellipsoid("chest", "shirt", chest_joint, rest[thorax] - 30.0 * sc * up_torso + 10.0 * sc * _FWD, frame_t,
              (sh_half / sc - 15.0, 145.0, 108.0))
    capsule("shoulders", "shirt", J("l_shoulder"), J("r_shoulder"), 55.0, 55.0, frame_joint=chest_joint)

    # --- neck and head
    head = sm.head
    head_end = rest_end[head]
    head_vec = head_end - rest[head]
    if not np.all(np.isfinite(head_vec)) or np.linalg.norm(head_vec) < 1e-6:
        head_vec = 95.0 * sc * up_torso
    capsule("neck", "skin", thorax, head, 52.0, 48.0)
    head_axes = _frame(_unit(head_vec), _FWD)  # columns: up, forward, up x forward
    # lateral = forward x up, so that (lateral, fwd, up) stays right-handed: a mirrored frame turns the
    # ellipsoid's triangles inside out, and back-face culling then drew the inside of the back of the head
    head_axes = np.stack([-head_axes[:, 2], head_axes[:, 1], head_axes[:, 0]], axis=1)  # lateral, fwd, up
    head_centre = rest[head] + 0.45 * head_vec + 12.0 * sc * _FWD
    ellipsoid("head", "skin", head, head_centre, head_axes, (74.0, 94.0, 108.0))

    # --- arms and hands
    for x in ("l", "r"):
        sh, el, wr = J(f"{x}_shoulder"), J(f"{x}_elbow"), J(f"{x}_wrist")
        capsule(f"{x}_upper_arm", "shirt", sh, el, 50.0, 40.0)
        capsule(f"{x}_forearm", "skin", el, wr, 41.0, 29.0)
        hand = getattr(sm, f"{x}_hand")
        tip = getattr(sm, f"{x}_hand_tip")
        tip_p = rest_end[tip] if np.all(np.isfinite(rest_end[tip])) else rest[tip]
        axis = tip_p - rest[wr]
        if np.linalg.norm(axis) < 1e-6:
            axis = rest[wr] - rest[el]
        # palm width direction: towards the thumb (the wrist's other child), else forward
        thumbs = [c for c in np.nonzero(parents == wr)[0] if c != hand]
        width_ref = _FWD
        if thumbs:
            t = int(thumbs[0])
            tp = rest_end[t] if np.all(np.isfinite(rest_end[t])) else rest[t]
            if np.linalg.norm(tp - rest[wr]) > 1e-6:
                width_ref = tp - rest[wr]
        hand_len = max(175.0 * sc, float(np.linalg.norm(axis)))
        hand_axes = _frame(axis, width_ref)  # along, width, thickness
        ellipsoid(f"{x}_hand", "skin", hand, rest[wr] + 0.5 * hand_len * hand_axes[:, 0], hand_axes,
                  (0.5 * hand_len / sc, 44.0, 17.0))

    # --- legs and feet
    for x in ("l", "r"):
        hip, knee, ankle = J(f"{x}_hip"), J(f"{x}_knee"), J(f"{x}_ankle")
        capsule(f"{x}_thigh", "trousers", hip, knee, 80.0, 52.0)
        capsule(f"{x}_calf", "trousers", knee, ankle, 52.0, 37.0)
        toe = getattr(sm, f"{x}_toe")
        toe_tip = rest_end[toe] if np.all(np.isfinite(rest_end[toe])) else rest[toe]
        shin_up = _unit(rest[knee] - rest[ankle])
        fwd = toe_tip - rest[ankle]
        fwd = _unit(fwd - np.dot(fwd, shin_up) * shin_up)
        heel = rest[ankle] - 55.0 * sc * fwd - 45.0 * sc * shin_up
        foot_axes = _frame(toe_tip - heel, np.cross(shin_up, fwd))  # along, lateral, vertical
        half = 0.5 * float(np.linalg.norm(toe_tip - heel)) + 10.0 * sc
        ellipsoid(f"{x}_foot", "shoes", ankle, 0.5 * (heel + toe_tip), foot_axes, (half / sc, 46.0, 38.0))
    return parts, sc
