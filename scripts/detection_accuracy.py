"""How well MediaPipe Pose sees the synthetic sequences: its mask and its 15 joints against the rendering's truth.

For each shared clip (../shared/data/mocap/*.bvh) the synthetic sequence that `swarmpose track CLIP` uses
(default synthesis settings, seed 0, cached under cache/sequences) is opened, and MediaPipe Pose (video mode,
model_complexity=1, one detector per view fed that view's frames in order) runs on every evaluated frame of
every view: by default the frames the tracker uses at 20 fps (`seq.subsample(20)`), with `--fps 60` all of
them. Per view it measures

* the learned silhouette's IoU against the exact rendered mask (`masks(k)`), and background subtraction's
  (`swarmpose.features.silhouette` with the tracker's default options) against the same mask: 5th, 50th
  and 95th percentiles over the frames (a frame where nobody is found counts with its empty mask, IoU 0);
* the 2D error (px) of the 15 joints of `swarmpose.detection.joints.to_joints15` against the projected
  ground truth `cam.project(gt_joints[k])`, as labelled and after matching left and right per view and
  frame (the better, by mean error, of the labelling and its SWAP15 swap), the share of view-frames where
  the swap was better, and per joint the median error and the median signed offset along the image's torso
  axis (positive: the detection lies towards the head from the truth);
* the share of frames with a person found, and the detector's time per frame (ms; each detector's first
  call, which builds MediaPipe's graph, is left out).

The person's size sets the scale of the pixel errors: each view's median height of the exact mask's
bounding box (px) is reported too. The ground truth's own thorax, pelvis and head top are not the
detector's definitions (shoulder midpoint, hip midpoint, a point extrapolated above the ears): the script
also reports, from the ground truth alone, how far the truth's thorax and pelvis lie from the midpoints of
the truth's own shoulders and hips (mm in 3D, px projected), the floor of those joints' errors.

Run:  .venv/bin/python scripts/detection_accuracy.py [--clips walk,jog] [--fps 20] [--json out.json]
      (from the repository root, so that the sequences are cached where `swarmpose track` caches them)

Prints one Markdown table per clip and view plus pooled summaries; `--json PATH` also writes everything
as one JSON object (`-`: to stdout, instead of the tables).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "data" / "mocap"


def _stats(values, percentiles=(5, 50, 95)) -> dict:
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"n": 0, **{f"p{p:02d}": None for p in percentiles}, "mean": None}
    q = np.percentile(v, percentiles)
    return {"n": int(v.size), **{f"p{p:02d}": float(x) for p, x in zip(percentiles, q, strict=True)},
            "mean": float(v.mean())}


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a.astype(bool), b.astype(bool)
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else float("nan")


def _clips(selection: str) -> list[Path]:
    every = sorted(MOCAP.glob("*.bvh"))
    if not every:
        sys.exit(f"no clips in {MOCAP}")
    if not selection:
        return every
    picked = []
    for word in (w.strip() for w in selection.split(",") if w.strip()):
        hits = [c for c in every if word == c.stem or word in c.stem]
        if not hits:
            sys.exit(f"--clips: no clip matches {word!r} (clips: {', '.join(c.stem for c in every)})")
        picked += [c for c in hits if c not in picked]
    return picked


def _torso_axis(gt2d: np.ndarray) -> np.ndarray:
    """Unit image vector from the truth's pelvis to its thorax (JOINTS15 0 = thorax, 1 = pelvis)."""
    d = gt2d[0] - gt2d[1]
    n = np.linalg.norm(d)
    return d / n if n > 0 else np.array([0.0, -1.0])


def definition_gap(seq) -> dict:
    """How far the truth's thorax and pelvis lie from its own shoulder and hip midpoints (3D mm, 2D px)."""
    from swarmpose.joints import JOINT_INDEX as J

    g = np.asarray(seq.gt_joints, dtype=np.float64)
    out = {}
    for joint, (a, b) in {"thorax": ("l_shoulder", "r_shoulder"), "pelvis": ("l_hip", "r_hip")}.items():
        mid = 0.5 * (g[:, J[a]] + g[:, J[b]])
        d3 = np.linalg.norm(g[:, J[joint]] - mid, axis=1)
        d2, towards_head = [], []
        for c in seq.cameras:
            truth, midpoint = c.project(g[:, J[joint]]), c.project(mid)
            axis = c.project(g[:, J["thorax"]]) - c.project(g[:, J["pelvis"]])
            axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-9)
            d2.append(np.linalg.norm(truth - midpoint, axis=1))
            towards_head.append(np.einsum("ij,ij->i", midpoint - truth, axis))
        out[joint] = {"mm_3d": _stats(d3, (50,)), "px_2d": _stats(np.concatenate(d2), (50, 95)),
                      "midpoint_towards_head_px": _stats(np.concatenate(towards_head), (50,))}
    return out


