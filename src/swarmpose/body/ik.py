"""Inverse kinematics: fit model parameters to 15 ground-truth joints, frame by frame.

Per frame a bounded least-squares problem (``scipy.optimize.least_squares``, trust-region
reflective, inside the joint limits) on the 45 residuals ``model.joints15(x) - gt``, warm-started
from the previous frame, with small damping and rest-pose residuals that keep the fit smooth along the
model's null spaces. The Jacobian is taken by forward differences in one batched FK call of ``D + 1``
poses. Each frame's smooth fit is then polished on the joint residuals alone (no damping, no rest
prior, same bounds): the mean over frames of the polished per-frame error D (mean joint distance, mm)
is the clip's **IK floor** (design.md §4, thesis sec. 6.4), the error of the model's best fit to the
truth, which no tracker using this model can beat.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from swarmpose.body.model import BodyModel
from swarmpose.errors import ShapeError

__all__ = ["IKResult", "fit_ik", "initial_root_pose"]


@dataclass(frozen=True)
class IKResult:
    """Fitted parameters and errors.

    ``params (T, D)``: the smooth fit (damped, rest prior), the tracker's start pose. ``joint_error_mm
    (T, 15)``: the joint errors of the best fit, ``floor_params (T, D)``, which starts from ``params`` and
    minimises the joint residuals alone; these give the IK floor.
    """

    params: np.ndarray
    joint_error_mm: np.ndarray
    floor_params: np.ndarray

    @property
    def frame_error_mm(self) -> np.ndarray:
        """Per-frame D: mean of the 15 joint distances (HumanEva eq. 3), ``(T,)``."""
        return self.joint_error_mm.mean(axis=1)

    @property
    def floor_mean_mm(self) -> float:
        return float(self.frame_error_mm.mean())

    @property
    def floor_max_mm(self) -> float:
        return float(self.frame_error_mm.max())


def _kabsch(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Rotation R minimising ||R @ src_i - dst_i|| for centred point sets ``(K, 3)``."""
    h = src.T @ dst
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T


def initial_root_pose(model: BodyModel, gt15: np.ndarray) -> np.ndarray:
    """A start pose ``(D,)``: zero joint angles, the root placed by a rigid fit of pelvis, hips, thorax."""
    from swarmpose.joints import JOINT_INDEX as J

    x = np.zeros(model.n_params)
    idx = [J["pelvis"], J["l_hip"], J["r_hip"], J["thorax"]]
    ref = model.joints15(x)[0][idx]
    tgt = gt15[idx]
    R = _kabsch(ref - ref.mean(0), tgt - tgt.mean(0))
    # thesis/bodytrack root convention R = Rz(x3) Rx(x1) Ry(x2)
    x1 = np.arcsin(np.clip(R[2, 1], -1.0, 1.0))
    x3 = np.arctan2(-R[0, 1], R[1, 1])
    x2 = np.arctan2(-R[2, 0], R[2, 2])
    names = model.param_names
    if {"pelvis_rx", "pelvis_ry", "pelvis_rz"} <= set(names):
        x[model.param_index("pelvis_rx")] = x1
        x[model.param_index("pelvis_ry")] = x2
        x[model.param_index("pelvis_rz")] = x3
    pelvis_now = model.joints15(x)[0][J["pelvis"]]
    for a, n in enumerate(("pelvis_tx", "pelvis_ty", "pelvis_tz")):
        if n in names:
            x[model.param_index(n)] += gt15[J["pelvis"], a] - pelvis_now[a]
    return np.clip(x, model.lower, model.upper)


