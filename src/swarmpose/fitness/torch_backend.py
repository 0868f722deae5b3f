"""Optional PyTorch backend of the image fitness: the GPU path (``pip install 'swarmpose[torch]'``; runs on the CPU too).

:class:`TorchBackend` computes the same :class:`~swarmpose.fitness.backends.Measurements` as the numba
kernel, with the definitions of :mod:`swarmpose.render` (outline, pixel rule, occlusion, samples),
as batched tensor code over ``(poses, views, cones)`` -- no Python loop over poses, pixels or
samples:

* kinematics: the tree's elementary rotations chained joint by joint (a loop over the ~15 joints),
  batched over poses (thesis sec. 5.1.1);
* outlines: the closed-form silhouette generators and the cap arcs of
  :func:`swarmpose.render._kernels.cone_outline`, each arc as a fixed number of slots (its two
  tangent points and the ``n_rim`` grid angles that may lie inside; slots outside the arc repeat an
  end point, a zero-length edge that changes no row span and no inside test);
* silhouette counts (thesis eq. 5.2-5.5): every outline's span on every image row (the extreme
  crossings of the row's centre line with the outline's edges), the spans of a row sorted and merged
  with a running maximum, ``Y`` read from the row prefix sums of the observed silhouette;
* edge samples (eq. 5.1; Deutscher & Reid eq. 14) on the silhouette lines and the torso's upper arc,
  with the occlusion rule (inside another drawn outline whose axis is nearer);
* interior grid points (Deutscher & Reid eq. 15).

Work is cut into chunks of similar poses so that the largest intermediate tensor stays below
``max_elements`` (a pose close to a camera has thousands of samples). Double precision by default: the
tests require the numba backend's pixel and sample counts exactly (a sample exactly on a pixel
boundary may round the other way, as :mod:`swarmpose.render` allows); ``dtype="float32"`` is faster
on most GPUs and moves a boundary pixel now and then.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.features import FrameFeatures
from swarmpose.fitness.backends import Measurements, PreparedFrame, Request, _BackendBase, prepare_frame
from swarmpose.render.project import DEFAULT_N_RIM, DEFAULT_NEAR_MM

__all__ = ["TorchBackend", "torch_available", "import_torch"]

_ANGLE_EPS = 1e-9  # as swarmpose.render._kernels
_INSTALL = ("pip install 'swarmpose[torch]' (or first the PyTorch build for your GPU or CPU: "
            "https://pytorch.org/get-started)")


def torch_available() -> bool:
    """True when PyTorch can be imported."""
    try:
        import torch  # noqa: F401
    except ImportError:
        return False
    return True


def import_torch():
    """``import torch``, or a :class:`ConfigError` with the install line."""
    try:
        import torch
    except ImportError:
        raise ConfigError(f"the 'torch' fitness backend needs PyTorch, which is not installed: {_INSTALL}") from None
    return torch


class TorchBackend(_BackendBase):
    """Image fitness measurements with PyTorch (GPU when there is one).

    Parameters
    ----------
    model : BodyModel
    n_rim, near : see :func:`swarmpose.render.project_cones`.
    device : str, optional
        A torch device (``"cuda"``, ``"cuda:1"``, ``"cpu"``...). Default: ``"cuda"`` when available,
        else ``"cpu"``.
    dtype : {"float64", "float32"}, default "float64"
        Precision of the geometry.
    max_elements : int, optional
        Largest intermediate tensor, in elements (default 2**26 on a GPU, 2**22 on the CPU); the batch
        is cut into chunks of poses to stay below it (a pose that needs more alone is measured alone).

    Raises
    ------
    ConfigError
        PyTorch is not installed, or a bad device or dtype.
    """

    name = "torch"

    def __init__(self, model, *, n_rim: int = DEFAULT_N_RIM, near: float = DEFAULT_NEAR_MM,
                 device: str | None = None, dtype: str = "float64", max_elements: int | None = None):
        torch = import_torch()
        super().__init__(model, n_rim=n_rim, near=near)
        self.torch = torch
        dtypes = {"float64": torch.float64, "float32": torch.float32}
        if dtype not in dtypes:
            raise ConfigError(f"torch backend: dtype must be 'float64' or 'float32', got {dtype!r}")
        self.dtype = dtypes[dtype]
        try:
            self.device = torch.device(device if device is not None else
                                       ("cuda" if torch.cuda.is_available() else "cpu"))
            torch.zeros(1, dtype=self.dtype, device=self.device)
        except Exception as e:  # RuntimeError, TypeError (e.g. float64 on "mps"), AssertionError...
            raise ConfigError(f"torch backend: cannot use device {device!r} with {dtype} ({e})") from None
        if max_elements is None:
            max_elements = 2**26 if self.device.type == "cuda" else 2**22
        if int(max_elements) < 1:
            raise ConfigError(f"torch backend: max_elements must be >= 1, got {max_elements!r}")
        self.max_elements = int(max_elements)
        if self.device.type == "cpu":
            import numba

            # process-wide: torch's CPU threads follow numba's, the process's share of the cores when
            # runs go in parallel (the runner's workers set it), instead of all cores per process
            torch.set_num_threads(numba.get_num_threads())
        self._masks: dict[bytes, Any] = {}
        kin = model.kin
        self._parents = [int(p) for p in kin.parents]
        self._rot = [[(int(kin.rot_axis[j, k]), float(kin.rot_sign[j, k]), int(kin.rot_param[j, k]))
                      for k in range(3) if kin.rot_axis[j, k] >= 0] for j in range(kin.n_joints)]
        self._trans = [[(a, int(kin.trans_param[j, a])) for a in range(3) if kin.trans_param[j, a] >= 0]
                       for j in range(kin.n_joints)]
        t = self._tensor
        self._offsets = t(kin.offsets)
        ct = self.cones
        self._joint = torch.tensor(ct.joint, dtype=torch.long, device=self.device)
        self._start, self._end = t(ct.start), t(ct.end)
        self._semi_a, self._semi_b, self._scale = t(ct.semi_a), t(ct.semi_b), t(ct.scale)
        grid = 2 * math.pi * np.arange(self.n_rim) / self.n_rim
        self._ctab, self._stab = t(np.cos(grid)), t(np.sin(grid))

    def _tensor(self, a: Any):
        return self.torch.tensor(np.asarray(a, np.float64), dtype=self.dtype, device=self.device)

    def __repr__(self) -> str:
        return (f"TorchBackend(model={self.model.name!r}, n_rim={self.n_rim}, device={str(self.device)!r}, "
                f"dtype={str(self.dtype).removeprefix('torch.')!r})")

    # ------------------------------------------------------------------ frame
    def prepare(self, frame: FrameFeatures) -> PreparedFrame:
        """:func:`~swarmpose.fitness.backends.prepare_frame`, plus the frame's tensors on the device."""
        prep = prepare_frame(frame)
        self._frame_tensors(prep)
        return prep

    def _frame_tensors(self, prep: PreparedFrame) -> dict:
        key = ("torch", str(self.device), str(self.dtype))
        ft = prep.extra.get(key)
        if ft is None:
            torch = self.torch
            dev = self.device
            ft = {"prefix": torch.as_tensor(prep.prefix.astype(np.int64).ravel(), device=dev),
                  "sil": torch.as_tensor(prep.silhouettes.ravel(), device=dev).to(self.dtype),
                  "edges": torch.as_tensor(prep.edges.ravel(), device=dev).to(self.dtype),
                  "R": self._tensor(prep.R), "t": self._tensor(prep.t), "cam": self._tensor(prep.cam)}
            prep.extra[key] = ft
        return ft

    # ------------------------------------------------------------------ evaluation
    def measure(self, prepared: PreparedFrame, poses: np.ndarray, request: Request) -> Measurements:
        """Measurements of ``poses (N, D)`` (see :class:`~swarmpose.fitness.backends.Measurements`).

        The outlines of the whole batch come first; then each pose's largest intermediate tensor is
        known (it grows with the pose's sample counts: a pose close to a camera has thousands), and
        the poses are measured in chunks of similar poses whose tensors stay below ``max_elements``.
        """
        torch = self.torch
        ft = self._frame_tensors(prepared)
        p = np.ascontiguousarray(poses, dtype=np.float64)
        N, C = p.shape[0], prepared.n_views
        counts = np.zeros((N, C, 2), np.int64)
        sums = np.zeros((N, C, 5))
        if N == 0:
            return Measurements.from_arrays(counts, sums)
        with torch.no_grad():
            pt = self._tensor(p)
            step = max(1, self.max_elements // (C * len(self.cones.names) * (2 * self.n_rim + 4) * 4))
            parts = [self._outlines(self._forward(pt[a:a + step]), ft) for a in range(0, N, step)]
            geo = {k: torch.cat([g[k] for g in parts]) for k in parts[0]}
            for idx in _plan_chunks(self._pose_costs(geo, prepared, request), self.max_elements):
                sel = torch.as_tensor(idx, device=self.device)
                c_out, s_out = self._measure_chunk(ft, prepared, {k: v[sel] for k, v in geo.items()}, request)
                counts[idx] = c_out
                sums[idx] = s_out
        return Measurements.from_arrays(counts, sums)

    def _pose_costs(self, geo: dict, prep: PreparedFrame, request: Request) -> np.ndarray:
        """``(N,)`` elements of each pose's largest intermediate tensor in :meth:`_measure_chunk`: row
        spans, edge-line clipping and occlusion, top-arc occlusion, interior grid (its larger side
        squared, an upper bound whatever the other poses of a chunk)."""
        torch = self.torch
        N, C, K, P = geo["uv"].shape[:4]
        cost = torch.full((N,), C * K * max(prep.height, 2 * K * P), dtype=torch.long, device=self.device)
        spacing = float(request.edge_spacing)
        if request.edge:
            use = geo["tangent"] & self._mask(request)
            n_line = self._line_counts(*self._line_ends(geo), use, spacing)
            cost = torch.maximum(cost, C * K * 2 * K * n_line.amax((1, 2, 3)))
            if request.top_cone >= 0:
                n_arc = self._arc_geometry(geo, int(request.top_cone), spacing)[-1]
                cost = torch.maximum(cost, C * K * P * n_arc.amax(1))
        if request.region:
            nt, ns = self._region_counts(geo, float(request.region_spacing))
            side = torch.maximum(nt, ns).amax((1, 2))
            cost = torch.maximum(cost, C * K * 2 * side * side)
        return cost.cpu().numpy()

    def _mask(self, request: Request):
        """The request's edge-sampled cones as a device tensor (uploaded once per request)."""
        key = np.asarray(request.edge_mask, bool).tobytes()
        m = self._masks.get(key)
        if m is None:
            m = self._masks[key] = self.torch.tensor(np.asarray(request.edge_mask, bool), device=self.device)
        return m

    def _measure_chunk(self, ft: dict, prep: PreparedFrame, geo: dict, request: Request):
        torch = self.torch
        N, C = geo["valid"].shape[:2]
        counts = torch.zeros((N, C, 2), dtype=torch.long, device=self.device)
        sums = torch.zeros((N, C, 5), dtype=self.dtype, device=self.device)
        if request.silhouette:
            counts[..., 0], counts[..., 1] = self._silhouette_counts(geo, ft, prep.width, prep.height)
        if request.edge:
            sums[..., 0], sums[..., 1], sums[..., 2] = self._edge_sums(geo, ft, prep, request)
        if request.region:
            sums[..., 3], sums[..., 4] = self._region_sums(geo, ft, prep, float(request.region_spacing))
        return counts.cpu().numpy(), sums.to(torch.float64).cpu().numpy()

    # ------------------------------------------------------------------ kinematics
    def _forward(self, p):
        """World-from-joint rotations ``(N, J, 3, 3)`` and origins ``(N, J, 3)`` (thesis sec. 5.1.1)."""
        torch = self.torch
        N = p.shape[0]
        Rs: list = []
        ts: list = []
        eye = torch.eye(3, dtype=self.dtype, device=self.device).expand(N, 3, 3)
        for j, parent in enumerate(self._parents):
            loc = eye
            for ax, sign, param in self._rot[j]:
                loc = loc @ _elementary(torch, ax, sign * p[:, param])
            origin = self._offsets[j].expand(N, 3).clone()
            for a, param in self._trans[j]:
                origin[:, a] = origin[:, a] + p[:, param]
            if parent < 0:
                Rs.append(loc)
                ts.append(origin)
            else:
                Rs.append(Rs[parent] @ loc)
                ts.append(ts[parent] + (Rs[parent] @ origin[..., None])[..., 0])
        return torch.stack(Rs, 1), torch.stack(ts, 1)

    # ------------------------------------------------------------------ outlines
    def _outlines(self, fk, ft: dict) -> dict:
        """Outline polygons of every cone in every view (definition: :mod:`swarmpose.render`).

        Returns a dict of tensors over ``(N, C, K)``: ``uv (.., P, 2)``, ``z (.., P)`` (vertex depth),
        ``valid`` (drawn), ``tangent`` (has silhouette lines), ``use1`` (closed rim on the end cap),
        ``axis (.., 2, 3)`` (projected cap centres and depths), ``bbox (.., 4)``, ``orient``.
        """
        torch = self.torch
        Rw, tw = fk
        R = Rw[:, self._joint]  # (N, K, 3, 3)
        t = tw[:, self._joint]
        S0 = (R @ self._start[None, :, :, None])[..., 0] + t
        S1 = (R @ self._end[None, :, :, None])[..., 0] + t
        Rc, tc, cam = ft["R"], ft["t"], ft["cam"]

        def to_cam(v, shift):  # (N, K, 3) world -> (N, C, K, 3) camera frame
            out = torch.einsum("cab,nkb->ncka", Rc, v)
            return out + tc[None, :, None, :] if shift else out

        c0, c1 = to_cam(S0, True), to_cam(S1, True)
        X, Y = to_cam(R[..., 0], False), to_cam(R[..., 1], False)
        A0, B0, s = self._semi_a[None, None], self._semi_b[None, None], self._scale[None, None]  # (1, 1, K)
        rmax = torch.maximum(A0, B0)
        valid = ~((c0[..., 2] < self.near + rmax) | (c1[..., 2] < self.near + rmax * s))
        Z = torch.cross(X, Y, dim=-1)
        A = c1 - c0
        w = torch.cross(c0, A, dim=-1)
        dZ = (c0 * Z).sum(-1)
        AZ = (A * Z).sum(-1)
        sg = torch.where(AZ > 0, 1.0, -1.0).to(self.dtype)
        alpha = sg * B0 * (w * Y).sum(-1)
        beta = -sg * A0 * (w * X).sum(-1)
        gamma = sg * A0 * B0 * ((s - 1.0) * dZ - AZ)
        cap0_front = sg * dZ > 0
        cap1_front = sg * (dZ + AZ) < 0
        Rh = torch.sqrt(alpha * alpha + beta * beta)
        tangent = Rh > gamma.abs()
        # tangent angles phi -/+ delta (as the numba kernel, without more trigonometry)
        Rs = torch.where(tangent, Rh, torch.ones_like(Rh))
        phi = torch.atan2(beta, alpha)
        cd = torch.where(tangent, -gamma / Rs, torch.zeros_like(Rh))
        delta = torch.acos(cd.clamp(-1.0, 1.0))
        cp, sp = alpha / Rs, beta / Rs
        sd = torch.sqrt((1.0 - cd * cd).clamp(min=0.0))
        cm, sm = cp * cd + sp * sd, sp * cd - cp * sd  # cos, sin (phi - delta)
        cq, sq = cp * cd - sp * sd, sp * cd + cp * sd  # cos, sin (phi + delta)
        f0 = torch.remainder(phi - delta, 2 * math.pi)
        f1 = f0 + 2.0 * delta
        front = (f0, cm, sm, f1, cq, sq)
        back = (f1, cq, sq, f0 + 2 * math.pi, cm, sm)

        def arc(on_back, forward):
            ends = [torch.where(on_back, b_, f_) for f_, b_ in zip(front, back, strict=True)]
            cs, sn = self._arc_slots(*ends)
            if forward is not True:
                cs = torch.where(forward[..., None], cs, cs.flip(-1))
                sn = torch.where(forward[..., None], sn, sn.flip(-1))
            return cs, sn

        cs0, sn0 = arc(cap0_front, True)
        cs1, sn1 = arc(cap1_front, cap0_front != cap1_front)
        # no silhouette lines: the outline is one whole rim (the end cap's when use1)
        lat_front = gamma > 0
        use0 = lat_front != cap0_front
        use1 = lat_front != cap1_front
        use1 = torch.where(use0 == use1, (s > 1.0).expand_as(use1), use1)
        n_rim = self.n_rim
        pad = self._ctab.new_zeros(2 * n_rim + 4 - n_rim)
        rim_c = torch.cat([self._ctab, pad + self._ctab[-1]])
        rim_s = torch.cat([self._stab, pad + self._stab[-1]])
        P = 2 * n_rim + 4
        on_end_slot = torch.arange(P, device=self.device) >= n_rim + 2
        cosv = torch.where(tangent[..., None], torch.cat([cs0, cs1], -1), rim_c)
        sinv = torch.where(tangent[..., None], torch.cat([sn0, sn1], -1), rim_s)
        on_end = torch.where(tangent[..., None], on_end_slot, use1[..., None])  # (N, C, K, P)
        r = torch.where(on_end, s[..., None], torch.ones_like(cosv))
        centre = torch.where(on_end[..., None], c1[..., None, :], c0[..., None, :])
        a_vec = (A0[..., None] * X)[..., None, :]  # (N, C, K, 1, 3)
        b_vec = (B0[..., None] * Y)[..., None, :]
        pts = centre + cosv[..., None] * (r[..., None] * a_vec) + sinv[..., None] * (r[..., None] * b_vec)
        camv = cam[None, :, None, None, :]
        uv = _project(torch, pts, camv)
        axis_uv = _project(torch, torch.stack([c0, c1], -2), camv)  # (N, C, K, 2, 2)
        axis = torch.cat([axis_uv, torch.stack([c0[..., 2], c1[..., 2]], -1)[..., None]], -1)
        u, v = uv[..., 0], uv[..., 1]
        bbox = torch.stack([u.amin(-1), u.amax(-1), v.amin(-1), v.amax(-1)], -1)
        area = (u * v.roll(-1, -1) - u.roll(-1, -1) * v).sum(-1)
        orient = torch.where(area >= 0, 1.0, -1.0).to(self.dtype)
        return {"uv": uv, "z": pts[..., 2], "valid": valid, "tangent": tangent & valid, "use1": use1,
                "axis": axis, "bbox": bbox, "orient": orient}

    def _arc_slots(self, th0, c0, s0, th1, c1, s1):
        """Cosines and sines of an increasing arc ``[th0, th1]`` in ``n_rim + 2`` slots: the end points
        and the grid angles ``2 pi j / n_rim`` strictly inside; unused grid slots repeat an end point."""
        torch = self.torch
        n_rim = self.n_rim
        step = 2 * math.pi / n_rim
        j = torch.floor(th0 / step)[..., None].long() + 1 + torch.arange(n_rim, device=self.device)
        ang = j.to(self.dtype) * step
        jj = torch.remainder(j, n_rim)
        gc, gs = self._ctab[jj], self._stab[jj]
        low = ang <= th0[..., None] + _ANGLE_EPS
        high = ang >= th1[..., None] - _ANGLE_EPS
        gc = torch.where(low, c0[..., None], torch.where(high, c1[..., None], gc))
        gs = torch.where(low, s0[..., None], torch.where(high, s1[..., None], gs))
        return (torch.cat([c0[..., None], gc, c1[..., None]], -1), torch.cat([s0[..., None], gs, s1[..., None]], -1))

    # ------------------------------------------------------------------ silhouette
    def _silhouette_counts(self, geo: dict, ft: dict, W: int, H: int):
        """``(Y, P)`` per (pose, view): the union of the drawn outlines by the scanline rule
        (:func:`swarmpose.render._kernels.silhouette_counts`).

        Each outline is split at its top and bottom vertices into two chains, monotone in ``v``; on row
        ``y`` a chain's crossing is on its edge from the last vertex at or above the row (found by
        binary search) to the next. The row's span is between the two chains' crossings.
        """
        torch = self.torch
        uv, valid = geo["uv"], geo["valid"]
        N, C, K, P = uv.shape[:4]
        zero = torch.zeros((N, C), dtype=torch.long, device=self.device)
        if not bool(valid.any()):
            return zero, zero
        vv = uv[..., 1][valid]
        y0 = max(int(math.ceil(float(vv.min()))), 0)
        y1 = min(int(math.floor(float(vv.max()))), H - 1)
        if y0 > y1:
            return zero, zero
        rows = torch.arange(y0, y1 + 1, device=self.device).to(self.dtype)
        Hr = rows.shape[0]
        v = uv[..., 1]
        itop = v.argmin(-1, keepdim=True)
        ibot = v.argmax(-1, keepdim=True)
        steps = torch.arange(P, device=self.device)
        bot = torch.remainder(ibot - itop, P)  # position of the bottom vertex on the forward chain
        yr = rows.expand(N, C, K, Hr).contiguous()
        xs = []
        for order, last in ((steps, bot), (-steps, torch.remainder(-bot, P))):  # forward, backward chain
            idx = torch.remainder(itop + order, P)
            cu = uv[..., 0].gather(-1, idx)
            cv = v.gather(-1, idx)
            past = steps > last  # beyond the bottom vertex
            mono = torch.where(past, torch.full_like(cv, math.inf), cv).cummax(-1).values.contiguous()
            e = (torch.searchsorted(mono, yr, right=True) - 1).clamp(min=0)
            e = torch.minimum(e, (last - 1).clamp(min=0))
            xa, ya = cu.gather(-1, e), cv.gather(-1, e)
            xb, yb = cu.gather(-1, e + 1), cv.gather(-1, e + 1)
            d = yb - ya
            slope = torch.where(d > 0, (xb - xa) / torch.where(d > 0, d, torch.ones_like(d)), torch.zeros_like(d))
            xs.append(xa + (yr - ya) * slope)
        inside = valid[..., None] & (yr >= v.amin(-1, keepdim=True)) & (yr <= v.amax(-1, keepdim=True))
        lf = torch.ceil(torch.minimum(xs[0], xs[1])).clamp(min=0)
        rf = torch.floor(torch.maximum(xs[0], xs[1])).clamp(max=W - 1)
        ok = inside & (lf <= rf)
        lo_i = torch.where(ok, lf, torch.full_like(lf, W)).long().transpose(-1, -2)  # (N, C, Hr, K)
        hi_i = torch.where(ok, rf, torch.full_like(rf, -1)).long().transpose(-1, -2)
        # merge each row's spans: sorted by left end, each counts from past the right end so far
        lo_s, order = lo_i.sort(-1)
        hi_s = hi_i.gather(-1, order)
        run = hi_s.cummax(-1).values
        prev = torch.cat([torch.full_like(run[..., :1], -1), run[..., :-1]], -1)
        st = torch.maximum(lo_s, prev + 1)
        take = hi_s >= st
        Pc = torch.where(take, hi_s - st + 1, 0).sum((-1, -2))
        base = ((torch.arange(C, device=self.device)[:, None] * H
                 + torch.arange(y0, y1 + 1, device=self.device)[None, :]) * (W + 1))[None, :, :, None]
        pre = ft["prefix"]
        Yc = torch.where(take, pre[base + torch.where(take, hi_s + 1, 0)] - pre[base + torch.where(take, st, 0)],
                         0).sum((-1, -2))
        return Yc, Pc

    # ------------------------------------------------------------------ edge samples
    def _edge_sums(self, geo: dict, ft: dict, prep: PreparedFrame, request: Request):
        """Sums of ``p``, ``(1 - p)^2`` and the count over the visible edge samples per (pose, view)."""
        torch = self.torch
        z, tangent = geo["z"], geo["tangent"]
        N, C = z.shape[:2]
        spacing = float(request.edge_spacing)
        W, H = prep.width, prep.height
        zero = torch.zeros((N, C), dtype=self.dtype, device=self.device)
        out = [zero, zero, zero]

        def add(x, y, m):
            x, y, m = x.reshape(N, C, -1), y.reshape(N, C, -1), m.reshape(N, C, -1)
            p = torch.where(m, _pixel_values(torch, ft["edges"], x, y, W, H), 0.0)
            out[0] = out[0] + p.sum(-1)
            out[1] = out[1] + torch.where(m, (1.0 - p) ** 2, 0.0).sum(-1)
            out[2] = out[2] + m.sum(-1).to(self.dtype)

        use = tangent & self._mask(request)
        if bool(use.any()):
            x, y, m = self._line_samples(geo, use, spacing)
            add(x, y, m)
        top = int(request.top_cone)
        if top >= 0:
            arc = self._top_arc(geo, top, spacing)
            if arc is not None:
                x, y, zz, m = arc
                m = m & ~self._hidden(geo, x, y, zz, top)
                add(x, y, m)
        return tuple(out)

    def _line_ends(self, geo: dict):
        """End points ``(u, v, depth)`` of both silhouette lines, ``p0, q0 (N, C, K, 2, 3)``: side 0 from
        the end of the start cap's arc to the start of the end cap's, side 1 from the first vertex to
        the last."""
        torch = self.torch
        uv, z = geo["uv"], geo["z"]
        n_rim, P = self.n_rim, uv.shape[3]
        pq = torch.cat([uv, z[..., None]], -1)  # (N, C, K, P, 3)
        p0 = torch.stack([pq[..., n_rim + 1, :], pq[..., 0, :]], -2)
        q0 = torch.stack([pq[..., n_rim + 2, :], pq[..., P - 1, :]], -2)
        return p0, q0

    def _line_counts(self, p0, q0, use, spacing: float):
        """Samples per silhouette line ``(N, C, K, 2)`` (ends from :meth:`_line_ends`), 0 for the cones
        not in ``use``."""
        n = _n_samples(self.torch, self.torch.linalg.vector_norm(q0[..., :2] - p0[..., :2], dim=-1), spacing)
        return self.torch.where(use[..., None], n, 0)

    def _line_samples(self, geo: dict, use, spacing: float):
        """Visible samples at ``t = (i + 1/2) / n`` on both silhouette lines of the cones ``use``.

        As the numba kernel: each line is clipped to every other drawn outline once (Cyrus-Beck, an
        interval of ``t``); a sample is hidden where it lies in such an interval and that cone's axis is
        nearer there. Returns ``x, y, mask``, each ``(N, C, K, 2, S)``.
        """
        torch = self.torch
        uv, valid = geo["uv"], geo["valid"]
        K = valid.shape[-1]
        p0, q0 = self._line_ends(geo)
        d = q0 - p0
        n = self._line_counts(p0, q0, use, spacing)
        S = int(n.max())
        i = torch.arange(S, device=self.device)
        t = (i + 0.5) / n.clamp(min=1)[..., None].to(self.dtype)  # (N, C, K, 2, S)
        x = p0[..., 0, None] + t * d[..., 0, None]
        y = p0[..., 1, None] + t * d[..., 1, None]
        zs = p0[..., 2, None] + t * d[..., 2, None]
        m = i < n[..., None]
        # clip each line (N, C, K, 2) to each outline j (K) with edges (P): f0 + t f1 >= 0 on every edge
        ea = uv[:, :, None, None]  # (N, C, 1, 1, K, P, 2)
        e = uv.roll(-1, -2)[:, :, None, None] - ea
        o = geo["orient"][:, :, None, None, :, None]
        px, py = p0[..., 0, None, None], p0[..., 1, None, None]  # (N, C, K, 2, 1, 1)
        dx, dy = d[..., 0, None, None], d[..., 1, None, None]
        f0 = o * (e[..., 0] * (py - ea[..., 1]) - e[..., 1] * (px - ea[..., 0]))
        f1 = o * (e[..., 0] * dy - e[..., 1] * dx)  # (N, C, K, 2, K, P)
        safe = torch.where(f1 != 0, f1, torch.ones_like(f1))
        t_in = torch.where(f1 > 0, -f0 / safe, 0.0).amax(-1).clamp(min=0.0)
        t_out = torch.where(f1 < 0, -f0 / safe, 1.0).amin(-1).clamp(max=1.0)
        miss = ((f1 == 0) & (f0 < 0)).any(-1)
        ax = geo["axis"]  # (N, C, K, 2, 3)
        zmax = torch.maximum(p0[..., 2], q0[..., 2])  # (N, C, K, 2)
        near_j = ax[..., 2].amin(-1)[:, :, None, None, :] < zmax[..., None]  # (N, C, K, 2, K)
        other = torch.arange(K, device=self.device)[:, None, None] != torch.arange(K, device=self.device)
        cover = ~miss & (t_in <= t_out) & near_j & valid[:, :, None, None, :] & other  # (N, C, K, 2, K)
        if bool(cover.any()):
            # depth of cone j's axis at each sample (N, C, K, 2, S, K)
            a0 = ax[:, :, None, None, None, :, 0]
            a1 = ax[:, :, None, None, None, :, 1]
            zj = _axis_depth(torch, a0, a1, x[..., None], y[..., None])
            tt = t[..., None]
            hid = (cover[..., None, :] & (t_in[..., None, :] <= tt) & (tt <= t_out[..., None, :])
                   & (zj < zs[..., None])).any(-1)
            m = m & ~hid
        return x, y, m

    def _arc_geometry(self, geo: dict, k: int, spacing: float):
        """The end cap's outline arc of cone ``k`` as a polyline ``(N, C, n_rim + 2, 3)`` (a closed rim:
        back to its start, padded with it), its segment lengths, their running sums and the sample count
        ``(N, C)`` (0 where no arc is drawn)."""
        torch = self.torch
        uv, z = geo["uv"][:, :, k], geo["z"][:, :, k]
        tangent, valid, use1 = geo["tangent"][:, :, k], geo["valid"][:, :, k], geo["use1"][:, :, k]
        n_rim = self.n_rim
        pq = torch.cat([uv, z[..., None]], -1)  # (N, C, P, 3)
        rim = torch.cat([pq[..., :n_rim, :], pq[..., :1, :], pq[..., :1, :]], -2)
        poly = torch.where(tangent[..., None, None], pq[..., n_rim + 2:, :], rim)
        seg = torch.linalg.vector_norm(poly[..., 1:, :2] - poly[..., :-1, :2], dim=-1)  # (N, C, n_rim + 1)
        cum = seg.cumsum(-1)
        n = torch.where(valid & (tangent | use1), _n_samples(torch, cum[..., -1], spacing), 0)
        return poly, seg, cum, n

    def _top_arc(self, geo: dict, k: int, spacing: float):
        """Samples at arc lengths ``(i + 1/2) L / n`` along the end cap's outline arc of cone ``k``
        (the torso's upper edge): ``x, y, depth, mask (N, C, S)``; ``None`` when no view draws one."""
        torch = self.torch
        poly, seg, cum, n = self._arc_geometry(geo, k, spacing)
        S = int(n.max())
        if S == 0:
            return None
        i = torch.arange(S, device=self.device)
        sarc = (i + 0.5) * cum[..., -1:] / n.clamp(min=1)[..., None].to(self.dtype)  # (N, C, S)
        j = torch.searchsorted(cum.contiguous(), sarc.contiguous()).clamp(max=seg.shape[-1] - 1)
        sl = seg.gather(-1, j)
        start = cum.gather(-1, j) - sl
        tt = torch.where(sl > 0, (sarc - start) / torch.where(sl > 0, sl, torch.ones_like(sl)), 0.0).clamp(0.0, 1.0)
        a = poly.gather(-2, j[..., None].expand(*j.shape, 3))
        b = poly.gather(-2, (j + 1)[..., None].expand(*j.shape, 3))
        pt = a + tt[..., None] * (b - a)
        return pt[..., 0], pt[..., 1], pt[..., 2], i < n[..., None]

    def _hidden(self, geo: dict, x, y, z, k: int):
        """``(N, C, M)`` bool: sample ``(x, y)`` at depth ``z`` on cone ``k`` lies inside the outline of
        another drawn cone whose axis is nearer there (:func:`swarmpose.render._kernels.hidden`)."""
        torch = self.torch
        uv, axis, bbox, orient, valid = geo["uv"], geo["axis"], geo["bbox"], geo["orient"], geo["valid"]
        K = valid.shape[-1]
        xq, yq, zq = x[..., None], y[..., None], z[..., None]  # (N, C, M, 1) against the cones (.., K)
        other = (torch.arange(K, device=self.device) != k) & valid[:, :, None, :]
        bb = bbox[:, :, None]  # (N, C, 1, K, 4)
        cand = other & (xq >= bb[..., 0]) & (xq <= bb[..., 1]) & (yq >= bb[..., 2]) & (yq <= bb[..., 3])
        zj = _axis_depth(torch, axis[:, :, None, :, 0], axis[:, :, None, :, 1], xq, yq)  # (N, C, M, K)
        cand = cand & (zj < zq)
        if not bool(cand.any()):
            return torch.zeros_like(cand[..., 0])
        pa = uv[:, :, None]  # (N, C, 1, K, P, 2)
        pb = uv.roll(-1, -2)[:, :, None]
        cr = ((pb[..., 0] - pa[..., 0]) * (yq[..., None] - pa[..., 1])
              - (pb[..., 1] - pa[..., 1]) * (xq[..., None] - pa[..., 0]))  # (N, C, M, K, P)
        inside = ((cr * orient[:, :, None, :, None]) >= 0).all(-1)
        return (cand & inside).any(-1)

    # ------------------------------------------------------------------ interior points
    def _region_counts(self, geo: dict, spacing: float):
        """Interior grid size ``(nt, ns)``, each ``(N, C, K)``, of the cones with silhouette lines (0
        elsewhere): ``nt`` along the projected axis, ``ns`` across the wider end."""
        torch = self.torch
        tangent = geo["tangent"]
        p, q = self._line_ends(geo)  # (N, C, K, side, 3): start-cap and end-cap ends of both lines
        ax = geo["axis"][..., :2]
        nt = _n_samples(torch, torch.linalg.vector_norm(ax[..., 1, :] - ax[..., 0, :], dim=-1), spacing)
        width = torch.maximum(torch.linalg.vector_norm(p[..., 1, :2] - p[..., 0, :2], dim=-1),
                              torch.linalg.vector_norm(q[..., 1, :2] - q[..., 0, :2], dim=-1))
        ns = _n_samples(torch, width, spacing)
        return torch.where(tangent, nt, 0), torch.where(tangent, ns, 0)

    def _region_sums(self, geo: dict, ft: dict, prep: PreparedFrame, spacing: float):
        """Deutscher & Reid eq. 15: sum of ``(1 - O)^2`` and the count over every drawn cone's interior
        grid (:func:`swarmpose.render.reference.region_samples_reference`)."""
        torch = self.torch
        uv, valid, tangent = geo["uv"], geo["valid"], geo["tangent"]
        N, C, K = uv.shape[:3]
        n_rim = self.n_rim
        W, H = prep.width, prep.height
        sil = ft["sil"]
        sq = torch.zeros((N, C), dtype=self.dtype, device=self.device)
        cnt = torch.zeros((N, C), dtype=self.dtype, device=self.device)
        if bool(tangent.any()):
            p, q = self._line_ends(geo)
            p0, q0, p1, q1 = p[..., 0, :2], q[..., 0, :2], p[..., 1, :2], q[..., 1, :2]
            nt, ns = self._region_counts(geo, spacing)
            T, S = int(nt.max()), int(ns.max())
            it = torch.arange(T, device=self.device)
            js = torch.arange(S, device=self.device)
            t = ((it + 0.5) / nt.clamp(min=1)[..., None].to(self.dtype))[..., :, None, None]  # (N, C, K, T, 1, 1)
            u = ((js + 0.5) / ns.clamp(min=1)[..., None].to(self.dtype))[..., None, :, None]  # (N, C, K, 1, S, 1)
            e = (slice(None),) * 3 + (None, None)
            left = p0[e] + t * (q0 - p0)[e]
            right = p1[e] + t * (q1 - p1)[e]
            pt = left + u * (right - left)  # (N, C, K, T, S, 2)
            m = (it[:, None] < nt[..., None, None]) & (js[None, :] < ns[..., None, None])
            o = _pixel_values(torch, sil, pt[..., 0].reshape(N, C, -1), pt[..., 1].reshape(N, C, -1), W, H)
            m = m.reshape(N, C, -1)
            sq = sq + torch.where(m, (1.0 - o) ** 2, 0.0).sum(-1)
            cnt = cnt + m.sum(-1).to(self.dtype)
        closed = valid & ~tangent
        if bool(closed.any()):
            v = uv[..., :n_rim, :]  # the whole rim: the outline's n_rim vertices
            g = v.mean(-2, keepdim=True)
            pt = torch.cat([g, g + 0.5 * (v - g)], -2)  # (N, C, K, n_rim + 1, 2)
            o = _pixel_values(torch, sil, pt[..., 0].reshape(N, C, -1), pt[..., 1].reshape(N, C, -1), W, H)
            m = closed[..., None].expand(N, C, K, n_rim + 1).reshape(N, C, -1)
            sq = sq + torch.where(m, (1.0 - o) ** 2, 0.0).sum(-1)
            cnt = cnt + m.sum(-1).to(self.dtype)
        return sq, cnt


# ---------------------------------------------------------------------- helpers
def _plan_chunks(cost: np.ndarray, budget: int) -> list[np.ndarray]:
    """Pose indices in chunks whose size times their largest ``cost`` stays within ``budget`` (a pose
    over it alone gets a chunk of its own): the costliest poses first, so that one pose near a camera
    does not inflate the tensors of a chunk of ordinary ones."""
    order = np.argsort(-cost, kind="stable")
    chunks = []
    i = 0
    while i < len(order):
        n = max(1, int(budget // max(int(cost[order[i]]), 1)))
        chunks.append(np.sort(order[i:i + n]))
        i += n
    return chunks


def _elementary(torch, axis: int, angle):
    """Rotations about x (0), y (1) or z (2) by ``angle (N,)``: ``(N, 3, 3)``."""
    c, s = torch.cos(angle), torch.sin(angle)
    one, zero = torch.ones_like(c), torch.zeros_like(c)
    if axis == 0:
        rows = ((one, zero, zero), (zero, c, -s), (zero, s, c))
    elif axis == 1:
        rows = ((c, zero, s), (zero, one, zero), (-s, zero, c))
    else:
        rows = ((c, -s, zero), (s, c, zero), (zero, zero, one))
    return torch.stack([torch.stack(r, -1) for r in rows], -2)


def _project(torch, pts, cam):
    """Bouguet projection of camera-frame points ``(..., 3)``; ``cam (..., 11)`` broadcasts against
    ``pts[..., 0]`` (:func:`swarmpose.render._kernels.project_cam_point`)."""
    fx, fy, cx, cy, skew, k1, k2, p1, p2, k3, r2max = cam.unbind(-1)
    a = pts[..., 0] / pts[..., 2]
    b = pts[..., 1] / pts[..., 2]
    r2 = a * a + b * b
    rr = r2.minimum(r2max)
    radial = 1.0 + rr * (k1 + rr * (k2 + rr * k3))
    xd = a * radial + 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a)
    yd = b * radial + p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b
    return torch.stack([fx * (xd + skew * yd) + cx, fy * yd + cy], -1)


def _axis_depth(torch, a0, a1, x, y):
    """Depth of a cone's axis (projected end points ``a0, a1 (..., 3)`` as ``u, v, depth``) at the
    orthogonal projection of ``(x, y)`` onto it, clamped to the segment; ``t = 1/2`` for a point-like
    axis (:func:`swarmpose.render._kernels.axis_depth_at`)."""
    dx, dy = a1[..., 0] - a0[..., 0], a1[..., 1] - a0[..., 1]
    L2 = dx * dx + dy * dy
    long = L2 > 1e-12
    t = ((x - a0[..., 0]) * dx + (y - a0[..., 1]) * dy) / torch.where(long, L2, torch.ones_like(L2))
    t = torch.where(long, t.clamp(0.0, 1.0), 0.5)
    return a0[..., 2] + t * (a1[..., 2] - a0[..., 2])


def _n_samples(torch, length, spacing: float):
    """``max(1, floor(length / spacing + 1/2))`` as long."""
    return torch.floor(length / spacing + 0.5).clamp(min=1).long()


def _pixel_values(torch, img_flat, x, y, W: int, H: int):
    """``img[c, floor(y + 1/2), floor(x + 1/2)]`` for points ``(N, C, M)`` in view ``c``; 0 outside."""
    xi = torch.floor(x + 0.5)
    yi = torch.floor(y + 0.5)
    ok = (xi >= 0) & (yi >= 0) & (xi < W) & (yi < H)
    C = x.shape[1]
    view = torch.arange(C, device=x.device)[None, :, None]
    idx = torch.where(ok, (view * H + yi.long().clamp(0, H - 1)) * W + xi.long().clamp(0, W - 1), 0)
    return torch.where(ok, img_flat[idx], 0.0)