def measure_clip(clip: Path, fps: float, seed: int, progress: bool) -> dict:
    from swarmpose.detection.joints import SWAP15, to_joints15
    from swarmpose.detection.mediapipe_pose import MediaPipePose
    from swarmpose.features import parse_feature_options, silhouette
    from swarmpose.io.sequence import open_sequence
    from swarmpose.synth.synthesize import cached_sequence

    # what `swarmpose track CLIP` resolves the clip to (swarmpose.track.runner.resolve_sequence), with the seed
    path = cached_sequence(clip, seed=seed, progress=progress)
    sil_opts, _ = parse_feature_options("")  # the tracker's default feature options
    seq = open_sequence(path)
    try:
        frames = np.asarray(seq.subsample(fps), dtype=np.int64)
        backgrounds = seq.backgrounds()
        n_views, nf = seq.n_views, len(frames)
        iou_mp = np.full((n_views, nf), np.nan)
        iou_bg = np.full((n_views, nf), np.nan)
        err_lab = np.full((n_views, nf, 15), np.nan)
        err_sw = np.full((n_views, nf, 15), np.nan)
        along = np.full((n_views, nf, 15), np.nan)  # signed offset along the torso axis (matched labels)
        swapped = np.zeros((n_views, nf), bool)
        found = np.zeros((n_views, nf), bool)
        height = np.full((n_views, nf), np.nan)
        ms = np.full((n_views, nf), np.nan)
        detectors = [MediaPipePose(model_complexity=1, static_image_mode=False) for _ in range(n_views)]
        t_start = time.perf_counter()
        try:
            for i, k in enumerate(frames):
                images, masks = seq.images(int(k)), seq.masks(int(k))
                gt = np.asarray(seq.gt_joints[int(k)], dtype=np.float64)
                for v, det in enumerate(detectors):
                    t0 = time.perf_counter()
                    d = det.detect(images[v])
                    if i > 0:  # the first call builds MediaPipe's graph
                        ms[v, i] = 1e3 * (time.perf_counter() - t0)
                    truth = masks[v]
                    rows = np.flatnonzero(truth.any(axis=1))
                    if rows.size:
                        height[v, i] = rows[-1] - rows[0] + 1
                    iou_mp[v, i] = _iou(d.mask, truth)
                    iou_bg[v, i] = _iou(silhouette(images[v], backgrounds[v], **sil_opts), truth)
                    found[v, i] = d.found
                    if not d.found:
                        continue
                    joints, _ = to_joints15(d.keypoints, d.confidence)
                    gt2d = seq.cameras[v].project(gt)
                    e = np.linalg.norm(joints - gt2d, axis=1)
                    es = np.linalg.norm(joints[SWAP15] - gt2d, axis=1)
                    err_lab[v, i] = e
                    swapped[v, i] = np.nanmean(es) < np.nanmean(e)
                    best = joints[SWAP15] if swapped[v, i] else joints
                    err_sw[v, i] = es if swapped[v, i] else e
                    along[v, i] = (best - gt2d) @ _torso_axis(gt2d)
                if progress and (i + 1) % 20 == 0:
                    rate = (i + 1) / (time.perf_counter() - t_start)
                    print(f"  {clip.stem}: {i + 1}/{nf} frames ({rate:.1f} frames/s, {n_views} views)",
                          file=sys.stderr, flush=True)
        finally:
            for det in detectors:
                det.close()
        from swarmpose.joints import JOINTS15

        views = {}
        for v, name in enumerate(seq.view_names):
            hit = found[v]
            views[name] = {
                "frames": nf,
                "found_rate": float(hit.mean()),
                "iou_learned": _stats(iou_mp[v]),
                "iou_learned_when_found": _stats(iou_mp[v][hit]),
                "iou_background_subtraction": _stats(iou_bg[v]),
                "keypoint_error_px_labelled": _stats(err_lab[v], (50, 95)),
                "keypoint_error_px_matched": _stats(err_sw[v], (50, 95)),
                "swap_share": float(swapped[v][hit].mean()) if hit.any() else None,
                "person_height_px": _stats(height[v], (50,)),
                "ms_per_frame": {"median": float(np.nanmedian(ms[v])), "mean": float(np.nanmean(ms[v]))},
                "per_joint_median_px_matched": {j: _stats(err_sw[v][:, n], (50,))["p50"]
                                                for n, j in enumerate(JOINTS15)},
            }
        return {"clip": clip.stem, "sequence": str(path), "frame_rate": float(seq.frame_rate), "fps": fps,
                "frames": [int(k) for k in frames], "views": views, "definition_gap": definition_gap(seq),
                "_raw": {"iou_mp": iou_mp, "iou_bg": iou_bg, "err_lab": err_lab, "err_sw": err_sw,
                         "along": along, "swapped": swapped, "found": found, "ms": ms, "height": height}}
    finally:
        seq.close()


