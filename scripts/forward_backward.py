"""What the offline backward pass (``swarmpose track --backward``) buys, clip by clip.

For each clip: ``swarmpose track CLIP --algo ALGO --runs N`` (forwards only) and the same with ``--backward``,
then one table: D_mean (each run's in brackets), the worst run's D_max, MMTA, frames/s per run, and the share of
frames where the backward pass's pose was kept. Results go to ``results/<clip>-<algo>-<fps>fps[-backward]`` (a
folder that is already complete is reused).

Run:  .venv/bin/python scripts/forward_backward.py [--clips CLIP ...] [--algo refined] [--runs 3] [--fps 20] [--json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

MOCAP = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mocap"
CLIPS = ["cmu_16_16_walk", "cmu_135_04_kick", "cmu_131_01_walk", "cmu_131_03_hop", "cmu_16_02_jump",
         "cmu_16_18_turn", "cmu_16_35_jog", "cmu_49_17_dance"]


def track(clip: str, algo: str, runs: int, fps: float, backward: bool) -> dict:
    out = Path("results") / f"{clip}-{algo}-{fps:g}fps{'-backward' if backward else ''}"
    cmd = [sys.executable, "-m", "swarmpose", "track", str(MOCAP / f"{clip}.bvh"), "--algo", algo, "--runs",
           str(runs), "--fps", f"{fps:g}", "--out", str(out), "--resume", "--json", *(["--backward"] if backward else [])]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{res.stderr[-2000:]}")
    summary = json.loads(res.stdout.strip().splitlines()[-1])
    per_run = [json.loads((out / f"run_{k:03d}" / "summary.json").read_text()) for k in range(runs)]
    kept = [r.get("backward_kept") for r in per_run]
    return {"d_mean_mm": summary["d_mean_mm"], "runs_d_mean_mm": [r["d_mean"] for r in per_run],
            "d_max_mm": max(r["d_max"] for r in per_run), "mmta": summary["mmta"],
            "frames_per_s": summary["frames_per_s"], "frames": summary["frames"],
            "backward_kept": None if None in kept else sum(kept) / (runs * summary["frames"])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="*", default=CLIPS)
    ap.add_argument("--algo", default="refined")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--fps", type=float, default=20.0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = [{"clip": c, "forward": track(c, args.algo, args.runs, args.fps, False),
             "backward": track(c, args.algo, args.runs, args.fps, True)} for c in args.clips]
    if args.json:
        print(json.dumps({"algo": args.algo, "runs": args.runs, "fps": args.fps, "clips": rows}))
        return

    def cell(r: dict) -> str:
        runs = "–".join(f"{x:.1f}" for x in (min(r["runs_d_mean_mm"]), max(r["runs_d_mean_mm"])))
        return f"{r['d_mean_mm']:.1f} ({runs}) | {r['d_max_mm']:.0f} | {100 * r['mmta']:.1f} % | {r['frames_per_s']:.2f}"

    print("| clip | frames | forwards: D_mean (runs) | D_max | MMTA | frames/s | with --backward: D_mean (runs) | "
          "D_max | MMTA | frames/s | backward pose kept |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        f, b = r["forward"], r["backward"]
        print(f"| {r['clip']} | {f['frames']} | {cell(f)} | {cell(b)} | {100 * b['backward_kept']:.0f} % |")
    mean = {k: sum(r[k]["d_mean_mm"] for r in rows) / len(rows) for k in ("forward", "backward")}
    print(f"\nmean over the clips: forwards {mean['forward']:.1f} mm, with --backward {mean['backward']:.1f} mm")


if __name__ == "__main__":
    main()
