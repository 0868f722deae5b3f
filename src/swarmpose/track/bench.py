"""``swarmpose bench track``: one run of a sequence, its wall time split by part of the frame loop."""

from __future__ import annotations

import dataclasses
import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.track.timing import PARTS
from swarmpose.track.tracker import TrackConfig, TrackSetup, prepare_track, run_tracker

__all__ = ["bench_track", "repeated"]

#: What each part of :data:`~swarmpose.track.timing.PARTS` covers.
PART_HELP = {
    "features": "waiting for the frame (read, background subtraction, silhouettes and edge maps run ahead on a "
                "worker thread) and the per-frame preparation",
    "motion": "motion model: the prediction and the moved particle set",
    "optimiser": "the search's own work (ask/tell, sampling, weights), without fitness and priors; a PSO's moves "
                 "with the priors that gate them, which run as one compiled call",
    "fitness": "fitness kernels (kinematics, projection, silhouette, edges; the distance maps)",
    "priors": "hard priors: joint limits and limb collisions (where not inside a PSO's compiled moves)",
    "recovery": "loss detection and re-search, without fitness and priors",
    "keypoint_ik": "the fits of a frame's pose to its triangulated keypoints (after the searches; from the "
                   "prediction with keypoint_proposals)",
    "consensus": "a run with members: their poses fused into the frame's (the fit to their joints' median)",
    "writing": "results written per frame (progress files)",
}


def _peak_rss_mb() -> float:
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb / 1024.0 if sys.platform != "darwin" else kb / 2**20


#: How many memory samples :func:`bench_track` takes along a run (at most).
MEMORY_SAMPLES = 40
_STATUS_FIELDS = {"VmRSS": "rss_mb", "RssAnon": "anon_mb", "RssFile": "file_mb"}


def memory_now() -> dict[str, float]:
    """The process's resident memory, MB: ``rss_mb`` and, where the kernel says, ``anon_mb`` (heap and other
    private memory) and ``file_mb`` (mapped files and libraries), from ``/proc/self/status``; {} elsewhere."""
    out: dict[str, float] = {}
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                key, _, value = line.partition(":")
                if key in _STATUS_FIELDS:
                    out[_STATUS_FIELDS[key]] = int(value.split()[0]) / 1024.0  # kB
    except (OSError, ValueError):
        return {}
    return out


def memory_growth(samples: list[dict[str, Any]], key: str = "rss_mb") -> float | None:
    """KB per frame that ``key`` grew by over the last three quarters of the run (a line fitted to the samples
    from the first quarter's end on: setting up and the first frames' caches are left out); None with fewer
    than 3 such samples."""
    if not samples:
        return None
    last = samples[-1]["frame"]
    pts = [(s["frame"], s[key]) for s in samples if key in s and s["frame"] >= last / 4]
    if len(pts) < 3:
        return None
    f, m = np.array(pts, dtype=float).T
    return float(np.polyfit(f, m, 1)[0] * 1024.0)


def repeated(setup: TrackSetup, times: int) -> TrackSetup:
    """The tracked frames played ``times`` times in a row, every other pass backwards (a long recording from
    a short clip with no jump between the passes: the motion reverses, the clock runs on at the tracking
    rate), for measuring how the cost per frame grows with the length of a recording."""
    if isinstance(times, bool) or int(times) != times or times < 1:
        raise ConfigError(f"--repeat must be a whole number >= 1, got {times!r}")
    n = int(times)
    if n == 1 or len(setup.frame_indices) < 2:
        return setup
    fwd = np.arange(len(setup.frame_indices))
    order = np.concatenate([fwd if k % 2 == 0 else fwd[::-1] for k in range(n)])
    order = order[np.concatenate([[True], order[1:] != order[:-1]])]  # a turn does not repeat its frame
    t = setup.frame_times
    step = float(np.median(np.diff(t)))
    return dataclasses.replace(
        setup, frame_indices=setup.frame_indices[order], frame_times=t[0] + step * np.arange(len(order)),
        gt_joints=setup.gt_joints[order], ik_params=setup.ik_params[order], ik_error_mm=setup.ik_error_mm[order])


