"""The Markdown summary of a results folder: configuration, error tables, figures, versions."""

from __future__ import annotations

import os
import re
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.joints import JOINTS15
from swarmpose.metrics import MMTA_DELTA_MM, spread_over_runs, track_errors
from swarmpose.report._style import count
from swarmpose.report.results import Results, as_results, largest_run_maximum

__all__ = ["write_summary", "run_rows"]


def _f(x: Any, fmt: str = ".1f") -> str:
    """A number for a table cell; a dash when missing or not finite."""
    if x is None:
        return "–"
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    return format(v, fmt) if np.isfinite(v) else "–"


def _pct(x: Any) -> str:
    return "–" if x is None else _f(100.0 * float(x))


def run_rows(res: Results) -> list[dict[str, Any]]:
    """Per-run errors: ``run, d_mean_mm, d_max_mm, mmta, mmtp_mm, frames_per_s``.

    Taken from the run's ``summary.json`` (then the folder's ``summary.json``) where stored, and
    recomputed from the run's joints (:func:`swarmpose.metrics.track_errors`) where not.
    """
    stored = {int(r["run"]): r for r in res.summary.get("per_run", []) if "run" in r}
    rows = []
    for r in res.runs:
        s, agg = r.summary, stored.get(r.run, {})
        e = None

        def get(run_key: str, agg_key: str, attr: str, s=s, agg=agg, r=r) -> float:
            nonlocal e
            if run_key in s and s[run_key] is not None:
                return float(s[run_key])
            if agg_key in agg and agg[agg_key] is not None:
                return float(agg[agg_key])
            if e is None:
                e = track_errors(r.joints, r.gt_joints)
            return float(getattr(e, attr))

        fps = s.get("frames_per_s", agg.get("frames_per_s"))
        rows.append({
            "run": r.run,
            "d_mean_mm": get("d_mean", "d_mean_mm", "d_mean"),
            "d_max_mm": get("d_max", "d_max_mm", "d_max"),
            "mmta": get("mmta", "mmta", "mmta"),
            "mmtp_mm": get("mmtp", "mmtp_mm", "mmtp"),
            "frames_per_s": float(fps) if fps is not None else r.frames_per_s,
        })
    return rows


def _rel(path: Path, base: Path) -> str:
    return Path(os.path.relpath(path, base)).as_posix()


