"""Hard priors: joint limits and no inter-penetration of non-adjacent limbs (thesis sec. 5.3.2).

The optimisers call :meth:`HardPriors.valid` to reject candidates (thesis Algorithm 2: a violating
particle's velocity is re-drawn up to 10 times; HumanEva's APF drops such particles).

Inter-penetration follows the idea of PARSEC bodytrack (a cone approximated by a chain of spheres)
with one refinement for elliptical cones: for each collision pair ``(A, B)`` the sphere chain of
``B`` is tested against the *volume* of ``A`` (its elliptical cross-section interpolated along the
axis), so an arm hanging beside the broad torso is fine while an arm through it is not. ``A``'s
volume is the one the renderer draws: elliptical cross-sections in the plane of its joint frame's x
and y axes, centred on the cone's axis, which may be tilted in that frame (the torso's leans from the
pelvis towards the shoulders). A sphere of radius ``rho`` centred at ``start + s * (end - start) +
x * e_x + y * e_y`` collides when ``0 <= s <= 1`` and ``(x / a')**2 + (y / b')**2 < 1`` with
``a' = (1 - tol) * (a(s) + rho)`` (``b'`` alike): ``tol`` is the fraction of the summed radii two
surfaces may sink into each other before it counts (soft tissue, clothing and the coarseness of cones;
default 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from swarmpose.body.kinematics import fk_pose_into
from swarmpose.body.model import BodyModel
from swarmpose.errors import ConfigError

__all__ = ["HardPriors", "pose_valid"]

#: Hash of body/kinematics.py, whose FK the fused kernel calls: numba's cache sees edits to this file only
#: (tests/test_numba_cache.py says when to change it and gives the new value).
INLINED_SOURCES_SHA1 = "53350a34825074f8"


@dataclass
class HardPriors:
    """Batched constraint test for a body model. ``valid(poses (N, D)) -> (N,) bool``.

    Parameters
    ----------
    model : the body model (its limits and ``spec.collision_pairs`` are used).
    penetration_tolerance : see the module docstring; 0 = any contact of the cones is a collision.
    spheres_per_cone : samples along ``B``'s axis.
    check_limits, check_collisions : switch either test off.
    coupled_limits : also reject the regions of the spec's ``coupled_limits`` (every parameter of an entry above
        its value: the shoulders' second branch of angles, where the upper arm hangs twisted beyond its rotation
        limits). Off by default, so the benchmark trackers keep the parameters' own limits; the default tracker
        turns it on (``RefinedConfig.coupled_limits``).
    """

    model: BodyModel
    penetration_tolerance: float = 0.5
    spheres_per_cone: int = 8
    check_limits: bool = True
    check_collisions: bool = True
    coupled_limits: bool = False

    def __post_init__(self) -> None:
        if not 0.0 <= self.penetration_tolerance < 1.0:
            raise ConfigError(f"penetration_tolerance must be in [0, 1), got {self.penetration_tolerance}")
        if self.spheres_per_cone < 2:
            raise ConfigError(f"spheres_per_cone must be at least 2, got {self.spheres_per_cone}")
        names = self.model.cone_arrays.names
        self._pairs = np.array([(names.index(a), names.index(b)) for a, b in self.model.spec.collision_pairs],
                               dtype=np.int64).reshape(-1, 2)
        ca = self.model.cone_arrays
        for a in np.unique(self._pairs[:, 0]):
            if abs(ca.end[a, 2] - ca.start[a, 2]) < 1e-6:
                raise ConfigError(f"collision cone {names[a]!r} lies in its joint frame's x-y plane; its "
                                  "cross-sections (in that plane) would not span a volume")
        self._frac = np.linspace(0.0, 1.0, self.spheres_per_cone)
        limits = self.model.spec.coupled_limits if self.coupled_limits else ()
        width = max((len(c.parameters) for c in limits), default=1)
        # (M, width) parameter indices (-1: none) and the values every one of them must exceed for the pose to be out
        self._coupled_index = np.full((len(limits), width), -1, dtype=np.int64)
        self._coupled_above = np.zeros((len(limits), width))
        for i, c in enumerate(limits):
            self._coupled_index[i, :len(c.parameters)] = [self.model.param_index(n) for n in c.parameters]
            self._coupled_above[i, :len(c.above)] = c.above

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        return self.valid(poses)

    def valid(self, poses: np.ndarray) -> np.ndarray:
        """``(N,)`` True where the pose is inside the joint limits and free of inter-penetration (one numba pass:
        limits, kinematics, collisions; :meth:`valid_reference` is the plain version it is tested against)."""
        p = np.ascontiguousarray(self.model.check_poses(poses))
        out = np.empty(p.shape[0], dtype=np.bool_)
        _valid_kernel(p, *self.kernel_tables(), out)
        return out

    def kernel_tables(self) -> tuple:
        """The arguments of :func:`pose_valid` after the pose and its scratch: limits, coupled limits (none unless
        ``coupled_limits``), kinematic and cone tables, collision pairs (none when ``check_collisions`` is off),
        sphere fractions, ``1 - penetration_tolerance``."""
        ca = self.model.cone_arrays
        pairs = self._pairs if self.check_collisions else self._pairs[:0]
        return (self.model.lower, self.model.upper, self.check_limits, self._coupled_index, self._coupled_above,
                *self.model.kin.as_tuple(), ca.joint, ca.start, ca.end, ca.radii, ca.scale, pairs, self._frac,
                1.0 - self.penetration_tolerance)

    def valid_reference(self, poses: np.ndarray) -> np.ndarray:
        """Plain version of :meth:`valid`: the limits and :meth:`collisions`, as separate batched steps."""
        p = self.model.check_poses(poses)
        ok = np.ones(p.shape[0], dtype=bool)
        if self.check_limits:
            ok &= self.model.within_limits(p)
            for idx, above in zip(self._coupled_index, self._coupled_above, strict=True):
                used = idx >= 0
                ok &= ~np.all(p[:, idx[used]] > above[used], axis=1)
        if self.check_collisions and len(self._pairs):
            ok &= ~self.collisions(p).any(axis=1)
        return ok

    def collisions(self, poses: np.ndarray) -> np.ndarray:
        """``(N, P)`` bool: which collision pair (order of ``spec.collision_pairs``) penetrates.

        Numba kernel; :meth:`collisions_reference` is the plain numpy version it is tested against.
        """
        p = self.model.check_poses(poses)
        T = self.model.forward(p)
        ca = self.model.cone_arrays
        out = np.zeros((p.shape[0], len(self._pairs)), dtype=np.bool_)
        _collisions_kernel(T, ca.joint, ca.start, ca.end, ca.radii, ca.scale, self._pairs, self._frac,
                           1.0 - self.penetration_tolerance, out)
        return out

    def collisions_reference(self, poses: np.ndarray) -> np.ndarray:
        """Plain numpy version of :meth:`collisions`."""
        p = self.model.check_poses(poses)
        cones = self.model.cones(p)
        tol = 1.0 - self.penetration_tolerance
        ca = self.model.cone_arrays
        out = np.zeros((p.shape[0], len(self._pairs)), dtype=bool)
        f = self._frac
        for i, (a, b) in enumerate(self._pairs):
            # spheres of B: centres (N, M, 3), radii (M,) (mean of the two semi-axes)
            rb = 0.5 * (cones.semi_x[b] + cones.semi_y[b])
            rho = rb[0] + (rb[1] - rb[0]) * f
            centres = cones.start[:, b, None] + (cones.end[:, b] - cones.start[:, b])[:, None] * f[None, :, None]
            # B's centres as start + s * axis + x * e_x + y * e_y of A (cross-sections in A's frame x-y plane)
            axis = cones.end[:, a] - cones.start[:, a]
            normal = np.cross(cones.axis_x[:, a], cones.axis_y[:, a])
            d = centres - cones.start[:, a, None]
            s = np.einsum("nmk,nk->nm", d, normal) / np.einsum("nk,nk->n", axis, normal)[:, None]
            r = d - s[..., None] * axis[:, None]
            x = np.einsum("nmk,nk->nm", r, cones.axis_x[:, a])
            y = np.einsum("nmk,nk->nm", r, cones.axis_y[:, a])
            sc = np.clip(s, 0.0, 1.0)
            sa = ca.radii[a, 0] * ca.scale[a, 0] + (ca.radii[a, 1] - ca.radii[a, 0]) * ca.scale[a, 0] * sc
            sb = ca.radii[a, 0] * ca.scale[a, 1] + (ca.radii[a, 1] - ca.radii[a, 0]) * ca.scale[a, 1] * sc
            ax_ = tol * (sa + rho)
            by_ = tol * (sb + rho)
            inside = ((x / ax_) ** 2 + (y / by_) ** 2 < 1.0) & (s >= 0.0) & (s <= 1.0)
            out[:, i] = inside.any(axis=1)
        return out

    def describe(self, pose: np.ndarray) -> list[str]:
        """Human-readable reasons why one pose ``(D,)`` is invalid (empty when it is valid)."""
        p = self.model.check_poses(pose)[:1]
        reasons = []
        m = self.model
        for i, name in enumerate(m.param_names):
            v = p[0, i]
            if not m.lower[i] <= v <= m.upper[i]:
                reasons.append(f"{name} = {np.degrees(v) if m.is_rotation[i] else v:.1f} outside "
                               f"[{np.degrees(m.lower[i]) if m.is_rotation[i] else m.lower[i]:.1f}, "
                               f"{np.degrees(m.upper[i]) if m.is_rotation[i] else m.upper[i]:.1f}]")
        if len(self._pairs):
            hit = self.collisions(p)[0]
            for (a, b), h in zip(m.spec.collision_pairs, hit, strict=True):
                if h:
                    reasons.append(f"{b} penetrates {a}")
        return reasons


@nb.njit(cache=True, nogil=True, inline="always")
def _world(Tj, p):
    """The point ``p (3,)`` of a joint frame in world: ``Tj (3, 4) @ (p, 1)``."""
    return (Tj[0, 3] + Tj[0, 0] * p[0] + Tj[0, 1] * p[1] + Tj[0, 2] * p[2],
            Tj[1, 3] + Tj[1, 0] * p[0] + Tj[1, 1] * p[1] + Tj[1, 2] * p[2],
            Tj[2, 3] + Tj[2, 0] * p[0] + Tj[2, 1] * p[1] + Tj[2, 2] * p[2])


@nb.njit(cache=True, nogil=True, inline="always")
def segment_distance2(p0, p1, p2, q0, q1, q2, r0, r1, r2, t0, t1, t2):
    """Squared distance between the segments ``p -> q`` and ``r -> t`` (closest points, clamped to both)."""
    d10, d11, d12 = q0 - p0, q1 - p1, q2 - p2
    d20, d21, d22 = t0 - r0, t1 - r1, t2 - r2
    w0, w1, w2 = p0 - r0, p1 - r1, p2 - r2
    a = d10 * d10 + d11 * d11 + d12 * d12
    e = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * w0 + d21 * w1 + d22 * w2
    if a <= 1e-12 and e <= 1e-12:
        return w0 * w0 + w1 * w1 + w2 * w2
    if a <= 1e-12:
        u = 0.0
        v = min(max(f / e, 0.0), 1.0)
    else:
        c = d10 * w0 + d11 * w1 + d12 * w2
        if e <= 1e-12:
            v = 0.0
            u = min(max(-c / a, 0.0), 1.0)
        else:
            b = d10 * d20 + d11 * d21 + d12 * d22
            den = a * e - b * b
            u = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 1e-12 else 0.0
            v = (b * u + f) / e
            if v < 0.0:
                v = 0.0
                u = min(max(-c / a, 0.0), 1.0)
            elif v > 1.0:
                v = 1.0
                u = min(max((b - c) / a, 0.0), 1.0)
    x0 = p0 + d10 * u - (r0 + d20 * v)
    x1 = p1 + d11 * u - (r1 + d21 * v)
    x2 = p2 + d12 * u - (r2 + d22 * v)
    return x0 * x0 + x1 * x1 + x2 * x2


@nb.njit(cache=True, nogil=True, inline="always")
def _pair_hits(T, a, b, joint, start, end, radii, scale, frac, keep):
    """Whether a sphere of cone ``b``'s chain lies in cone ``a``'s volume, for one pose's transforms ``T``.

    A sphere centre that collides lies within ``keep * (max a-radius * max scale + max sphere radius)`` of a point
    of ``a``'s axis segment (its offset from the axis point at its ``s`` is the cross-section's ``(x, y)``), and the
    centres lie on ``b``'s axis segment: axes farther apart than that, plus 1 mm, cannot collide, and the spheres
    are not tested (the same answers, fewer operations)."""
    Ta = T[joint[a]]
    Tb = T[joint[b]]
    # A's and B's axes in world
    sa0, sa1, sa2 = _world(Ta, start[a])
    ea0, ea1, ea2 = _world(Ta, end[a])
    sb0, sb1, sb2 = _world(Tb, start[b])
    eb0, eb1, eb2 = _world(Tb, end[b])
    reach = keep * (max(radii[a, 0], radii[a, 1]) * max(scale[a, 0], scale[a, 1])
                    + 0.5 * max(radii[b, 0], radii[b, 1]) * (scale[b, 0] + scale[b, 1])) + 1.0
    if segment_distance2(sa0, sa1, sa2, ea0, ea1, ea2, sb0, sb1, sb2, eb0, eb1, eb2) > reach * reach:
        return False
    # axis . e_z of A's frame: the axis's rise out of the cross-section plane (checked non-zero)
    rise = (ea0 - sa0) * Ta[0, 2] + (ea1 - sa1) * Ta[1, 2] + (ea2 - sa2) * Ta[2, 2]
    rb0 = 0.5 * (radii[b, 0] * scale[b, 0] + radii[b, 0] * scale[b, 1])
    rb1 = 0.5 * (radii[b, 1] * scale[b, 0] + radii[b, 1] * scale[b, 1])
    for m in range(frac.shape[0]):
        f = frac[m]
        rho = rb0 + (rb1 - rb0) * f
        d0 = sb0 + (eb0 - sb0) * f - sa0
        d1 = sb1 + (eb1 - sb1) * f - sa1
        d2 = sb2 + (eb2 - sb2) * f - sa2
        s = (d0 * Ta[0, 2] + d1 * Ta[1, 2] + d2 * Ta[2, 2]) / rise
        if s < 0.0 or s > 1.0:
            continue
        r0 = d0 - s * (ea0 - sa0)
        r1 = d1 - s * (ea1 - sa1)
        r2 = d2 - s * (ea2 - sa2)
        x = r0 * Ta[0, 0] + r1 * Ta[1, 0] + r2 * Ta[2, 0]
        y = r0 * Ta[0, 1] + r1 * Ta[1, 1] + r2 * Ta[2, 1]
        ra = radii[a, 0] + (radii[a, 1] - radii[a, 0]) * s
        axl = keep * (ra * scale[a, 0] + rho)
        byl = keep * (ra * scale[a, 1] + rho)
        if (x / axl) ** 2 + (y / byl) ** 2 < 1.0:
            return True
    return False


@nb.njit(cache=True, nogil=True)
def _collisions_kernel(T, joint, start, end, radii, scale, pairs, frac, keep, out):
    """Sphere chain of cone B against the elliptical volume of cone A, for every pose and pair."""
    for n in range(T.shape[0]):
        for i in range(pairs.shape[0]):
            out[n, i] = _pair_hits(T[n], pairs[i, 0], pairs[i, 1], joint, start, end, radii, scale, frac, keep)


@nb.njit(cache=True, nogil=True, inline="always")
def pose_valid(pose, T, lower, upper, check_limits, c_index, c_above, parents, offsets, rot_axis, rot_sign, rot_param,
               trans_param, joint, start, end, radii, scale, pairs, frac, keep):
    """One pose of :meth:`HardPriors.valid`: the limits and the coupled limits, then (inside them) kinematics into the
    scratch ``T (J, 3, 4)`` and the collision pairs, stopping at the first pair that collides. The arguments after
    ``T`` are :meth:`HardPriors.kernel_tables`."""
    if check_limits:
        for d in range(pose.shape[0]):
            v = pose[d]
            if not (v >= lower[d] and v <= upper[d]):
                return False
        for i in range(c_index.shape[0]):  # a coupled limit: out when every one of its parameters is above its value
            out = True
            for q in range(c_index.shape[1]):
                d = c_index[i, q]
                if d >= 0 and not pose[d] > c_above[i, q]:
                    out = False
                    break
            if out:
                return False
    if pairs.shape[0] > 0:
        fk_pose_into(pose, parents, offsets, rot_axis, rot_sign, rot_param, trans_param, T)
        for i in range(pairs.shape[0]):
            if _pair_hits(T, pairs[i, 0], pairs[i, 1], joint, start, end, radii, scale, frac, keep):
                return False
    return True


@nb.njit(cache=True, nogil=True)
def _valid_kernel(poses, lower, upper, check_limits, c_index, c_above, parents, offsets, rot_axis, rot_sign, rot_param,
                  trans_param, joint, start, end, radii, scale, pairs, frac, keep, out):
    """:meth:`HardPriors.valid` in one pass (:func:`pose_valid` per pose)."""
    T = np.empty((parents.shape[0], 3, 4))
    for n in range(poses.shape[0]):
        out[n] = pose_valid(poses[n], T, lower, upper, check_limits, c_index, c_above, parents, offsets, rot_axis,
                            rot_sign, rot_param, trans_param, joint, start, end, radii, scale, pairs, frac, keep)
