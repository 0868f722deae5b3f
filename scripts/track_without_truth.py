"""The no-mocap path on a synthetic clip, scored afterwards against the ground truth it withheld.

For each clip: the synthesised sequence (``swarmpose track CLIP``'s, cached) is exported as per-camera PNG
folders, its empty-scene backgrounds and a TOML calibration (no ground truth, no source clip, no subject);
``swarmpose import`` reads it back with the detector (keypoints; silhouettes by background subtraction
against the exported backgrounds, as the tracker computes them on the original); ``track --algo
refined-keypoints --height H`` tracks it with H the clip skeleton's stature; and the track is scored against
the withheld joints. Beside it: ``refined`` on the original sequence, started from the IK fit of the truth,
and the subject's limb lengths against the skeleton's (from stature alone, then from the keypoints).

Run:  .venv/bin/python scripts/track_without_truth.py [--clips CLIP ...] [--fps 20] [--max-frames N] [--runs N] [--import-only]
      [--no-keypoints] [--subject-effect] [--json]
(--import-only: import and fit where the truth's pelvis and thorax lie along the keypoints' trunk, no tracking;
--no-keypoints: import without the detector and track with ``refined --height H`` from the silhouettes alone.)
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from swarmpose.body.anthropometry import HEIGHT_FRACTIONS, limb_lengths, subject_from_height
from swarmpose.body.spec import Subject, load_spec
from swarmpose.export.recording import export_recording
from swarmpose.io.mocap import load_clip, subject_from_clip
from swarmpose.io.sequence import open_sequence
from swarmpose.synth.synthesize import cached_sequence

MOCAP = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mocap"
CLI = [sys.executable, "-m", "swarmpose"]


def stature(subject) -> float:
    o = subject.offsets
    span = (abs(o["l_pelvis_to_hip"][2]) + abs(o["l_thigh"][2]) + abs(o["l_shank"][2]) + o["spine_to_thorax"][2]
            + o["neck_to_head_top"][2])
    return span / (1.0 - HEIGHT_FRACTIONS["ankle"])


def run(cmd: list[str]) -> dict:
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def scored(results: Path, truth: np.ndarray) -> dict:
    """Errors of the runs in ``results`` against ``truth``: means over the runs, and each run's D_mean."""
    from swarmpose.joints import JOINTS15

    dists = []
    for run_dir in sorted(results.glob("run_*")):
        with np.load(run_dir / "joints.npz") as z:
            dists.append(np.linalg.norm(z["joints"] - truth, axis=-1))
    dist = np.stack(dists)  # (runs, T, 15)
    d = dist.mean(axis=2)
    return {"frame0_mm": float(d[:, 0].mean()), "d_mean_mm": float(d.mean()),
            "d_mean_first20_mm": float(d[:, :20].mean()), "d_max_mm": float(d.max(axis=1).mean()),
            "runs_d_mean_mm": d.mean(axis=1).tolist(),
            "per_joint_mm": dict(zip(JOINTS15, dist.mean(axis=(0, 1)).tolist(), strict=True))}


def trunk_fit(imported: Path, truth_all: np.ndarray) -> dict:
    """Where the truth's pelvis and thorax lie along the trunk of the triangulated keypoints: ``pelvis = hip_mid +
    p (shoulder_mid - hip_mid)``, ``thorax = shoulder_mid - t (shoulder_mid - hip_mid)``, least squares over all
    frames (the fractions behind ``swarmpose.detection.joints.PELVIS_FRACTION`` and ``THORAX_FRACTION``), and the
    mean distance to the truth at the midpoints, at the fitted fractions and at the shipped ones."""
    from swarmpose.detection.joints import PELVIS_FRACTION, THORAX_FRACTION
    from swarmpose.joints import JOINT_INDEX as J
    from swarmpose.track.start import keypoint_joints

    with open_sequence(imported) as seq:
        K = keypoint_joints(seq, np.arange(seq.n_frames))
    hip = (K[:, J["l_hip"]] + K[:, J["r_hip"]]) / 2
    sh = (K[:, J["l_shoulder"]] + K[:, J["r_shoulder"]]) / 2
    ok = np.isfinite(hip).all(axis=1) & np.isfinite(sh).all(axis=1)
    d = (sh - hip)[ok]
    out = {}
    for name, base, sign, shipped in (("pelvis", hip, 1.0, PELVIS_FRACTION), ("thorax", sh, -1.0, THORAX_FRACTION)):
        r = (truth_all[:, J[name]] - base)[ok]
        f = sign * float((r * d).sum() / (d * d).sum())
        errs = [float(np.linalg.norm(r - sign * x * d, axis=1).mean()) for x in (0.0, f, shipped)]
        out[name] = {"fraction": f, "midpoint_mm": errs[0], "fitted_mm": errs[1], "shipped_mm": errs[2]}
    return out


