"""Marker fitness functions on 2D detections: Sharifi et al. (2017) eq. 7-12 and a robust reprojection.

The observation of a frame is a :class:`MarkerFrame`: per view an unlabelled ``(Q_c, 2)`` array of
detected marker positions in (distorted) pixels, and the cameras. The model points are the 3D
joints of the pose (``points="joints15"``: the 15 HumanEva joints; ``"joints"``: every joint
frame origin of the body model).

* :class:`MarkerFitness` (``kind="markers"``) -- Sharifi et al. sec. 3.3: project every model
  point (eq. 9), take the nearest detection in every view (eq. 10), drop it if farther than
  ``rho = 5`` px; the score of point ``m`` is the generalised symmetric epipolar distance of its
  matched detections (eq. 7-8) with ``penalty = 200`` for every view pair lacking a match;
  ``w = exp(-mean_m s_m)`` (eq. 11-12), returned as ``log w = -mean_m s_m``.
* :class:`ReprojectionFitness` (``kind="reprojection"``) -- our better-behaved alternative: the
  reprojection error ``e`` of every point to its nearest detection in every view, and (``symmetric``,
  the default) of every detection to its nearest projected point, through a truncated Cauchy loss
  ``log(1 + min(e, e_max)^2 / tau^2)``; ``log w = -mean loss``. Smooth near the optimum (the
  epipolar score depends on the pose only through which detections match, so it is flat within
  ``rho`` of them), and bounded for missing or false detections. The detection-to-model half stops
  two model points from sharing one detection while another detection goes unexplained (a model
  wrist settling on another joint's marker scores as well there as at the truth one-sided).

Backends: ``"numba"`` (default; numba kinematics, then the matching vectorised over the batch in
numpy, with the epipolar distances of all detection pairs tabulated once per frame) and
``"reference"`` (plain loops over poses, points and views with the formulas written out).

Both return log-weights (the :class:`~swarmpose.fitness.base.Fitness` contract): the annealed particle
filter weights a particle by ``w^beta = exp(beta * score)`` (DR05 eq. 3, 6); read as a weight itself,
``exp(beta * w)`` left the epipolar score's weights almost uniform.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmpose.camera import Camera, fundamental_matrix
from swarmpose.errors import ConfigError, ShapeError

__all__ = ["MarkerFrame", "MarkerFitness", "ReprojectionFitness", "symmetric_epipolar_distance"]

_BACKENDS = ("reference", "numba")
_POINTS = ("joints15", "joints")


@dataclass(eq=False)
class MarkerFrame:
    """2D marker detections of one frame.

    Parameters
    ----------
    detections : list of (Q_c, 2) arrays
        Detected marker positions per view, distorted pixels (``Q_c`` may be 0).
    cameras : list of Camera
        One per view.

    Raises
    ------
    ShapeError
        Not one detection array per camera, or an array not ``(Q, 2)``.
    """

    detections: list[np.ndarray]
    cameras: list[Camera]

    def __post_init__(self) -> None:
        dets = [np.asarray(d, np.float64).reshape(-1, 2) if np.size(d) == 0 else np.asarray(d, np.float64)
                for d in self.detections]
        if len(dets) != len(self.cameras):
            raise ShapeError(f"expected one detection array per camera ({len(self.cameras)}), got {len(dets)}")
        for i, d in enumerate(dets):
            if d.ndim != 2 or d.shape[1] != 2:
                raise ShapeError(f"detections[{i}] must have shape (Q, 2), got {d.shape}")
            if not np.isfinite(d).all():
                raise ShapeError(f"detections[{i}] must be finite")
        self.detections = dets
        self.cameras = list(self.cameras)


def symmetric_epipolar_distance(F: np.ndarray, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """Sharifi et al. eq. 7: ``sqrt(d(F x_a, x_b)^2 + d(F^T x_b, x_a)^2)``, point-to-line distances.

    Parameters
    ----------
    F : (3, 3)
        Fundamental matrix with ``x_b^T F x_a = 0`` (:func:`swarmpose.camera.fundamental_matrix`).
    xa, xb : (..., 2)
        Undistorted pixel coordinates in views a and b (broadcast against each other).

    Returns
    -------
    (...) float64
    """
    ha = np.concatenate([xa, np.ones(xa.shape[:-1] + (1,))], axis=-1)
    hb = np.concatenate([xb, np.ones(xb.shape[:-1] + (1,))], axis=-1)
    lb = ha @ F.T  # epipolar line of x_a in view b: F x_a
    la = hb @ F  # epipolar line of x_b in view a: F^T x_b
    num = np.sum(hb * lb, axis=-1)  # x_b^T F x_a (= x_a^T F^T x_b)
    db = num / np.hypot(lb[..., 0], lb[..., 1])
    da = num / np.hypot(la[..., 0], la[..., 1])
    return np.sqrt(db * db + da * da)


class _MarkerBase:
    kind = "markers"

    def __init__(self, model, *, backend: str = "numba", points: str = "joints15"):
        if backend not in _BACKENDS:
            raise ConfigError(f"unknown fitness backend {backend!r} (known: {', '.join(_BACKENDS)})")
        if points not in _POINTS:
            raise ConfigError(f"unknown marker point set {points!r} (known: {', '.join(_POINTS)})")
        self.model = model
        self.backend_name = backend
        self.points = points
        self.frame: MarkerFrame | None = None
        self.prepare_ms = 0.0

    def _points3d(self, poses: np.ndarray) -> np.ndarray:
        ref = self.backend_name == "reference"
        if self.points == "joints15":
            return self.model.joints15(poses, reference=ref)
        return self.model.joint_positions(poses, reference=ref)

    def bind(self, frame: MarkerFrame) -> _MarkerBase:
        """Install one frame's detections (prepared once). Returns ``self``."""
        if not isinstance(frame, MarkerFrame):
            raise ShapeError(f"a marker fitness binds a MarkerFrame, got {type(frame).__name__}")
        t0 = time.perf_counter()
        self.frame = frame
        self._prepare(frame)
        self.prepare_ms = (time.perf_counter() - t0) * 1e3
        return self

    def _prepare(self, frame: MarkerFrame) -> None:
        pass

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        """Scores ``(N,)`` of ``poses (N, D)``."""
        return self.evaluate(poses)

    def evaluate(self, poses: np.ndarray, options: Mapping[str, Any] | None = None) -> np.ndarray:
        """Scores ``(N,)`` of ``poses (N, D)``, higher is better. ``options`` (per-stage image options
        such as ``edge_cones``) do not apply to markers and are ignored.

        Raises
        ------
        ShapeError
            ``poses`` is not ``(N, D)``.
        RuntimeError
            No frame bound.
        """
        if self.frame is None:
            raise RuntimeError("no frame bound: call fitness.bind(frame) first")
        p = self.model.check_poses(poses)
        X = self._points3d(p)  # (N, M, 3)
        if self.backend_name == "reference":
            return np.array([self._score_one(X[n]) for n in range(len(p))], dtype=np.float64)
        return self._score_batch(X)

    def _projections(self, X: np.ndarray) -> list[np.ndarray]:
        return [cam.project(X) for cam in self.frame.cameras]

    def _nearest(self, uv: np.ndarray, det: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest detection (index, distance) for ``uv (..., 2)``; index -1 / distance inf if none."""
        if len(det) == 0:
            return np.full(uv.shape[:-1], -1, np.int64), np.full(uv.shape[:-1], np.inf)
        d2 = np.sum((uv[..., None, :] - det) ** 2, axis=-1)
        idx = np.argmin(d2, axis=-1)
        return idx, np.sqrt(np.take_along_axis(d2, idx[..., None], axis=-1)[..., 0])


class MarkerFitness(_MarkerBase):
    """Sharifi et al. (2017) marker likelihood, eq. 7-12 (see the module docstring).

    Parameters
    ----------
    model : BodyModel
    backend : {"numba", "reference"}
    points : {"joints15", "joints"}
        Model points matched to the detections.
    rho : float, default 5.0
        Matching radius in pixels (eq. 10 and the text below it).
    penalty : float, default 200.0
        Symmetric epipolar distance used for a view pair where a point has no match.
    """

    kind = "markers"

    def __init__(self, model, *, backend: str = "numba", points: str = "joints15", rho: float = 5.0,
                 penalty: float = 200.0):
        super().__init__(model, backend=backend, points=points)
        if not rho > 0 or not penalty >= 0:
            raise ConfigError(f"need rho > 0 and penalty >= 0, got rho={rho!r}, penalty={penalty!r}")
        self.rho = float(rho)
        self.penalty = float(penalty)

    def _prepare(self, frame: MarkerFrame) -> None:
        cams = frame.cameras
        self._und = [cam.undistort_points(d) if len(d) else d for cam, d in zip(cams, frame.detections, strict=True)]
        self._pairs = list(itertools.combinations(range(len(cams)), 2))
        self._F = {(i, j): fundamental_matrix(cams[i], cams[j]) for i, j in self._pairs}
        # d_se of every detection pair, once per frame: (Q_i, Q_j) per view pair
        self._table = {}
        for i, j in self._pairs:
            a, b = self._und[i], self._und[j]
            if len(a) and len(b):
                self._table[(i, j)] = symmetric_epipolar_distance(self._F[(i, j)], a[:, None, :], b[None, :, :])

    def point_scores(self, poses: np.ndarray) -> np.ndarray:
        """Per-point scores ``s_m`` (eq. 8, 11): ``(N, M)`` generalised symmetric epipolar distances,
        pixels (``penalty`` for each view pair lacking a match). Always the vectorised path."""
        if self.frame is None:
            raise RuntimeError("no frame bound: call fitness.bind(frame) first")
        return self._point_scores(self._points3d(self.model.check_poses(poses)))

    def _score_batch(self, X: np.ndarray) -> np.ndarray:
        return -self._point_scores(X).mean(axis=1)  # log of eq. 12

    def _point_scores(self, X: np.ndarray) -> np.ndarray:
        matches = []
        for c, uv in enumerate(self._projections(X)):
            idx, dist = self._nearest(uv, self.frame.detections[c])
            matches.append(np.where(dist <= self.rho, idx, -1))  # eq. 10 with the rho threshold
        s2 = np.zeros(X.shape[:2])
        for i, j in self._pairs:
            mi, mj = matches[i], matches[j]
            ok = (mi >= 0) & (mj >= 0)
            d = np.full(X.shape[:2], self.penalty)
            if ok.any():
                d[ok] = self._table[(i, j)][mi[ok], mj[ok]]
            s2 += d * d  # eq. 8: sum over view pairs of d_se^2
        return np.sqrt(s2)  # eq. 11

    def _score_one(self, X: np.ndarray) -> float:
        """Eq. 9-12 for one pose, written out with loops (the reference backend)."""
        cams = self.frame.cameras
        scores = []
        for m in range(X.shape[0]):
            matched: list[np.ndarray | None] = []
            for c, cam in enumerate(cams):
                p = cam.project(X[m])  # eq. 9
                det = self.frame.detections[c]
                best, best_d = None, math.inf
                for q in range(len(det)):  # eq. 10
                    dq = math.hypot(*(p - det[q]))
                    if dq < best_d:
                        best, best_d = q, dq
                matched.append(cam.undistort_points(det[best]) if best is not None and best_d <= self.rho else None)
            total = 0.0
            for i, j in itertools.combinations(range(len(cams)), 2):
                if matched[i] is None or matched[j] is None:
                    d = self.penalty
                else:
                    F = fundamental_matrix(cams[i], cams[j])
                    d = float(symmetric_epipolar_distance(F, matched[i], matched[j]))  # eq. 7
                total += d * d
            scores.append(math.sqrt(total))  # eq. 8, 11
        return -float(np.mean(scores))  # log of eq. 12


class ReprojectionFitness(_MarkerBase):
    """Robust reprojection fitness: ``log w = -mean of log(1 + min(e, e_max)^2 / tau^2)``.

    The mean runs over ``e_mc``, the distance from model point ``m`` projected into view ``c`` to the
    nearest detection there (``e_max`` when the view has none), and -- with ``symmetric=True`` --
    over ``e'_qc``, the distance from detection ``q`` of view ``c`` to the nearest projected model
    point. At most 0 (the weight ``w`` in ``(0, 1]``); 0 when every point projects exactly onto a
    detection in every view and (symmetric) every detection is so explained. False detections add a bounded, nearly constant
    term.

    Parameters
    ----------
    model : BodyModel
    backend : {"numba", "reference"}
    points : {"joints15", "joints"}
    tau : float, default 5.0
        Scale of the Cauchy loss, pixels.
    e_max : float, default 50.0
        Distances are truncated here (outliers, missing detections), pixels.
    symmetric : bool, default True
        Add the detection-to-model distances (see the module docstring).
    """

    kind = "reprojection"

    def __init__(self, model, *, backend: str = "numba", points: str = "joints15", tau: float = 5.0,
                 e_max: float = 50.0, symmetric: bool = True):
        super().__init__(model, backend=backend, points=points)
        if not tau > 0 or not e_max > 0:
            raise ConfigError(f"need tau > 0 and e_max > 0, got tau={tau!r}, e_max={e_max!r}")
        self.tau = float(tau)
        self.e_max = float(e_max)
        self.symmetric = bool(symmetric)

    def _loss(self, e: np.ndarray) -> np.ndarray:
        e = np.minimum(e, self.e_max)
        return np.log1p((e / self.tau) ** 2)

    def _score_batch(self, X: np.ndarray) -> np.ndarray:
        total = np.zeros(X.shape[0])
        count = X.shape[1] * len(self.frame.cameras)
        for c, uv in enumerate(self._projections(X)):
            det = self.frame.detections[c]
            if len(det) == 0:
                total += X.shape[1] * self._loss(np.array(np.inf))
                continue
            d = np.sqrt(np.sum((uv[:, :, None, :] - det) ** 2, axis=-1))  # (N, M, Q)
            total += self._loss(d.min(axis=2)).sum(axis=1)
            if self.symmetric:
                total += self._loss(d.min(axis=1)).sum(axis=1)
                count += len(det)
        return -total / count

    def _score_one(self, X: np.ndarray) -> float:
        losses = []
        for c, cam in enumerate(self.frame.cameras):
            det = self.frame.detections[c]
            proj = [cam.project(X[m]) for m in range(X.shape[0])]
            for p in proj:
                e = min((math.hypot(*(p - d)) for d in det), default=math.inf)
                losses.append(math.log1p(min(e, self.e_max) ** 2 / self.tau**2))
            if self.symmetric:
                for d in det:
                    e = min(math.hypot(*(p - d)) for p in proj)
                    losses.append(math.log1p(min(e, self.e_max) ** 2 / self.tau**2))
        return -float(np.mean(losses))