def _table(header: Sequence[str], rows: Sequence[Sequence[str]], align: str | None = None) -> list[str]:
    align = align or ("l" + "r" * (len(header) - 1))
    sep = ["---:" if a == "r" else ":---" for a in align]
    out = ["| " + " | ".join(header) + " |", "| " + " | ".join(sep) + " |"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out


#: ``config.json`` keys that are ``swarmpose track`` options; fps, runs and seed are always written.
_TRACK_OPTIONS = (("fps", "--fps"), ("runs", "--runs"), ("seed", "--seed"), ("model", "--model"),
                  ("fitness", "--fitness"), ("optim_variant", "--variant"), ("fitness_options", "--fitness-options"),
                  ("feature_options", "--features"), ("motion", "--motion"), ("downsample", "--downsample"),
                  ("backend", "--backend"), ("max_frames", "--max-frames"), ("views", "--views"),
                  ("smooth", "--smooth"))
_ALWAYS = ("fps", "runs", "seed")


def _reproduce(cfg: dict[str, Any]) -> str | None:
    """The ``swarmpose track`` command line that repeats the run, every non-default setting included."""
    from dataclasses import asdict

    from swarmpose.track.tracker import TrackConfig

    if not cfg.get("sequence") or not cfg.get("algo"):
        return None
    defaults = asdict(TrackConfig())
    fused = cfg.get("consensus") or {}
    per_track = int(fused.get("runs_per_track") or 0)
    parts = ["swarmpose track", shlex.quote(str(cfg["sequence"])), f"--algo {shlex.quote(str(cfg['algo']))}"]
    for key, opt in _TRACK_OPTIONS:
        v = cfg.get(key)
        if key == "runs" and per_track and v is not None:  # a consensus folder: its tracks fuse K runs each
            v = int(v) * per_track
        if v is None or (key not in _ALWAYS and v == defaults[key]):
            continue
        parts.append(f"{opt} {v:g}" if isinstance(v, float) else f"{opt} {shlex.quote(str(v))}")
    if cfg.get("backward"):
        parts.append("--backward")
        path = cfg.get("backward_path", 0.0)  # a folder without it chose the passes' poses frame by frame
        if path is not None and path != defaults["backward_path"]:
            parts.append(f"--backward-path {path:g}")
    if per_track:
        parts.append(f"--consensus {per_track}")
    return " ".join(parts)


def write_summary(
    results: str | os.PathLike[str] | Results,
    *,
    out: str | os.PathLike[str] | None = None,
    figures: Sequence[str | os.PathLike[str]] | None = None,
    overlays: Sequence[str | os.PathLike[str]] | None = None,
    video: str | os.PathLike[str] | None = None,
    notes: Sequence[str] = (),
    sections: Sequence[str] = (),
) -> Path:
    """Write ``summary.md``: configuration, error table, per-joint table, figures and versions.

    The error table has one row per run (D_mean, D_max, MMTA, MMTP, frames/s), the mean over runs
    (the numbers of ``summary.json``), the worst run (highest D_mean) and the IK floor (the error of
    the model's best fit to the ground truth). Figures are embedded by paths relative to the
    summary, so the report folder can be moved or published as a whole.

    Parameters
    ----------
    results : path-like or Results
    out : path-like, optional
        Default ``RESULTS_DIR/report/summary.md``.
    figures, overlays : sequence of path-like, optional
        Images to embed; default: the plots and overlay PNGs already in the report folder.
    video : path-like, optional
        An overlay video to link.
    notes : sequence of str
        Extra remarks (e.g. why overlays were skipped), listed under the title.
    sections : sequence of str
        Further Markdown lines placed after the per-joint table (the per-limb confidence).

    Returns
    -------
    pathlib.Path
        The Markdown file written.
    """
    res = as_results(results)
    out_path = Path(out) if out is not None else res.path / "report" / "summary.md"
    base = out_path.parent
    base.mkdir(parents=True, exist_ok=True)
    if figures is None:
        figures = [p for p in (base / "error_over_time.png", base / "per_joint_errors.png") if p.is_file()]
    if overlays is None:
        overlays = sorted((base / "overlays").glob("overlay_*.png"))
    cfg, s = res.config, res.summary
    rows = run_rows(res)
    T = len(res.frame_indices)
    algo = str(cfg.get("algo") or s.get("algo") or "?")
    fps = res.fps
    evals = cfg.get("evals_per_frame") or s.get("evals_per_frame")

    scored = int(res.runs[0].valid.sum()) if res.runs else T
    L: list[str] = [f"# Tracking report: {res.name}", ""]
    head = f"**{algo.upper()}**"
    if fps:
        head += f" at {fps:g} fps"
    if evals:
        head += f", {evals} fitness evaluations per frame"
    head += f", {count(len(res.runs), 'run')} over {T} frames"
    if cfg.get("sequence"):
        head += f" of `{cfg['sequence']}`"
    L += [head + ".", ""]
    stale = [str(s["recomputed_because"])] if s.get("recomputed_because") else []
    remarks = list(notes) + stale + [f"run not included: {x}" for x in res.skipped]
    for n in remarks:
        L.append(f"> Note: {n}")
    if remarks:
        L.append("")

    # ---------------------------------------------------------------- configuration
    fi = res.frame_indices
    cfg_rows = [
        ("algorithm", algo),
        ("tracking frame rate", f"{fps:g} fps" if fps else "–"),
        ("fitness evaluations per frame", str(evals) if evals else "–"),
        ("fitness", str(cfg.get("fitness_kind") or cfg.get("fitness") or s.get("fitness") or "–")),
        ("body model", f"{cfg.get('model', '–')}" + (f" (variant {cfg['variant']})" if cfg.get("variant") else "")),
        ("fitness options", f"`{cfg['fitness_options']}`" if cfg.get("fitness_options") else "stage defaults"),
        ("image features", f"`{cfg['feature_options']}`" if cfg.get("feature_options") else "defaults"),
        ("optimiser variant", f"`{cfg['optim_variant']}`" if cfg.get("optim_variant") else "none"),
        ("motion model", str(cfg.get("motion", "zero-velocity"))),
        ("fitness backend", str(cfg.get("backend", "–"))),
        ("image downsampling", str(cfg.get("downsample", "–"))),
        ("seed", f"{cfg['seed']} (run k draws from SeedSequence([{cfg['seed']}, k]))" if "seed" in cfg else "–"),
        ("runs", f"{len(res.runs)}" + (f" of {cfg['runs']}" if cfg.get("runs") not in (None, len(res.runs)) else "")),
        ("frames", (f"{T} (sequence frames {int(fi[0])}–{int(fi[-1])})" if T else "0")
         + (f", the first {cfg['max_frames']} at this rate (--max-frames)"
            if cfg.get("max_frames") and cfg["max_frames"] <= T else "")
         + (f"; {scored} scored (the others lack valid ground truth)" if scored < T else "")),
        ("sequence", f"`{cfg['sequence']}`" if cfg.get("sequence") else "–"),
        ("created", str(cfg.get("created", "–"))),
    ]
    L += ["## Configuration", ""] + _table(["setting", "value"], cfg_rows, "ll") + [""]
    cmd = _reproduce(cfg)
    if cmd:
        L += ["Reproduce with:", "", "```", cmd, "```", ""]

    # ---------------------------------------------------------------- errors
    L += ["## Errors", "",
          "D is the 3D error of a frame: the mean distance (mm) of the 15 HumanEva joints to the ground "
          "truth; D_mean and D_max are its mean and maximum over the frames. MMTA is the share of joints "
          f"within {MMTA_DELTA_MM:g} mm of the ground truth and MMTP their mean distance (Sharifi et al.). "
          "The IK floor is the error of the model's best fit to the ground truth: no tracker using this "
          "model can do better (thesis sec. 6.4). Frames without valid ground truth are not scored. With "
          "several runs, D_max is the mean of the runs' maxima.", ""]
    trows = [[str(r["run"]), _f(r["d_mean_mm"]), _f(r["d_max_mm"]), _pct(r["mmta"]), _f(r["mmtp_mm"]),
              _f(r["frames_per_s"], ".2f")] for r in rows]
    trows.append(["**mean**", _f(s.get("d_mean_mm")), _f(s.get("d_max_mm")), _pct(s.get("mmta")),
                  _f(s.get("mmtp_mm")), _f(s.get("frames_per_s"), ".2f")])
    if len(rows) > 1:
        w = s.get("worst") or {}
        wr = next((r for r in rows if r["run"] == w.get("run")), max(rows, key=lambda r: r["d_mean_mm"]))
        trows.append([f"**worst** (run {wr['run']})", _f(w.get("d_mean_mm", wr["d_mean_mm"])),
                      _f(w.get("d_max_mm", wr["d_max_mm"])), _pct(w.get("mmta", wr["mmta"])),
                      _f(wr["mmtp_mm"]), _f(wr["frames_per_s"], ".2f")])
        spread = s.get("d_mean_std_over_runs_mm", s.get("d_mean_std_over_runs"))  # the key before the unit was added
        if spread is None:
            spread = spread_over_runs([r["d_mean_mm"] for r in rows])
    ik = res.ik_frame_error_mm
    ik_mean = s.get("ik_floor_mm", cfg.get("ik_floor_mm"))
    if ik_mean is None and ik is not None:
        ik_mean = float(np.nanmean(ik))
    if ik_mean is not None or ik is not None:
        ik_joint = res.ik_joint_error_mm
        ik_joint = None if ik_joint is None else ik_joint[np.isfinite(ik_joint).all(axis=1)]  # scored frames
        mmta_ik = None if ik_joint is None else float((ik_joint < MMTA_DELTA_MM).mean())
        trows.append(["IK floor", _f(ik_mean), _f(None if ik is None else float(np.nanmax(ik))), _pct(mmta_ik),
                      "–", "–"])
    L += _table(["run", "D_mean (mm)", "D_max (mm)", "MMTA (%)", "MMTP (mm)", "frames/s"], trows) + [""]
    if len(rows) > 1:
        largest = largest_run_maximum(s)
        if largest is None:
            largest = max(r["d_max_mm"] for r in rows)
        L += [f"Spread of D_mean over the runs (sample standard deviation): {_f(spread)} mm. The largest D of "
              f"any run: {_f(largest)} mm.", ""]
    for f in figures:
        if Path(f).name.startswith("error_over_time"):
            L += [f"![3D error over time: each run, their mean and the IK floor]({_rel(Path(f), base)})", ""]

    # ---------------------------------------------------------------- per joint
    per_run = res.per_joint_by_run()
    pj = s.get("per_joint_mm") or {}
    ik_pj = None if res.ik_joint_error_mm is None else np.nanmean(res.ik_joint_error_mm, axis=0)
    jrows = []
    for j, name in enumerate(JOINTS15):
        mean = pj.get(name, float(per_run[:, j].mean()))
        jrows.append([name, _f(mean), _f(per_run[:, j].min()), _f(per_run[:, j].max()),
                      _f(None if ik_pj is None else ik_pj[j])])
    L += ["## Error per joint", "", "Mean distance over the frames (mm): mean over the runs, the smallest and the "
          "largest of the runs' means (each joint's own; not necessarily the best and worst run above), and the IK "
          "floor of the joint.", ""]
    L += _table(["joint", "mean (mm)", "min over runs (mm)", "max over runs (mm)", "IK floor (mm)"], jrows) + [""]
    for f in figures:
        if not Path(f).name.startswith("error_over_time"):
            L += [f"![{Path(f).stem.replace('_', ' ')}]({_rel(Path(f), base)})", ""]
    L += list(sections)

    # ---------------------------------------------------------------- overlays
    if overlays or video:
        L += ["## Overlays", "",
              "The tracked cones on the camera views (left limbs blue, right limbs orange, torso and head "
              "green) and the ground-truth skeleton (yellow).", ""]
        for p in overlays:
            L += [_overlay_caption(res, Path(p)), "", f"![{Path(p).stem}]({_rel(Path(p), base)})", ""]
        if video:
            L += [f"Video of every frame: [{Path(video).name}]({_rel(Path(video), base)})", ""]

    # ---------------------------------------------------------------- versions
    versions = cfg.get("versions") or {}
    if versions:
        L += ["## Versions", ""] + _table(["component", "version"],
                                          [[str(k), f"`{v}`"] for k, v in versions.items()], "ll") + [""]
    out_path.write_text("\n".join(L).rstrip() + "\n", encoding="utf-8")
    return out_path


def _overlay_caption(res: Results, path: Path) -> str:
    """``Run 0, sequence frame 234 (t = 3.90 s): D = 158.4 mm, the run's worst frame.`` for an overlay PNG
    named as :func:`swarmpose.report.overlay.overlays` names them; the file's name for any other."""
    m = re.fullmatch(r"overlay_run(\d+)_frame(\d+)", path.stem)
    if m is None:
        return f"*{path.stem}*"
    run, k = int(m.group(1)), int(m.group(2))
    r = next((x for x in res.runs if x.run == run), None)
    hit = np.zeros(0, dtype=np.int64) if r is None else np.flatnonzero(r.frame_indices == k)
    if r is None or hit.size == 0:
        return f"*Run {run}, sequence frame {k}.*"
    i = int(hit[0])
    d = r.d_per_frame[i]
    t = f" (t = {float(r.frame_times[i]):.2f} s)"
    if not np.isfinite(d):
        return f"*Run {run}, sequence frame {k}{t}: no valid ground truth.*"
    worst = ", the run's worst frame" if i == int(np.nanargmax(r.d_per_frame)) else ""
    return f"*Run {run}, sequence frame {k}{t}: D = {float(d):.1f} mm{worst}.*"