def one_clip(clip: Path, work: Path, fps: float, max_frames: int | None, import_only: bool = False,
             keypoints: bool = True, subject_effect: bool = False, runs: int = 1) -> dict:
    seq_path = cached_sequence(clip, progress=False)
    spec = load_spec("balan31")
    truth_subject = subject_from_clip(spec, load_clip(clip))
    height = stature(truth_subject)
    rec, imported = work / f"{clip.stem}-recording", work / f"{clip.stem}-imported{'' if keypoints else '-bare'}"
    for p in (rec, imported):
        shutil.rmtree(p, ignore_errors=True)
    with open_sequence(seq_path) as seq:
        export_recording(seq, rec, calibration_format="toml", video=False)
        bg = rec / "backgrounds"
        bg.mkdir()
        for c, cam in enumerate(seq.cameras):
            cv2.imwrite(str(bg / f"{cam.name}.png"), seq.backgrounds()[c])
        frames = seq.subsample(fps)[:max_frames]
        truth_all = np.asarray(seq.gt_joints)
        truth = truth_all[frames]
        names = [c.name for c in seq.cameras]
        rate = seq.frame_rate
    run([*CLI, "import", *[str(rec / n) for n in names], "-c", str(rec / "calibration.toml"), "-o", str(imported),
         *([] if keypoints else ["--no-detect"]), "--silhouettes", "background", *sum((["--background", str(rec / "backgrounds" / f"{n}.png")] for n in names),
                                            []), "--fps", f"{rate:g}", "--no-page", "--json"])
    trunk = trunk_fit(imported, truth_all) if keypoints else None
    if import_only:
        return {"clip": clip.stem, "height_mm": height, "trunk": trunk}
    extra = ([] if max_frames is None else ["--max-frames", str(max_frames)]) + ["--runs", str(runs)]
    no_truth = work / f"{clip.stem}-{'refined-keypoints' if keypoints else 'refined-silhouettes'}"
    plain = work / f"{clip.stem}-refined-ik"
    for p in (no_truth, plain):
        shutil.rmtree(p, ignore_errors=True)
    run([*CLI, "track", str(imported), "--algo", "refined-keypoints" if keypoints else "refined", "--height",
         f"{height:.0f}", "--fps", f"{fps:g}", "--out", str(no_truth), "--json", *extra])
    run([*CLI, "track", str(seq_path), "--algo", "refined", "--fps", f"{fps:g}", "--out", str(plain), "--json",
         *extra])
    kp_subject = Subject.load(no_truth / "subject.json")  # from the stature alone without keypoints
    true_len, kp_len = limb_lengths(truth_subject), limb_lengths(kp_subject)
    h_len = limb_lengths(subject_from_height(spec, height))
    by_subject = {}
    if subject_effect:  # the same tracker from the IK fit of the truth, with the subject measured without it
        for name, how in (("stature", ["--height", f"{height:.0f}"]),
                          ("keypoints", ["--subject", str(no_truth / "subject.json")])):
            out = work / f"{clip.stem}-refined-ik-subject-{name}"
            shutil.rmtree(out, ignore_errors=True)
            run([*CLI, "track", str(seq_path), "--algo", "refined", "--fps", f"{fps:g}", "--out", str(out), "--json",
                 *how, *extra])
            by_subject[name] = scored(out, truth)
    return {"clip": clip.stem, "height_mm": height, "frames": int(len(truth)), "trunk": trunk,
            "without_truth": scored(no_truth, truth), "refined_from_ik": scored(plain, truth),
            "refined_from_ik_by_subject": by_subject,
            "limbs_mm": {k: {"skeleton": true_len[k], "stature": h_len[k], "keypoints": kp_len[k]} for k in true_len}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="*", default=["cmu_16_16_walk", "cmu_16_18_turn"])
    ap.add_argument("--fps", type=float, default=20.0)
    ap.add_argument("--max-frames", type=int, default=None)
    ap.add_argument("--runs", type=int, default=1, help="runs of each track (seed 0); errors are means over them")
    ap.add_argument("--work", type=Path, default=Path("results/without-truth"))
    ap.add_argument("--import-only", action="store_true", help="import and fit the trunk joints, no tracking")
    ap.add_argument("--no-keypoints", action="store_true",
                    help="no detector: start from the silhouettes and track with refined --height H")
    ap.add_argument("--subject-effect", action="store_true",
                    help="also track from the IK fit with the subject from the stature, then from the keypoints")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    rows = [one_clip(MOCAP / f"{c}.bvh", args.work, args.fps, args.max_frames, args.import_only,
                     not args.no_keypoints, args.subject_effect, args.runs) for c in args.clips]
    if args.json:
        print(json.dumps({"clips": rows}))
        return
    print("| clip | pelvis fraction | pelvis mm: midpoint / fitted / shipped | thorax fraction | "
          "thorax mm: midpoint / fitted / shipped |")
    print("|---|---:|---|---:|---|")
    for r in filter(lambda r: r["trunk"], rows):
        p, t = r["trunk"]["pelvis"], r["trunk"]["thorax"]
        print(f"| {r['clip']} | {p['fraction']:.2f} | {p['midpoint_mm']:.0f} / {p['fitted_mm']:.0f} / {p['shipped_mm']:.0f} "
              f"| {t['fraction']:.2f} | {t['midpoint_mm']:.0f} / {t['fitted_mm']:.0f} / {t['shipped_mm']:.0f} |")
    if args.import_only:
        return
    print()
    def spread(r: dict) -> str:
        d = r["runs_d_mean_mm"]
        return f"{r['d_mean_mm']:.1f}" + (f" ({min(d):.1f}-{max(d):.1f})" if len(d) > 1 else "")

    print("| clip | stature mm | frame 0 mm | D_mean first 20 | D_mean (runs) | D_max | refined from the IK fit: "
          "D_mean (runs) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        w, p = r["without_truth"], r["refined_from_ik"]
        print(f"| {r['clip']} | {r['height_mm']:.0f} | {w['frame0_mm']:.1f} | {w['d_mean_first20_mm']:.1f} | "
              f"{spread(w)} | {w['d_max_mm']:.1f} | {spread(p)} |")
    if args.subject_effect:
        print("\n| clip | `refined` from the IK fit, subject from: skeleton | stature | keypoints |")
        print("|---|---:|---:|---:|")
        for r in rows:
            b = r["refined_from_ik_by_subject"]
            print(f"| {r['clip']} | {spread(r['refined_from_ik'])} | {spread(b['stature'])} | "
                  f"{spread(b['keypoints'])} |")
    print("\n| clip | limb | skeleton mm | from stature | from keypoints |")
    print("|---|---|---:|---:|---:|")
    for r in rows:
        for k, v in r["limbs_mm"].items():
            s, h, kp = v["skeleton"], v["stature"], v["keypoints"]
            print(f"| {r['clip']} | {k} | {s:.0f} | {h:.0f} ({100 * (h - s) / s:+.0f} %) | "
                  f"{kp:.0f} ({100 * (kp - s) / s:+.0f} %) |")


if __name__ == "__main__":
    main()