def pooled(raws: list[dict]) -> dict:
    """The statistics over every clip's view-frames together (raws: the clips' ``_raw`` arrays)."""
    from swarmpose.joints import JOINTS15

    def cat(key):
        return np.concatenate([r[key].reshape(-1, *r[key].shape[2:]) for r in raws])

    found, swapped = cat("found"), cat("swapped")
    err_lab, err_sw, along = cat("err_lab"), cat("err_sw"), cat("along")
    return {
        "view_frames": int(found.size),
        "found_rate": float(found.mean()),
        "iou_learned": _stats(cat("iou_mp")),
        "iou_learned_when_found": _stats(cat("iou_mp")[found]),
        "iou_background_subtraction": _stats(cat("iou_bg")),
        "keypoint_error_px_labelled": _stats(err_lab, (50, 95)),
        "keypoint_error_px_matched": _stats(err_sw, (50, 95)),
        "swap_share": float(swapped[found].mean()) if found.any() else None,
        "person_height_px": _stats(cat("height"), (50,)),
        "ms_per_frame": {"median": float(np.nanmedian(cat("ms"))), "mean": float(np.nanmean(cat("ms")))},
        "per_joint": {j: {"median_px_labelled": _stats(err_lab[:, n], (50,))["p50"],
                          "median_px_matched": _stats(err_sw[:, n], (50,))["p50"],
                          "p95_px_matched": _stats(err_sw[:, n], (95,))["p95"],
                          "median_offset_towards_head_px": _stats(along[:, n], (50,))["p50"]}
                      for n, j in enumerate(JOINTS15)},
    }


