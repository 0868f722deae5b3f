"""What ``track --smooth S`` does to finished tracks: D_mean, MMTA and jitter before and after, per results folder.

The smoothing is applied after tracking (``swarmpose.track.smooth.smooth_params`` on each run's poses), so it is
measured here on folders already tracked: the same numbers ``track ... --smooth S`` writes. Jitter is the mean
joint acceleration (``swarmpose.metrics.joint_acceleration``, mm/s^2), beside the ground truth's own.

Run:  .venv/bin/python scripts/smoothing_effect.py RESULTS_FOLDER ... [--sigmas 0.025 0.05 0.075] [--json]
(e.g. the folders of scripts/forward_backward.py: results/CLIP-refined-20fps[-backward])
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from swarmpose.metrics import joint_acceleration, track_errors
from swarmpose.track.smooth import smooth_params
from swarmpose.track.tracker import TrackConfig, prepare_track


def folder_effect(folder: Path, sigmas: list[float]) -> dict:
    record = json.loads((folder / "config.json").read_text())
    fields = set(TrackConfig.__dataclass_fields__)
    cfg = TrackConfig(**{k: v for k, v in record.items() if k in fields})
    setup = prepare_track(record["sequence"], cfg, None)
    m, t = setup.model, setup.frame_times
    rows = {s: {"d_mean_mm": [], "d_max_mm": [], "mmta": [], "acceleration_mm_s2": []} for s in [0.0, *sigmas]}
    for run in sorted(folder.glob("run_*/track.npz")):
        with np.load(run) as z:
            raw = z["raw_params"] if "raw_params" in z else z["params"]
        for s, row in rows.items():
            joints = m.joints15(smooth_params(raw, t, s, m.is_rotation, m.lower, m.upper))
            summary = track_errors(joints, setup.gt_joints).summary()
            row["d_mean_mm"].append(summary["d_mean"])
            row["d_max_mm"].append(summary["d_max"])
            row["mmta"].append(summary["mmta"])
            row["acceleration_mm_s2"].append(joint_acceleration(joints, t))
    return {"folder": folder.name, "gt_acceleration_mm_s2": joint_acceleration(setup.gt_joints, t),
            "sigmas": {f"{s:g}": {**{k: float(np.mean(v)) for k, v in row.items()},
                                  "d_max_worst_run_mm": float(np.max(row["d_max_mm"]))} for s, row in rows.items()}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--sigmas", nargs="*", type=float, default=[0.025, 0.05, 0.075])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = [folder_effect(f, args.sigmas) for f in args.folders]
    if args.json:
        print(json.dumps({"folders": rows}))
        return
    keys = ["0", *(f"{s:g}" for s in args.sigmas)]
    print("| results | truth's jitter | " + " | ".join(f"S = {k} s: D_mean / MMTA / jitter" for k in keys) + " |")
    print("|---|---:|" + "---:|" * len(keys))
    for r in rows:
        cells = " | ".join(f"{r['sigmas'][k]['d_mean_mm']:.1f} / {100 * r['sigmas'][k]['mmta']:.1f} % / "
                           f"{r['sigmas'][k]['acceleration_mm_s2'] / 1000:.1f}" for k in keys)
        print(f"| {r['folder']} | {r['gt_acceleration_mm_s2'] / 1000:.1f} | {cells} |")
    print("\n(D_mean in mm and MMTA, means over the runs; jitter in m/s^2)")


if __name__ == "__main__":
    main()