def bench_track(sequence: str | Path, config: TrackConfig, *, run: int = 0, repeat: int = 1,
                feature_cache: str | Path | None = None) -> dict[str, Any]:
    """Track one run of ``sequence`` (in this process, into a temporary folder) and time it by part.

    ``repeat``: play the tracked frames that many times, forwards and backwards (:func:`repeated`). With
    ``config.backward`` the run makes its offline second pass as ``track --backward`` does, and a frame's time is
    its two searches' together.
    Returns ``{"frames", "seconds", "frames_per_s", "parts": [{"part", "seconds", "ms_per_frame", "share"}],
    "d_mean_mm", "evals_per_frame", "peak_rss_mb", "memory", ...}``; the first frame's kernel compilation is not
    counted (as in ``track``). ``memory``: up to :data:`MEMORY_SAMPLES` samples of :func:`memory_now` along the run
    (``frame``: frames done), and ``rss_growth_kb_per_frame`` / ``anon_growth_kb_per_frame``
    (:func:`memory_growth`): a long run whose memory is flat grows by about 0.
    """
    t0 = time.perf_counter()
    samples: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="swarmpose-bench-") as tmp:
        setup = repeated(prepare_track(sequence, config, Path(tmp)), repeat)
        t_setup = time.perf_counter() - t0
        every = max(1, setup.progress_frames // MEMORY_SAMPLES)  # with the backward pass: both passes' frames

        def sample(done: int, total: int) -> None:
            if done % every == 0 or done == total:
                samples.append({"frame": int(done), **memory_now()})

        result = run_tracker(setup, run, Path(tmp), feature_cache=feature_cache, progress=sample)
    # the time per frame along the run: a cost that grows with the recording shows as a rising last quarter
    quarter = max(1, len(result.seconds) // 4)
    first_q = float(result.seconds[:quarter].mean()) if len(result.seconds) else 0.0
    last_q = float(result.seconds[-quarter:].mean()) if len(result.seconds) else 0.0
    frames = len(result.seconds)
    total = float(result.seconds.sum())
    parts = []
    for name in PARTS:
        s = float(result.part_seconds.get(name, 0.0))
        parts.append({"part": name, "what": PART_HELP[name], "seconds": s, "ms_per_frame": 1e3 * s / max(frames, 1),
                      "share": s / total if total > 0 else 0.0})
    # the frame clock (``seconds``) stops before the results are written; every other part is inside it
    timed_in_frames = sum(p["seconds"] for p in parts if p["part"] != "writing")
    return {
        "sequence": str(sequence),
        "algo": config.algo,
        "variant": config.optim_variant,
        "fps": config.fps,
        "views": config.views or "all",
        "downsample": config.downsample,
        "backward": bool(config.backward),
        "frames": frames,
        "repeat": int(repeat),
        "ms_per_frame_first_quarter": 1e3 * first_q,
        "ms_per_frame_last_quarter": 1e3 * last_q,
        "seconds": total,
        "frames_per_s": frames / total if total > 0 else 0.0,
        "ms_per_frame": 1e3 * total / max(frames, 1),
        "untimed_ms_per_frame": 1e3 * max(total - timed_in_frames, 0.0) / max(frames, 1),
        "parts": parts,
        "evals_per_frame": int(result.evaluations.max()) if frames else 0,
        "d_mean_mm": result.errors.get("d_mean"),
        "setup_s": t_setup,
        "feature_store": result.feature_store,  # frames whose features were read from the store, and computed
        "peak_rss_mb": _peak_rss_mb(),
        "memory": samples,
        "rss_growth_kb_per_frame": memory_growth(samples, "rss_mb"),
        "anon_growth_kb_per_frame": memory_growth(samples, "anon_mb"),
    }