def _f(x, digits=1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


HEADER = ("| {first} | IoU learned p05 / p50 / p95 | IoU bg-sub p05 / p50 / p95 | kp px labelled p50 / p95 | "
          "kp px matched p50 / p95 | swap | found | ms/frame |\n|---|---|---|---|---|---|---|---|")


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def _row(first: str, s: dict) -> str:
    a, b = s["iou_learned"], s["iou_background_subtraction"]
    lab, mat = s["keypoint_error_px_labelled"], s["keypoint_error_px_matched"]
    return (f"| {first} | {_f(a['p05'], 3)} / {_f(a['p50'], 3)} / {_f(a['p95'], 3)} | "
            f"{_f(b['p05'], 3)} / {_f(b['p50'], 3)} / {_f(b['p95'], 3)} | {_f(lab['p50'])} / {_f(lab['p95'])} | "
            f"{_f(mat['p50'])} / {_f(mat['p95'])} | {_pct(s['swap_share'])} | "
            f"{100 * s['found_rate']:.1f} % | {s['ms_per_frame']['median']:.1f} |")


def markdown(result: dict) -> str:
    lines = [f"MediaPipe Pose {result['mediapipe']} (model_complexity=1, video mode) on the synthetic sequences "
             f"at {result['fps']:g} fps; swarmpose git {result['git']}; {result['machine']}", ""]
    for c in result["clips"]:
        nf = len(c["frames"])
        h = ", ".join(f"{v} {_f(s['person_height_px']['p50'], 0)}" for v, s in c["views"].items())
        lines += [f"### {c['clip']} ({nf} frames x {len(c['views'])} views; person height px: {h})", "",
                  HEADER.format(first="view")]
        lines += [_row(v, s) for v, s in c["views"].items()]
        lines.append("")
    lines += ["### All clips, per view", "", HEADER.format(first="view")]
    lines += [_row(v, s) for v, s in result["per_view"].items()]
    lines += [_row("all", result["overall"]), ""]
    lines += ["### All clips, per joint (px)", "",
              "| joint | median labelled | median matched | p95 matched | median offset towards the head |",
              "|---|---|---|---|---|"]
    for j, s in result["overall"]["per_joint"].items():
        lines.append(f"| {j} | {_f(s['median_px_labelled'])} | {_f(s['median_px_matched'])} | "
                     f"{_f(s['p95_px_matched'])} | {_f(s['median_offset_towards_head_px'])} |")
    lines += ["", "### The truth's thorax and pelvis against its own shoulder and hip midpoints", "",
              "| clip | thorax mm (3D) p50 | thorax px p50 / p95 | midpoint towards the head px p50 | "
              "pelvis mm (3D) p50 | pelvis px p50 / p95 | midpoint towards the head px p50 |",
              "|---|---|---|---|---|---|---|"]
    for c in result["clips"]:
        t, p = c["definition_gap"]["thorax"], c["definition_gap"]["pelvis"]
        lines.append(f"| {c['clip']} | {_f(t['mm_3d']['p50'])} | {_f(t['px_2d']['p50'])} / {_f(t['px_2d']['p95'])} | "
                     f"{_f(t['midpoint_towards_head_px']['p50'])} | {_f(p['mm_3d']['p50'])} | "
                     f"{_f(p['px_2d']['p50'])} / {_f(p['px_2d']['p95'])} | {_f(p['midpoint_towards_head_px']['p50'])} |")
    start, end = result["loadavg"]
    lines += ["", f"wall time {result['seconds']:.0f} s; 1-minute load average {_f(start)} before the run, {_f(end)} "
              f"at its end (MediaPipe's own threads included) on {result['cpus']} CPUs"]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", default="", help="comma-separated clip names or parts of them (default: all 8)")
    ap.add_argument("--fps", type=float, default=20.0,
                    help="evaluate the frames the tracker uses at this rate (60: every frame)")
    ap.add_argument("--seed", type=int, default=0, help="synthesis seed (track's default: 0)")
    ap.add_argument("--json", default=None, metavar="PATH", help="also write the results as JSON (-: stdout)")
    args = ap.parse_args()

    from swarmpose.detection.mediapipe_pose import import_mediapipe_pose
    from swarmpose.errors import ConfigError
    from swarmpose.track.provenance import source_revision

    try:
        _, mp_version = import_mediapipe_pose()
    except ConfigError as exc:
        sys.exit(str(exc))
    quiet = args.json == "-"
    load_start = _load()
    t0 = time.perf_counter()
    clips = []
    for clip in _clips(args.clips):
        if not quiet:
            print(f"{clip.stem} ...", file=sys.stderr, flush=True)
        clips.append(measure_clip(clip, args.fps, args.seed, progress=not quiet))
    raws = [c.pop("_raw") for c in clips]
    view_names = list(clips[0]["views"])
    per_view = {}
    for v, name in enumerate(view_names):
        per_view[name] = pooled([{k: a[v:v + 1] for k, a in r.items()} for r in raws])
    result = {"mediapipe": mp_version, "model_complexity": 1, "static_image_mode": False, "fps": args.fps,
              "seed": args.seed, "git": source_revision(),
              "cpus": _cpus(), "machine": f"{platform.processor() or platform.machine()}, {_cpus()} CPUs, Python "
                         f"{platform.python_version()}",
              "command": " ".join([".venv/bin/python", "scripts/detection_accuracy.py", *sys.argv[1:]]),
              "seconds": time.perf_counter() - t0, "loadavg": [load_start, _load()], "clips": clips, "per_view": per_view,
              "overall": pooled(raws)}
    if args.json == "-":
        print(json.dumps(result))
        return
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1) + "\n")
    print(markdown(result))


def _load() -> float | None:
    import os

    return os.getloadavg()[0] if hasattr(os, "getloadavg") else None


def _cpus() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


if __name__ == "__main__":
    main()
