"""``swarmpose bench track``: one run of a sequence, its wall time split by part of the frame loop."""

from __future__ import annotations

import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from swarmpose.track.timing import PARTS
from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

__all__ = ["bench_track"]

#: What each part of :data:`~swarmpose.track.timing.PARTS` covers.
PART_HELP = {
    "features": "frame reading, background subtraction, silhouettes, edge maps, per-frame preparation",
    "motion": "motion model: the prediction and the moved particle set",
    "optimiser": "the search's own work (ask/tell, sampling, weights), without fitness and priors",
    "fitness": "fitness kernels (kinematics, projection, silhouette, edges; the distance maps)",
    "priors": "hard priors: joint limits and limb collisions",
    "recovery": "loss detection and re-search, without fitness and priors",
    "writing": "results written per frame (progress files)",
}


def _peak_rss_mb() -> float:
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb / 1024.0 if sys.platform != "darwin" else kb / 2**20


def bench_track(sequence: str | Path, config: TrackConfig, *, run: int = 0) -> dict[str, Any]:
    """Track one run of ``sequence`` (in this process, into a temporary folder) and time it by part.

    Returns ``{"frames", "seconds", "frames_per_s", "parts": [{"part", "seconds", "ms_per_frame", "share"}],
    "d_mean_mm", "evals_per_frame", "peak_rss_mb", ...}``; the first frame's kernel compilation is not counted
    (as in ``track``).
    """
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="swarmpose-bench-") as tmp:
        setup = prepare_track(sequence, config, Path(tmp))
        t_setup = time.perf_counter() - t0
        result = run_tracker(setup, run, Path(tmp))
    frames = len(result.seconds)
    total = float(result.seconds.sum())
    parts = []
    for name in PARTS:
        s = float(result.part_seconds.get(name, 0.0))
        parts.append({"part": name, "what": PART_HELP[name], "seconds": s, "ms_per_frame": 1e3 * s / max(frames, 1),
                      "share": s / total if total > 0 else 0.0})
    timed = sum(p["seconds"] for p in parts)
    return {
        "sequence": str(sequence),
        "algo": config.algo,
        "fps": config.fps,
        "frames": frames,
        "seconds": total,
        "frames_per_s": frames / total if total > 0 else 0.0,
        "ms_per_frame": 1e3 * total / max(frames, 1),
        "untimed_ms_per_frame": 1e3 * max(total - timed + parts[-1]["seconds"], 0.0) / max(frames, 1),
        "parts": parts,
        "evals_per_frame": int(result.evaluations.max()) if frames else 0,
        "d_mean_mm": result.errors.get("d_mean"),
        "setup_s": t_setup,
        "peak_rss_mb": _peak_rss_mb(),
    }