def fit_ik(
    model: BodyModel,
    joints15: np.ndarray,
    *,
    init: np.ndarray | None = None,
    max_nfev: int = 200,
    damping: float = 1.0,
    rest_weight: float = 20.0,
    polish: bool = True,
    missing: bool = False,
    progress=None,
) -> IKResult:
    """Fit ``model`` to ground-truth joints ``(T, 15, 3)`` (mm) frame by frame.

    Parameters
    ----------
    init : start pose ``(D,)`` for the first frame; by default :func:`initial_root_pose`.
    damping : weight (mm per radian; mm per 100 mm for translations) of extra residuals
        ``damping * (x - x_previous)``. They pin parameters the joints cannot see (e.g. the head
        twist, a shoulder twist with a straight elbow) to the previous frame and make the problem
        well conditioned; the bias they add is negligible (a 0.1 rad change costs 0.1 mm).
    rest_weight : weight (mm per radian) of residuals ``rest_weight * x`` on the joint angles (not the
        root): among poses that fit the joints equally well (true null spaces such as a trunk twist
        against opposite clavicle protractions) the one closest to the zero pose wins, so the fit
        does not drift along them from frame to frame. Measured on cmu_16_16_walk: with 0.5 the
        trunk twist swings +-35 deg against clavicles at their limits (27 deg/frame jumps); with 20
        it stays within +-12 deg (under 2 deg/frame). The prior costs 2.1 mm of joint error there
        against 0.9 mm without it; the polish (below) removes that cost from the reported floor.
    polish : bool, default True
        Refine every frame's smooth fit on the joint residuals alone (``floor_params``); the errors
        are then those of the best fit. False: ``floor_params`` is ``params`` (faster, for tests).
    missing : bool, default False
        Allow non-finite joints (a detector's joint that no two views saw): they get no residual, so the
        parameters only they would show stay near the start (the rest pose) and their errors are NaN.
        By default a non-finite joint is an error.
    progress : optional callable ``progress(k)`` called after each frame (for progress bars).
    """
    gt = np.asarray(joints15, dtype=np.float64)
    if gt.ndim != 3 or gt.shape[1:] != (15, 3):
        raise ShapeError(f"joints15: expected shape (T, 15, 3), got {gt.shape}")
    seen = np.repeat(np.isfinite(gt).all(axis=2), 3, axis=1).astype(float)  # (T, 45)
    if not missing and not seen.all():
        raise ValueError("joints15 contains non-finite values")
    if not seen.any(axis=1).all():
        raise ValueError("joints15: a frame has no finite joint")
    T, D = gt.shape[0], model.n_params
    lo, hi = model.lower.copy(), model.upper.copy()
    # steps: 1e-6 rad for angles, 1e-3 mm for translations
    h = np.where(model.is_rotation, 1e-6, 1e-3)
    margin = 1e-7 * (np.where(np.isfinite(lo), np.abs(lo), 0.0) + 1.0)
    lo_in, hi_in = lo + margin, hi - margin
    eye_h = np.diag(h)
    w = damping * np.where(model.is_rotation, 1.0, 0.01)
    w_rest = rest_weight * model.is_rotation.astype(float)
    if "root" in model.groups:
        w_rest[model.group("root")] = 0.0

    params = np.empty((T, D))
    best = np.empty((T, D))  # the polished fits (the smooth ones without polish)
    x = initial_root_pose(model, gt[0]) if init is None else np.clip(np.asarray(init, float), lo, hi)
    for t in range(T):
        m = seen[t]
        target = np.where(m > 0, gt[t].ravel(), 0.0)
        prev = x.copy()

        def residuals(p, target=target, prev=prev, m=m):
            return np.concatenate([m * (model.joints15(p)[0].ravel() - target), w * (p - prev), w_rest * p])

        def jacobian(p, m=m):
            batch = np.vstack([p[None], p[None] + eye_h])
            j = model.joints15(batch).reshape(D + 1, -1)
            return np.vstack([m[:, None] * ((j[1:] - j[0]) / h[:, None]).T, np.diag(w), np.diag(w_rest)])

        # unbounded heading keeps continuity across the ±pi seam; stay strictly inside bounds
        x0 = np.clip(x, lo_in, hi_in)
        sol = least_squares(residuals, x0, jac=jacobian, bounds=(lo, hi), method="trf",
                            x_scale=np.where(model.is_rotation, 1.0, 100.0), max_nfev=max_nfev,
                            xtol=1e-10, ftol=1e-10)
        x = sol.x
        params[t] = best[t] = x
        if polish:
            fit = least_squares(lambda p, target=target, m=m: m * (model.joints15(p)[0].ravel() - target),
                                np.clip(x, lo_in, hi_in), jac=lambda p: jacobian(p)[: 45], bounds=(lo, hi),
                                method="trf", x_scale=np.where(model.is_rotation, 1.0, 100.0), max_nfev=max_nfev,
                                xtol=1e-10, ftol=1e-10)
            if fit.cost < 0.5 * np.sum(residuals(x)[: 45] ** 2):
                best[t] = fit.x
        if progress is not None:
            progress(t)
    err = np.linalg.norm(model.joints15(best) - gt, axis=-1)
    return IKResult(params=params, joint_error_mm=err, floor_params=best)
