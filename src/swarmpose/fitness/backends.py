"""Backends of the image fitness functions: one interface, a plain reference and the numba default.

A backend turns a batch of poses into per-(pose, view) *measurements* (:class:`Measurements`:
silhouette overlap and area, edge sums, Deutscher-Reid region sums); the fitness classes turn those
into scores with the shared formulas of :mod:`swarmpose.fitness.base`. A GPU backend only has to
implement :class:`ImageBackend` (``prepare`` and ``measure``) and be added to :data:`BACKENDS`;
optimisers and the tracker never see it.

* ``"reference"`` -- :class:`ReferenceBackend`: numpy kinematics, :mod:`swarmpose.render.reference`
  outlines, per-pixel half-plane rasterisation of each footprint, numpy sums. Loops over poses and
  views in Python; slow (tens of ms per pose), obviously right; what the tests compare against.
* ``"numba"`` -- :class:`NumbaBackend` (default): one fused numba kernel per share of the batch --
  kinematics, cone outlines, the scanline silhouette counter and the edge samples
  (:func:`swarmpose.fitness._numba.eval_share`) -- with the poses dealt to all cores
  (:mod:`swarmpose.fitness.threads`; numba's ``prange`` is an option). ``cache=True``: compiled once per machine
  (about 30-50 s), about 1 s to load afterwards.
* ``"torch"`` -- :class:`swarmpose.fitness.torch_backend.TorchBackend` (registered by
  :mod:`swarmpose.fitness`): the same definitions as batched PyTorch code, the GPU path.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Protocol

import numba
import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, ShapeError
from swarmpose.features import FrameFeatures
from swarmpose.fitness.threads import BatchThreads
from swarmpose.render.project import (
    DEFAULT_N_RIM,
    DEFAULT_NEAR_MM,
    ConeTables,
    _check_n_rim,
    camera_tables,
    cone_tables,
)

__all__ = ["PreparedFrame", "prepare_frame", "Request", "Measurements", "ImageBackend", "ReferenceBackend",
           "NumbaBackend", "BACKENDS", "make_backend", "parameter_cones"]


@dataclass(eq=False)
class PreparedFrame:
    """Everything an image fitness needs from one frame, computed once (:func:`prepare_frame`).

    Attributes
    ----------
    features : FrameFeatures
        The bound observation.
    cameras : list of Camera
    R : (C, 3, 3), t : (C, 3), cam : (C, 11)
        Camera tables for the kernels (:func:`swarmpose.render.project.camera_tables`).
    width, height : int
    silhouettes : (C, H, W) uint8, C-contiguous
    edges : (C, H, W) float32, C-contiguous
    prefix : (C, H, W + 1) int16 (int32 when W >= 32767)
        Row prefix sums of the silhouettes: ``prefix[c, y, x] = sum(silhouettes[c, y, :x])``.
    observed_area : (C,) int64
        ``|O|`` per view (``R + Y`` of thesis eq. 5.5).
    prepare_ms : float
        Wall time of the preparation.
    extra : dict
        Backend-specific state (e.g. device arrays of a GPU backend).
    """

    features: FrameFeatures
    cameras: list[Camera]
    R: np.ndarray
    t: np.ndarray
    cam: np.ndarray
    width: int
    height: int
    silhouettes: np.ndarray
    edges: np.ndarray
    prefix: np.ndarray
    observed_area: np.ndarray
    prepare_ms: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def n_views(self) -> int:
        """Number of views ``C``."""
        return len(self.cameras)


def prepare_frame(frame: FrameFeatures) -> PreparedFrame:
    """Per-frame preparation: contiguous features, row prefix sums, ``|O|``, camera tables (timed).

    Parameters
    ----------
    frame : FrameFeatures

    Returns
    -------
    PreparedFrame

    Raises
    ------
    ShapeError
        ``frame`` is not a :class:`~swarmpose.features.FrameFeatures`.
    """
    if not isinstance(frame, FrameFeatures):
        raise ShapeError(f"an image fitness binds a FrameFeatures, got {type(frame).__name__}")
    from swarmpose.fitness._numba import row_prefix_sums

    t0 = time.perf_counter()
    sil = np.ascontiguousarray(frame.silhouettes, dtype=np.uint8)
    edges = np.ascontiguousarray(frame.edges, dtype=np.float32)
    C, H, W = sil.shape
    dtype = np.int16 if W < np.iinfo(np.int16).max else np.int32  # int16 halves the kernels' cache footprint
    prefix = np.empty((C, H, W + 1), dtype)
    row_prefix_sums(sil, prefix)
    area = prefix[:, :, -1].sum(axis=1, dtype=np.int64)
    R, t, cam, w, h = camera_tables(frame.cameras)
    prep = PreparedFrame(features=frame, cameras=list(frame.cameras), R=R, t=t, cam=cam, width=w, height=h,
                         silhouettes=sil, edges=edges, prefix=prefix, observed_area=area)
    prep.prepare_ms = (time.perf_counter() - t0) * 1e3
    return prep


@dataclass(frozen=True)
class Request:
    """What to measure for a batch.

    Attributes
    ----------
    edge_mask : (K,) bool
        Cones whose silhouette lines are edge-sampled.
    top_cone : int
        Cone whose end-cap arc is also sampled (the torso's upper edge), ``-1`` for none.
    silhouette, edge, region : bool
        Compute the silhouette counts / the edge sums / the Deutscher-Reid interior sums.
    edge_spacing, region_spacing : float
        Sample spacing in pixels.
    joints : bool
        Also return the poses' 15 joints (:attr:`Measurements.joints`; the keypoint term's), where the backend has
        them from its own kinematics (the numba backend); else :attr:`Measurements.joints` is None.
    """

    edge_mask: np.ndarray
    top_cone: int
    silhouette: bool = True
    edge: bool = True
    region: bool = False
    edge_spacing: float = 5.0
    region_spacing: float = 8.0
    joints: bool = False


@dataclass
class Measurements:
    """Per (pose, view) raw measurements, all ``(N, C)``.

    Attributes
    ----------
    overlap : int64 -- ``Y = |O & P|`` (thesis eq. 5.4).
    projected : int64 -- ``|P| = B + Y``.
    edge_sum : float64 -- sum of edge-map values over the visible edge samples.
    edge_sq : float64 -- sum of ``(1 - p)^2`` over them (Deutscher & Reid eq. 14).
    edge_count : float64 -- number of visible edge samples.
    region_sq : float64 -- sum of ``(1 - O)^2`` over the interior points (Deutscher & Reid eq. 15).
    region_count : float64 -- number of interior points.
    joints : (N, 15, 3) float64 or None -- the poses' 15 joints (:meth:`~swarmpose.body.model.BodyModel.joints15`,
        to the last bit) when the request asked for them and the backend computes them.
    """

    overlap: np.ndarray
    projected: np.ndarray
    edge_sum: np.ndarray
    edge_sq: np.ndarray
    edge_count: np.ndarray
    region_sq: np.ndarray
    region_count: np.ndarray
    joints: np.ndarray | None = None

    @classmethod
    def from_arrays(cls, counts: np.ndarray, sums: np.ndarray, joints: np.ndarray | None = None) -> Measurements:
        """From a kernel's ``counts (N, C, 2)`` (``Y``, ``P``) and ``sums (N, C, 5)`` (edge sum, edge
        SSD, edge count, region SSD, region count)."""
        return cls(overlap=counts[..., 0], projected=counts[..., 1], edge_sum=sums[..., 0], edge_sq=sums[..., 1],
                   edge_count=sums[..., 2], region_sq=sums[..., 3], region_count=sums[..., 4], joints=joints)


class ImageBackend(Protocol):
    """What a backend implements. Constructed with ``(model, *, n_rim, near)``."""

    name: str

    def prepare(self, frame: FrameFeatures) -> PreparedFrame: ...

    def measure(self, prepared: PreparedFrame, poses: np.ndarray, request: Request) -> Measurements: ...


class _BackendBase:
    name = "base"

    def __init__(self, model, *, n_rim: int = DEFAULT_N_RIM, near: float = DEFAULT_NEAR_MM):
        self.model = model
        self.n_rim = _check_n_rim(n_rim)
        self.near = float(near)
        self.cones: ConeTables = cone_tables(model)

    def prepare(self, frame: FrameFeatures) -> PreparedFrame:
        """:func:`prepare_frame`."""
        return prepare_frame(frame)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(model={self.model.name!r}, n_rim={self.n_rim})"


class ReferenceBackend(_BackendBase):
    """Plain reference: numpy geometry, per-pixel footprint rasterisation, numpy sums (slow)."""

    name = "reference"

    def measure(self, prepared: PreparedFrame, poses: np.ndarray, request: Request) -> Measurements:
        """Measurements of ``poses (N, D)`` (see :class:`Measurements`)."""
        from swarmpose.render.reference import (
            edge_samples_reference,
            nearest_pixel_values,
            reference_geometry,
            region_samples_reference,
            union_mask,
        )

        geom = reference_geometry(self.model, poses, prepared.cameras, n_rim=self.n_rim, near=self.near)
        N, C = geom.cones.n_vertices.shape[:2]
        out = _empty(N, C)
        for n in range(N):
            for c in range(C):
                if request.silhouette:
                    mask = union_mask(geom, n, c)
                    out.projected[n, c] = np.count_nonzero(mask)
                    out.overlap[n, c] = np.count_nonzero(mask & (prepared.silhouettes[c] != 0))
                if request.edge:
                    xy, _, _, vis = edge_samples_reference(geom, n, c, request.edge_mask, request.top_cone,
                                                           request.edge_spacing)
                    p = nearest_pixel_values(prepared.edges[c], xy[vis])
                    out.edge_sum[n, c] = p.sum()
                    out.edge_sq[n, c] = ((1.0 - p) ** 2).sum()
                    out.edge_count[n, c] = len(p)
                if request.region:
                    xy = region_samples_reference(geom, n, c, request.region_spacing)
                    o = nearest_pixel_values(prepared.silhouettes[c], xy)
                    out.region_sq[n, c] = ((1.0 - o) ** 2).sum()
                    out.region_count[n, c] = len(o)
        return out


class NumbaBackend(_BackendBase):
    """Default CPU backend: numba kinematics + the fused scanline/edge kernel on all cores.

    Parameters
    ----------
    model : BodyModel
    n_rim, near : see :func:`swarmpose.render.project_cones`.
    threads : {"pool", "prange", "serial"}, default "pool"
        How the batch is spread over the cores. ``"pool"``: ``numba.get_num_threads()`` threads (the calling
        one and workers, :class:`~swarmpose.fitness.threads.BatchThreads`) each run the GIL-free kernel
        :func:`~swarmpose.fitness._numba.eval_claim`, which claims the batch's (view, pose) items one at a
        time with an atomic counter, so the threads finish together and a late or preempted worker takes
        what is left; between batches the workers wait spinning (yielding the core) for up to 2 ms and then
        sleep. ``"prange"``: numba's own parallel loop
        (:func:`~swarmpose.fitness._numba.eval_kernel`); with numba's default OpenMP layer its waiting
        threads spin without yielding, which starves the tracker's read-ahead of the next frame (features
        3 -> 26 ms per frame on the walk), and when other processes compete for the cores a batch took 5-10x
        longer (2-core machine at load average 7: 1.4k against 8.8k evaluations/s at 644x484).
        ``"serial"``: one core.
    moving : bool, default True
        A batch whose poses differ from its first pose only in parameters that move at most half of the cones
        (a limb's search) is measured with the other cones' outlines, spans and edge samples computed once
        (:mod:`swarmpose.fitness._numba_partial`): the same measurements to the last bit, in a fraction of the
        time. ``False``: every pose measured in full (for comparison).
    """

    name = "numba"
    _threads: BatchThreads | None = None  # shared by the backends of a process (see _batch_threads)

    def __init__(self, model, *, n_rim: int = DEFAULT_N_RIM, near: float = DEFAULT_NEAR_MM,
                 threads: str = "pool", moving: bool = True):
        super().__init__(model, n_rim=n_rim, near=near)
        from swarmpose.render._kernels import rim_tables

        if threads not in ("pool", "prange", "serial"):
            raise ConfigError(f"threads must be 'pool', 'prange' or 'serial', got {threads!r}")
        self.threads = threads
        self.moving = bool(moving)
        self._ctab, self._stab = rim_tables(self.n_rim)
        self._moves = parameter_cones(model.kin, self.cones.joint, len(model.lower))
        self._j15 = np.ascontiguousarray(model.joints15_index, dtype=np.int64)
        self._base: tuple | None = None  # (prepared frame, request key, T0, stay_base's arrays) of the last batch
        #: Items of the last batch measured in full although it took the moving-cones path (their staying
        #: cones' transforms differed after all); ``-1``: the last batch was measured in full.
        self.last_full_items = -1

    @classmethod
    def _batch_threads(cls, n: int) -> BatchThreads:
        # threads inherited through fork() do not run in the child: start new ones there
        bt = cls._threads
        if bt is None or bt.n != n or not bt.alive:
            if bt is not None and bt.alive:
                bt.close()
            bt = cls._threads = BatchThreads(n)
        return bt

    def measure(self, prepared: PreparedFrame, poses: np.ndarray, request: Request) -> Measurements:
        """Measurements of ``poses (N, D)`` (see :class:`Measurements`)."""
        from swarmpose.fitness._numba import eval_claim, eval_claim_go, eval_kernel, eval_share

        p = np.ascontiguousarray(poses, dtype=np.float64)
        N, C = p.shape[0], prepared.n_views
        counts = np.empty((N, C, 2), np.int64)
        sums = np.empty((N, C, 5))
        j15 = self._j15 if request.joints else self._j15[:0]
        joints = np.empty((N, j15.shape[0], 3))
        args = (p, *self.model.kin.as_tuple(), *self.cones.as_tuple(), prepared.R, prepared.t, prepared.cam,
                self._ctab, self._stab, self.near, prepared.prefix, prepared.silhouettes, prepared.edges,
                request.edge_mask, int(request.top_cone), float(request.edge_spacing),
                float(request.region_spacing), bool(request.silhouette), bool(request.edge), bool(request.region))
        nth = max(1, min(numba.get_num_threads(), N)) if self.threads != "serial" else 1
        moving = self._moving_cones(p, request)
        self.last_full_items = -1
        if moving is not None and not (self.threads == "prange" and nth > 1):
            self._measure_moving(prepared, p, request, moving, args, nth, j15, joints, counts, sums)
        elif self.threads == "prange" and nth > 1:
            eval_kernel(*args, nth, j15, joints, counts, sums)
        elif nth == 1:
            eval_share(np.arange(N), *args, j15, joints, counts, sums)
        else:
            # every thread claims (view, pose) items one at a time inside the kernel, so that a worker that
            # starts late still takes its part; the workers wait spinning between batches, so that a batch of
            # 20 poses does not pay two thread wake-ups
            claim, done = np.zeros(1, np.int64), np.zeros(1, np.int64)
            self._batch_threads(numba.get_num_threads()).share(
                lambda: eval_claim(claim, done, *args, j15, joints, counts, sums),
                lambda go, seq: eval_claim_go(go, seq, claim, done, *args, j15, joints, counts, sums), done, N * C)
        return Measurements.from_arrays(counts, sums, joints if request.joints else None)

    def _moving_cones(self, poses: np.ndarray, request: Request) -> np.ndarray | None:
        """The cones the batch moves against its first pose, when that is at most half of them and the request
        has no region sums (else ``None``: the batch is measured in full)."""
        if not self.moving or request.region or poses.shape[0] < 2 or poses.shape[1] != self._moves.shape[0]:
            return None
        moving = self._moves[(poses != poses[:1]).any(axis=0)].any(axis=0)
        return moving if 2 * int(moving.sum()) <= moving.size else None

    def _measure_moving(self, prepared: PreparedFrame, p: np.ndarray, request: Request, moving: np.ndarray,
                        args: tuple, nth: int, j15: np.ndarray, joints: np.ndarray, counts: np.ndarray,
                        sums: np.ndarray) -> None:
        """The batch ``p`` through :func:`~swarmpose.fitness._numba_partial.eval_claim_moving` (``args``: the full
        kernel's arguments), the staying cones' base measured by
        :func:`~swarmpose.fitness._numba_partial.stay_base` or kept from the last batch when it had the same frame,
        request, moving cones and staying transforms."""
        from swarmpose.body.kinematics import fk_pose_into
        from swarmpose.fitness._numba_partial import eval_claim_moving, eval_claim_moving_go, stay_base

        kin = self.model.kin
        T0 = np.empty((kin.n_joints, 3, 4))
        fk_pose_into(p[0], *kin.as_tuple(), T0)
        # a search's batches hold the same staying cones: their base is measured once per frame and search
        key = (moving.tobytes(), request.edge_mask.tobytes(), int(request.top_cone), float(request.edge_spacing))
        staying = self.cones.joint[~moving]
        cached = self._base
        if (cached is not None and cached[0] is prepared and cached[1] == key
                and np.array_equal(cached[2][staying], T0[staying])):
            T0, base = cached[2], cached[3]
        else:
            base = stay_base(T0, moving, *self.cones.as_tuple(), prepared.R, prepared.t, prepared.cam, self._ctab,
                             self._stab, self.near, prepared.prefix, prepared.edges, request.edge_mask,
                             int(request.top_cone), float(request.edge_spacing))
            self._base = (prepared, key, T0, base)
        # the kernel's arguments: (poses, moving, kinematics, cones, ..., do_sil, do_edge) then the base
        margs = (p, moving, *args[1:-1], T0, *base)
        claim, done, full = np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.int64)
        N, C = p.shape[0], prepared.n_views
        if nth == 1:
            eval_claim_moving(claim, done, full, *margs, j15, joints, counts, sums)
        else:
            self._batch_threads(numba.get_num_threads()).share(
                lambda: eval_claim_moving(claim, done, full, *margs, j15, joints, counts, sums),
                lambda go, seq: eval_claim_moving_go(go, seq, claim, done, full, *margs, j15, joints, counts, sums),
                done, N * C)
        self.last_full_items = int(full[0])


def parameter_cones(kin, cone_joint: np.ndarray, n_params: int) -> np.ndarray:
    """``(D, K)`` bool: the cones whose joint's transform parameter ``d`` changes (the joints it drives, by a
    rotation or a translation, and everything below them in the tree)."""
    driven_by = np.zeros((n_params, kin.n_joints), bool)
    for j in range(kin.n_joints):
        for a in range(kin.rot_axis.shape[1]):
            if kin.rot_axis[j, a] >= 0:
                driven_by[kin.rot_param[j, a], j] = True
        for a in range(kin.trans_param.shape[1]):
            if kin.trans_param[j, a] >= 0:
                driven_by[kin.trans_param[j, a], j] = True
    moved = driven_by.copy()
    for j in range(kin.n_joints):  # parents come first
        if kin.parents[j] >= 0:
            moved[:, j] |= moved[:, kin.parents[j]]
    return moved[:, np.asarray(cone_joint)]


def _empty(N: int, C: int) -> Measurements:
    z = np.zeros((N, C))
    return Measurements(overlap=np.zeros((N, C), np.int64), projected=np.zeros((N, C), np.int64),
                        edge_sum=z.copy(), edge_sq=z.copy(), edge_count=z.copy(), region_sq=z.copy(),
                        region_count=z.copy())


#: Registered image backends by name.
BACKENDS: dict[str, type[_BackendBase]] = {"reference": ReferenceBackend, "numba": NumbaBackend}


def make_backend(name: str, model, **kwargs) -> ImageBackend:
    """Instantiate a registered backend.

    Raises
    ------
    ConfigError
        Unknown name (the message lists the known ones).
    """
    try:
        cls = BACKENDS[name]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown fitness backend {name!r} (known: {', '.join(BACKENDS)})") from None
    return cls(model, **kwargs)
