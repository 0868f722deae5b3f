"""A body model instance: a :class:`~swarmpose.body.spec.BodySpec` plus a subject's measurements.

The instance compiles the tree to flat arrays once (:class:`KinematicArrays`, :class:`ConeArrays`)
and offers batched kinematics on ``(N, D)`` pose arrays: joint transforms, the 15 HumanEva joints
and the placed truncated cones.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from swarmpose.body.kinematics import (
    KinematicArrays,
    forward_kinematics,
    forward_kinematics_reference,
)
from swarmpose.body.spec import AXES, BodySpec, Subject, load_spec
from swarmpose.errors import ConfigError, ShapeError

__all__ = ["BodyModel", "ConeArrays", "PlacedCones", "load_model", "JOINTS_CHUNK"]

#: Poses per step of :meth:`BodyModel.joints15` (the whole track of a long recording is taken in steps).
JOINTS_CHUNK = 1024


@dataclass(frozen=True)
class ConeArrays:
    """The cones compiled to arrays (what numba kernels take). ``K`` cones.

    Attributes
    ----------
    joint : (K,) int64, joint frame the cone is fixed to.
    start, end : (K, 3) float64, axis end points in the joint frame (mm).
    radii : (K, 2) float64, radius at ``start`` and at ``end`` (mm).
    scale : (K, 2) float64, cross-section scale along the joint frame's x and y axes.
    """

    names: tuple[str, ...]
    sides: tuple[str, ...]
    joint: np.ndarray
    start: np.ndarray
    end: np.ndarray
    radii: np.ndarray
    scale: np.ndarray

    def index(self, name: str) -> int:
        return self.names.index(name)


@dataclass(frozen=True)
class PlacedCones:
    """Cones placed in the world for a batch of poses.

    Attributes
    ----------
    start, end : (N, K, 3) axis end points in world mm.
    axis_x, axis_y : (N, K, 3) world directions of the cross-section's semi-axes (unit vectors).
    semi_x, semi_y : (K, 2) semi-axis lengths (mm) at start and end: ``radii * scale``.
    """

    start: np.ndarray
    end: np.ndarray
    axis_x: np.ndarray
    axis_y: np.ndarray
    semi_x: np.ndarray
    semi_y: np.ndarray


class BodyModel:
    """Kinematic tree + truncated cones for one subject.

    Parameters
    ----------
    spec : the body-model specification (see :func:`swarmpose.body.spec.load_spec`).
    subject : measurements; missing entries fall back to the spec's default subject, names the spec does
        not have are refused (a typo would otherwise be ignored).
    variant : name of a cone variant in the spec (e.g. ``"thesis"``: the modifications of thesis
        sec. 5.1.2) or ``None`` for the unmodified cones.
    """

    def __init__(self, spec: BodySpec, subject: Subject | None = None, variant: str | None = None):
        self.spec = spec
        base = spec.default_subject
        subject = subject or base
        for kind, given, known in (("offset", subject.offsets, base.offsets), ("cone", subject.cones, base.cones)):
            unknown = sorted(set(given) - set(known))
            if unknown:
                where = f" ({subject.source})" if subject.source else ""
                raise ConfigError(f"subject {subject.name!r}{where} has {kind}s that body model {spec.name!r} does "
                                  f"not have: {', '.join(unknown)} (known: {', '.join(known)})")
        offsets = {**base.offsets, **subject.offsets}
        cones = {**base.cones, **subject.cones}
        self.subject = Subject(name=subject.name, offsets=offsets, cones=cones, source=subject.source)
        if variant is not None and variant not in spec.variants:
            raise ConfigError(f"body model {spec.name!r} has no cone variant {variant!r} "
                              f"(known: {', '.join(spec.variants) or 'none'})")
        self.variant = variant
        self.kin = self._compile_kinematics()
        self.cone_arrays = self._compile_cones()

    # ----------------------------------------------------------------- parameter layout
    @property
    def name(self) -> str:
        return self.spec.name

    @cached_property
    def param_names(self) -> tuple[str, ...]:
        return self.spec.param_names

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @cached_property
    def sigma(self) -> np.ndarray:
        """Per-parameter motion-model standard deviation at 60 fps, ``(D,)`` (rad / mm)."""
        return _ro(np.array([p.sigma for p in self.spec.parameters]))

    @cached_property
    def lower(self) -> np.ndarray:
        return _ro(np.array([p.lower for p in self.spec.parameters]))

    @cached_property
    def upper(self) -> np.ndarray:
        return _ro(np.array([p.upper for p in self.spec.parameters]))

    @cached_property
    def is_rotation(self) -> np.ndarray:
        return _ro(np.array([p.kind == "rotation" for p in self.spec.parameters]))

    @cached_property
    def groups(self) -> dict[str, np.ndarray]:
        """Parameter indices per named group (``root_orientation``, ``left_leg``, ...)."""
        out: dict[str, list[int]] = {}
        for i, p in enumerate(self.spec.parameters):
            for g in (p.group, *p.tags):
                out.setdefault(g, []).append(i)
        groups = {k: np.array(v, dtype=np.int64) for k, v in out.items()}
        # Composite groups used by staged searches (thesis Table 6.1; Sharifi et al. sec. 3.4).
        if "root_orientation" in groups and "root_position" in groups:
            groups["root"] = np.concatenate([groups["root_orientation"], groups["root_position"]])
            groups["torso"] = np.concatenate([groups["root"]] + [groups[g] for g in ("spine",) if g in groups])
        for g in groups.values():
            g.setflags(write=False)
        return groups

    def group(self, name: str) -> np.ndarray:
        """Indices of the parameters in group ``name``; ``KeyError`` lists the known groups."""
        try:
            return self.groups[name]
        except KeyError:
            raise KeyError(f"body model {self.name!r} has no parameter group {name!r} "
                           f"(known: {', '.join(sorted(self.groups))})") from None

    def param_index(self, name: str) -> int:
        try:
            return self.param_names.index(name)
        except ValueError:
            raise KeyError(f"body model {self.name!r} has no parameter {name!r}") from None

    def zero_pose(self) -> np.ndarray:
        """The all-zero pose ``(D,)`` (upright, arms hanging, at the world origin)."""
        return np.zeros(self.n_params)

    def check_poses(self, poses: np.ndarray, name: str = "poses") -> np.ndarray:
        """Return ``poses`` as a float64 ``(N, D)`` array; a ``(D,)`` pose becomes a batch of one."""
        arr = np.asarray(poses, dtype=np.float64)
        if arr.ndim == 1:
            arr = arr[None]
        if arr.ndim != 2 or arr.shape[1] != self.n_params:
            raise ShapeError(f"{name}: expected shape (N, {self.n_params}) for body model {self.name!r}, "
                             f"got {np.shape(poses)}")
        return arr

    def within_limits(self, poses: np.ndarray) -> np.ndarray:
        """``(N,)`` bool: every parameter inside ``[lower, upper]``."""
        p = self.check_poses(poses)
        return np.all((p >= self.lower) & (p <= self.upper), axis=1)

    # ----------------------------------------------------------------- kinematics
    @cached_property
    def joint_index(self) -> dict[str, int]:
        return {n: i for i, n in enumerate(self.spec.joint_names)}

    @cached_property
    def joints15_index(self) -> np.ndarray:
        """Joint-frame index of each of the 15 HumanEva joints (their origins are the joints)."""
        return _ro(np.array([self.joint_index[n] for n in self.spec.joints15], dtype=np.int64))

    def forward(self, poses: np.ndarray, *, reference: bool = False) -> np.ndarray:
        """``world_from_joint`` transforms ``(N, J, 3, 4)`` for poses ``(N, D)``."""
        p = self.check_poses(poses)
        if reference:
            return forward_kinematics_reference(p, self.kin)
        return forward_kinematics(p, self.kin)

    def joint_positions(self, poses: np.ndarray, *, reference: bool = False) -> np.ndarray:
        """Origins of all joint frames, ``(N, J, 3)`` mm."""
        return self.forward(poses, reference=reference)[..., 3]

    def joints15(self, poses: np.ndarray, *, reference: bool = False) -> np.ndarray:
        """The 15 HumanEva joints ``(N, 15, 3)`` in mm, order of :data:`swarmpose.joints.JOINTS15`.

        Computed :data:`JOINTS_CHUNK` poses at a time, so that a long recording's whole track (20,000 frames)
        does not hold every joint frame's transform at once (100 MB)."""
        p = self.check_poses(poses)
        if len(p) <= JOINTS_CHUNK:
            return self.joint_positions(p, reference=reference)[:, self.joints15_index]
        out = np.empty((len(p), len(self.joints15_index), 3))
        for a in range(0, len(p), JOINTS_CHUNK):
            out[a:a + JOINTS_CHUNK] = self.joint_positions(p[a:a + JOINTS_CHUNK], reference=reference)[:, self.joints15_index]
        return out

    def cones(self, poses: np.ndarray, transforms: np.ndarray | None = None) -> PlacedCones:
        """Place the truncated cones in the world for poses ``(N, D)``."""
        T = self.forward(poses) if transforms is None else transforms
        ca = self.cone_arrays
        Tk = T[:, ca.joint]  # (N, K, 3, 4)
        R, t = Tk[..., :3], Tk[..., 3]
        start = t + np.einsum("nkab,kb->nka", R, ca.start)
        end = t + np.einsum("nkab,kb->nka", R, ca.end)
        return PlacedCones(start=start, end=end, axis_x=R[..., 0].copy(), axis_y=R[..., 1].copy(),
                           semi_x=ca.radii * ca.scale[:, :1], semi_y=ca.radii * ca.scale[:, 1:])

    # ----------------------------------------------------------------- compilation
    def _compile_kinematics(self) -> KinematicArrays:
        spec = self.spec
        J = len(spec.joints)
        pidx = {n: i for i, n in enumerate(spec.param_names)}
        jidx = {j.name: i for i, j in enumerate(spec.joints)}
        parents = np.full(J, -1, dtype=np.int64)
        offsets = np.zeros((J, 3))
        rot_axis = np.full((J, 3), -1, dtype=np.int64)
        rot_sign = np.ones((J, 3))
        rot_param = np.zeros((J, 3), dtype=np.int64)
        trans_param = np.full((J, 3), -1, dtype=np.int64)
        for j, js in enumerate(spec.joints):
            if js.parent is not None:
                parents[j] = jidx[js.parent]
            if js.offset is not None:
                offsets[j] = self.subject.offsets[js.offset]
            if len(js.rotation) > 3:
                raise ConfigError(f"joint {js.name!r}: at most 3 elementary rotations are supported")
            for k, (ax, pn) in enumerate(js.rotation):
                rot_axis[j, k] = AXES[ax.lstrip("-")]
                rot_sign[j, k] = -1.0 if ax.startswith("-") else 1.0
                rot_param[j, k] = pidx[pn]
            for a, pn in enumerate(js.translation):
                trans_param[j, a] = pidx[pn]
        arrays = [parents, offsets, rot_axis, rot_sign, rot_param, trans_param]
        for a in arrays:
            a.setflags(write=False)
        return KinematicArrays(*arrays)

    def _compile_cones(self) -> ConeArrays:
        spec = self.spec
        jidx = {j.name: i for i, j in enumerate(spec.joints)}
        changes = spec.variants.get(self.variant, {}) if self.variant else {}
        K = len(spec.cones)
        joint = np.empty(K, dtype=np.int64)
        start = np.empty((K, 3))
        end = np.empty((K, 3))
        radii = np.empty((K, 2))
        scale = np.empty((K, 2))
        for k, c in enumerate(spec.cones):
            mod = changes.get(c.name, {})
            axis = np.array(self.subject.offsets[c.axis])
            r0, r1, sx, sy = self.subject.cones[c.name]
            length_scale = float(mod.get("length", 1.0))
            s0 = c.start_frac + float(mod.get("start_shift", 0.0))
            joint[k] = jidx[c.joint]
            start[k] = axis * s0
            end[k] = axis * (s0 + (c.end_frac - c.start_frac) * length_scale)
            thick = float(mod.get("thickness", 1.0))
            radii[k] = (r0 * thick, r1 * thick)
            scale[k] = (sx, sy)
        for a in (joint, start, end, radii, scale):
            a.setflags(write=False)
        return ConeArrays(names=tuple(c.name for c in spec.cones), sides=tuple(c.side for c in spec.cones),
                          joint=joint, start=start, end=end, radii=radii, scale=scale)

    def with_subject(self, subject: Subject) -> BodyModel:
        return BodyModel(self.spec, subject, self.variant)

    def __repr__(self) -> str:
        return (f"BodyModel({self.name!r}, subject={self.subject.name!r}, variant={self.variant!r}, "
                f"D={self.n_params}, joints={self.kin.n_joints}, cones={len(self.cone_arrays.names)})")


def load_model(name: str = "balan31", subject: Subject | None = None, variant: str | None = "default") -> BodyModel:
    """Load a shipped or file body model; ``variant="default"`` picks the spec's default variant."""
    spec = load_spec(name)
    if variant == "default":
        variant = "thesis" if "thesis" in spec.variants else None
    return BodyModel(spec, subject, variant)


def _ro(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a
