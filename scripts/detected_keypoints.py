"""The synthetic clips with a detector's keypoints: the default tracker with keypoints as evidence, scored.

For each clip the synthesised sequence (``swarmpose track CLIP``'s, cached) is exported as per-camera PNG
folders and a TOML calibration and read back by ``swarmpose import`` with MediaPipe Pose (keypoints only:
``--silhouettes none``), as a recording of one's own would be. The keypoints, matched across views and
left/right as the import does it, then replace the synthetic sequence's marker stream in a copy of it that keeps
its images, masks, ground truth and subject. That copy is tracked with ``--algo A`` (default: the default
tracker, which weighs keypoints wherever a sequence carries them) into ``WORK/<clip>-<algo>`` and measured
against the ground truth; ``--without`` tracks it a second time with ``--fitness-options keypoints=0`` into
``WORK/<clip>-<algo>-keypoints0`` (the keypoint term off; the default's fit to the keypoints stays).

``--fitness-options TEXT`` passes the track's fitness options on (e.g. ``keypoint_swaps=ends``) and ``--variant
TEXT`` its optimiser variant (e.g. ``keypoint_ik=off``, the default without its fit to the keypoints); both name
the results folder.

``--mocap DIR`` reads the clips from another folder than the shared one (e.g. the mirrored clips of
``scripts/mirrored_clips.py``, motions the tracker was never tuned on).

Run:  .venv/bin/python scripts/detected_keypoints.py [--clips CLIP ...] [--fps 20] [--runs 3] [--algo A]
      [--fitness-options TEXT] [--variant TEXT] [--without] [--mocap DIR] [--work results/detected-keypoints]
      [--json]
Needs MediaPipe Pose (``make detect``).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from swarmpose.export.recording import export_recording
from swarmpose.io.sequence import open_sequence
from swarmpose.synth.synthesize import cached_sequence

MOCAP = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mocap"
CLI = [sys.executable, "-m", "swarmpose"]
CLIPS = ["cmu_16_16_walk", "cmu_135_04_kick", "cmu_131_01_walk", "cmu_131_03_hop", "cmu_16_02_jump",
         "cmu_16_18_turn", "cmu_16_35_jog", "cmu_49_17_dance"]


def run(cmd: list[str]) -> dict:
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def with_keypoints(clip: Path, work: Path) -> tuple[Path, dict]:
    """The clip's synthetic sequence with the detector's keypoints as its marker stream, and the import's summary."""
    seq_path = cached_sequence(clip, progress=False)
    imported, hybrid = work / f"{clip.stem}-imported", work / f"{clip.stem}-keypoints"
    summary_file = work / f"{clip.stem}-import.json"
    if not (imported / "sequence.json").is_file() or not summary_file.is_file():
        rec = work / f"{clip.stem}-recording"
        for p in (rec, imported):
            shutil.rmtree(p, ignore_errors=True)
        with open_sequence(seq_path) as seq:
            export_recording(seq, rec, calibration_format="toml", video=False)
            names, rate = [c.name for c in seq.cameras], seq.frame_rate
        summary = run([*CLI, "import", *[str(rec / n) for n in names], "-c", str(rec / "calibration.toml"), "-o",
                       str(imported), "--silhouettes", "none", "--fps", f"{rate:g}", "--no-page", "--json"])
        summary_file.write_text(json.dumps(summary, indent=1))
        shutil.rmtree(rec, ignore_errors=True)
    summary = json.loads(summary_file.read_text())
    meta = json.loads((seq_path / "sequence.json").read_text())
    imeta = json.loads((imported / "sequence.json").read_text())
    if imeta["n_frames"] != meta["n_frames"] or imeta["views"] != meta["views"]:
        raise SystemExit(f"{imported}: {imeta['n_frames']} frames of {imeta['views']}, expected {meta['n_frames']} "
                         f"of {meta['views']}")
    tmp = hybrid.with_name(hybrid.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(seq_path, tmp)
    shutil.copy(imported / imeta["files"]["markers"], tmp / "markers.npz")
    meta["files"]["markers"], meta["markers"] = "markers.npz", imeta["markers"]
    meta["provenance"] = {**meta.get("provenance", {}), "keypoints": f"MediaPipe Pose on the renders, {imported}"}
    (tmp / "sequence.json").write_text(json.dumps(meta, indent=1))
    shutil.rmtree(hybrid, ignore_errors=True)
    tmp.rename(hybrid)
    return hybrid, summary


def scored(results: Path) -> dict:
    runs = [json.loads(f.read_text()) for f in sorted(results.glob("run_*/summary.json"))]
    d = np.array([r["d_mean"] for r in runs])
    return {"d_mean": float(d.mean()), "runs": d.tolist(), "d_max": max(r["d_max"] for r in runs),
            "mmta": float(np.mean([r["mmta"] for r in runs])),
            "frames_per_s": float(np.mean([r["frames_per_s"] for r in runs]))}


def main() -> None:
    from swarmpose.cli.common import DEFAULT_ALGO

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="*", default=CLIPS)
    ap.add_argument("--fps", type=float, default=20.0)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--algo", default=DEFAULT_ALGO)
    ap.add_argument("--fitness-options", default="", help="the track's --fitness-options (e.g. keypoint_swaps=ends)")
    ap.add_argument("--variant", default="", help="the track's --variant (e.g. keypoint_ik=off)")
    ap.add_argument("--without", action="store_true", help="also track with keypoints=0 (the term off)")
    ap.add_argument("--mocap", type=Path, default=MOCAP, help="the folder of the clips (default: the shared one)")
    ap.add_argument("--work", type=Path, default=Path("results/detected-keypoints"))
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.clips:
        clip = args.mocap / f"{name}.bvh"
        if not clip.is_file():
            raise SystemExit(f"{clip}: no such clip")
        hybrid, imp = with_keypoints(clip, args.work)
        row = {"clip": name, "swapped_view_frames": imp["swapped_view_frames"],
               "view_frames": imp["n_frames"] * len(imp["cameras"]), "found_rate": imp["found_rate"]}
        own = [args.fitness_options] if args.fitness_options else []
        for label, options in (("with", own), ("without", [*own, "keypoints=0"])):
            if label == "without" and not args.without:
                continue
            extra = ["--fitness-options", ",".join(options)] if options else []
            if args.variant:
                extra += ["--variant", args.variant]
            tag = "".join(f"-{o.replace('=', '')}" for o in [*options, *([args.variant] if args.variant else [])])
            tag = tag.replace(",", "-").replace(":", "").replace("+", "")
            out = args.work / f"{name}-{args.algo}{tag}"
            shutil.rmtree(out, ignore_errors=True)
            run([*CLI, "track", str(hybrid), "--algo", args.algo, "--fps", f"{args.fps:g}", "--runs", str(args.runs),
                 "--out", str(out), "--no-progress", "--json", *extra])
            row[label] = scored(out)
        rows.append(row)
        if not args.json:
            r = row["with"]
            print(f"{name}: D_mean {r['d_mean']:.1f} ({', '.join(f'{x:.1f}' for x in r['runs'])}) D_max "
                  f"{r['d_max']:.1f} MMTA {100 * r['mmta']:.1f} %"
                  + (f"; keypoints=0: {row['without']['d_mean']:.1f}" if "without" in row else ""), flush=True)
    if args.json:
        print(json.dumps({"algo": args.algo, "fps": args.fps, "runs": args.runs,
                          "fitness_options": args.fitness_options, "variant": args.variant, "clips": rows}))
    else:
        d = [r["with"]["d_mean"] for r in rows]
        print(f"mean over {len(d)} clips: {np.mean(d):.1f} mm")


if __name__ == "__main__":
    main()
