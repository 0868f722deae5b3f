"""Fitness throughput benchmark (the engine of ``swarmpose bench fitness``).

Evaluations per second of each backend for the full pipeline -- kinematics, cone projection with
end caps, silhouette (eq. 5.2-5.5) and edge (eq. 5.1) terms, ``C`` views -- at several pyramid levels
and batch sizes, on the demo scene of :mod:`swarmpose.fitness.scene` (HumanEva-like 4-camera rig,
644x484, candidates ``pose + N(0, sigma)``), plus the per-frame preparation time from raw images
(background subtraction, edge maps, prefix sums). One evaluation = one pose scored in all views.

Timing: each measurement is the median of ``repeats`` runs, each looping the batch for at least
``min_time`` seconds (the reference backend: one call per run, at most ``reference_max_batch``
poses). The machine's load average is recorded before and after, because other processes on a
small machine change the numbers a lot.
"""

from __future__ import annotations

import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

__all__ = ["machine_info", "run_fitness_benchmark", "time_call"]


def time_call(fn: Callable[[], Any], *, repeats: int = 5, min_time: float = 0.2) -> float:
    """Median seconds per call of ``fn`` over ``repeats`` runs of at least ``min_time`` s each.

    Before them, ``fn`` is called once and then for another ``min_time`` s: JIT compilation, caches and, for
    PyTorch, its allocator and thread pool need more than one call to settle (one warm-up call made
    torch's rate 20 % low with ``min_time=0.1``).
    """
    fn()  # the first call may compile: the warm-up time starts after it
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < min_time:
        fn()
    runs = []
    for _ in range(max(1, repeats)):
        n = 0
        t0 = time.perf_counter()
        while True:
            fn()
            n += 1
            el = time.perf_counter() - t0
            if el >= min_time:
                break
        runs.append(el / n)
    return statistics.median(runs)


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _loadavg() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (OSError, AttributeError):
        return None


def machine_info() -> dict[str, Any]:
    """CPU, core count, numba threads and threading layer, library versions, load average."""
    import cv2
    import numba

    from swarmpose import __version__ as sp_version

    info: dict[str, Any] = {
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "opencv": cv2.__version__,
        "swarmpose": sp_version,
        "numba_threads": numba.get_num_threads(),
        "numba_backend_threads": "pool",  # NumbaBackend default (GIL-free kernel on a thread pool)
        "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY"),
        "loadavg_start": _loadavg(),
    }
    try:
        info["numba_threading_layer"] = numba.threading_layer()
    except ValueError:  # no parallel region has run yet
        info["numba_threading_layer"] = None
    return info


def run_fitness_benchmark(
    *,
    backends: Sequence[str] = ("numba", "reference"),
    scales: Sequence[int] = (1, 2, 4),
    batches: Sequence[int] = (20, 200),
    n_views: int = 4,
    repeats: int = 5,
    min_time: float = 0.3,
    reference_max_batch: int = 200,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Measure evaluations/s; returns the ``--json`` document of ``swarmpose bench fitness``.

    Parameters
    ----------
    backends : sequence of str
        Backend names; ``"reference"`` (if present) is the denominator of ``ratio_to_reference``.
    scales : sequence of int
        Downsampling factors of the 644x484 frame (1: full, 2: half, 4: quarter).
    batches : sequence of int
        Poses per fitness call.
    n_views : int, default 4
    repeats, min_time : timing settings (see :func:`time_call`).
    reference_max_batch : int, default 200
        The reference backend is timed on at most this many poses of each batch.
    seed : int
    progress : callable, optional
        Called with a short message before each measurement.

    Returns
    -------
    dict
        ``{"machine": {...}, "rows": [{"backend", "width", "height", "batch", "evals_per_s",
        "ratio_to_reference"}, ...], "prepare_ms": float, "prepare": {...}}`` where ``prepare_ms`` is
        the median per-frame preparation of ``n_views`` raw full-resolution images (features and
        prefix sums) and ``prepare`` its parts and the per-level values.
    """
    from swarmpose.body.model import load_model
    from swarmpose.features import compute_features
    from swarmpose.fitness import make_fitness, prepare_frame
    from swarmpose.fitness.scene import demo_cameras, demo_images

    say = progress or (lambda _msg: None)
    machine = machine_info()
    rng = np.random.default_rng(seed)
    model = load_model("balan31")
    pose = model.zero_pose()
    pose[5] = 1000.0  # pelvis height, mm
    pose[model.param_index("l_shoulder_abd")] = 0.35
    pose[model.param_index("r_shoulder_abd")] = -0.35
    cams = demo_cameras(n_views)
    say("rendering the demo scene")
    images, backgrounds = demo_images(model, pose, cams, rng=rng)
    full = compute_features(images, backgrounds, cams)
    t_feat = time_call(lambda: compute_features(images, backgrounds, cams), repeats=repeats, min_time=min_time)
    t_prep = time_call(lambda: prepare_frame(full), repeats=repeats, min_time=min_time)
    prepare: dict[str, Any] = {"features_ms": t_feat * 1e3, "prefix_ms": t_prep * 1e3, "levels": {}}
    max_batch = max(batches)
    candidates = pose + rng.normal(0.0, 1.0, (max_batch, model.n_params)) * model.sigma
    fits = {b: make_fitness("silhouette_edge", model, backend=b) for b in backends}
    rows = []
    for scale in scales:
        frame = full.downsample(scale)
        w, h = frame.size
        t_lvl = time_call(lambda scale=scale: compute_features(images, backgrounds, cams, downsample=scale),
                          repeats=max(1, repeats // 2), min_time=min_time / 2)
        prepared = prepare_frame(frame)
        prepare["levels"][f"{w}x{h}"] = (t_lvl * 1e3 + prepared.prepare_ms)
        rates: dict[tuple[str, int], float] = {}
        for b, fit in fits.items():
            fit.bind(prepared)
            for batch in batches:
                poses = np.ascontiguousarray(candidates[:batch])
                say(f"{b} {w}x{h} batch {batch}")
                if b == "reference":
                    poses = poses[:reference_max_batch]
                    dt = time_call(lambda poses=poses, fit=fit: fit(poses), repeats=1, min_time=0.0)
                else:
                    dt = time_call(lambda poses=poses, fit=fit: fit(poses), repeats=repeats, min_time=min_time)
                rates[(b, batch)] = len(poses) / dt
        for b in fits:
            for batch in batches:
                ref = rates.get(("reference", batch))
                rows.append({"backend": b, "width": w, "height": h, "batch": int(batch),
                             "evals_per_s": rates[(b, batch)],
                             "ratio_to_reference": rates[(b, batch)] / ref if ref else None})
    machine["loadavg_end"] = _loadavg()
    if "torch" in fits:
        be = fits["torch"].backend
        machine["torch"] = be.torch.__version__
        machine["torch_device"] = (be.torch.cuda.get_device_name(be.device) if be.device.type == "cuda"
                                   else str(be.device))
    try:
        import numba

        machine["numba_threading_layer"] = numba.threading_layer()
    except ValueError:
        pass
    return {"machine": machine, "rows": rows, "prepare_ms": (t_feat + t_prep) * 1e3, "prepare": prepare}
