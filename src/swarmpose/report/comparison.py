"""The report of a ``swarmpose compare`` folder: the table, two figures and an HTML page.

``comparison_over_time.png`` draws, per clip and frame rate, the mean 3D error over the runs of every
entry against time, with the IK floor (as the thesis compares two trackers in Fig. 6.8-6.14);
``comparison_d_mean.png`` draws every run's D_mean of every entry as a dot, their mean as a bar, and
the IK floor, so the spread between runs is seen beside the gaps between entries.

The folder layout is ``SUITE_DIR/<sequence>/<entry>/`` (each a ``swarmpose track`` results folder)
with ``comparison.json`` (what :func:`swarmpose.experiments.run.run_suite` returns) at the top.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import DataError, FormatError
from swarmpose.io.files import read_json_object
from swarmpose.report._style import IK_RGB, count, rgb01
from swarmpose.report.plots import _figure
from swarmpose.report.results import largest_run_maximum

__all__ = ["comparison_table", "comparison_figures", "write_comparison", "load_comparison", "entry_folder"]

#: Entry colours (Okabe-Ito, without yellow, which is faint on white).
_ENTRY_RGB = ((0, 114, 178), (213, 94, 0), (0, 158, 115), (204, 121, 167), (86, 180, 233), (230, 159, 0),
              (0, 0, 0))
_ROW_KEYS = ("label", "fps", "sequence", "runs", "evals_per_frame", "d_mean_mm", "d_max_mm", "d_mean_std_over_runs_mm",
             "worst_d_mean_mm", "ik_floor_mm", "mmta", "frames_per_s", "out_dir")


def comparison_table(report: dict[str, Any]) -> str:
    """The Markdown table of a comparison: one row per clip and entry."""
    runs = f"{report['runs']} run{'' if report['runs'] == 1 else 's'}"
    part = ""
    if report.get("max_frames"):
        n, slowest = report["max_frames"], report["lowest_fps"]
        part = (f"; only the first {n} frames at {slowest:g} fps ({(n - 1) / slowest:.2f} s; the same stretch at "
                "the other rates), --max-frames: a quick try, not the papers' comparison")
    with_largest = any(r.get("d_max_over_runs_mm") is not None for r in report["rows"])
    seqs = list(dict.fromkeys(str(r["sequence"]) for r in report["rows"]))
    one_seq = len(seqs) == 1  # said once above the table instead of in every row
    head = ["entry", "eval/frame", "D_mean mm (± SD over runs)", "worst run D_mean mm",
            f"D_max mm: mean of the runs{' (largest)' if with_largest else ''}", "IK floor mm", "MMTA %", "frames/s"]
    head = head if one_seq else ["sequence", *head]
    lines = [f"# Suite `{report['suite']}` ({runs} per entry, seed {report['seed']}{part})", ""]
    lines += [f"Sequence: {seqs[0]}", ""] if one_seq else []
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * (1 if one_seq else 2) + "---:|" * 7]
    # one paper reference for the whole suite is said under the table; several are numbered per entry
    refs = list(dict.fromkeys(str(r["reference"]) for r in report["rows"] if r.get("reference")))
    for r in report["rows"]:
        largest = (f" ({r['d_max_over_runs_mm']:.1f})" if r.get("d_max_over_runs_mm") is not None
                   else " (–)" if with_largest else "")
        label = f"{r['label']} [{refs.index(r['reference']) + 1}]" if len(refs) > 1 and r.get("reference") else r["label"]
        # one run has no spread to measure: "± 0.0" would read as a measured zero
        spread = f"± {r['d_mean_std_over_runs_mm']:.1f}" if int(r["runs"]) > 1 else "(1 run)"
        cells = [label, str(r["evals_per_frame"]), f"{r['d_mean_mm']:.1f} {spread}", f"{r['worst_d_mean_mm']:.1f}",
                 f"{r['d_max_mm']:.1f}{largest}", f"{r['ik_floor_mm']:.1f}", f"{100 * r['mmta']:.1f}",
                 f"{r['frames_per_s']:.2f}"]
        lines.append("| " + " | ".join(cells if one_seq else [str(r["sequence"]), *cells]) + " |")
    if len(refs) == 1:
        lines += ["", f"Reference: {refs[0]}"]
    elif refs:
        lines += ["", "References:", ""] + [f"{i}. {ref}" for i, ref in enumerate(refs, 1)]
    return "\n".join(lines) + "\n"


def load_comparison(folder: str | os.PathLike[str]) -> dict[str, Any]:
    """Read ``FOLDER/comparison.json``; :class:`DataError` if there is none, :class:`FormatError` if it is not
    a comparison (the message names the file and the missing field)."""
    path = Path(folder) / "comparison.json"
    if not path.is_file():
        raise DataError(f"{path} not found: is {folder} a `swarmpose compare` folder?")
    report = read_json_object(path)
    for key in ("suite", "runs", "seed", "rows"):
        if key not in report:
            raise FormatError(f"no {key!r}: not a comparison written by `swarmpose compare`", path=path)
    if not isinstance(report["rows"], list):
        raise FormatError("'rows' must be a list of entries", path=path)
    for i, row in enumerate(report["rows"]):
        if isinstance(row, dict) and "d_mean_std_over_runs" in row:  # the key's name before the unit was added
            row.setdefault("d_mean_std_over_runs_mm", row.pop("d_mean_std_over_runs"))
        missing = [k for k in _ROW_KEYS if not isinstance(row, dict) or k not in row]
        if missing:
            raise FormatError(f"rows[{i}] has no {', '.join(repr(k) for k in missing)}", path=path)
        if row.get("d_max_over_runs_mm") is None:  # written before the key: the entry's own summary has it
            entry = entry_folder(folder, row) / "summary.json"
            try:
                row["d_max_over_runs_mm"] = largest_run_maximum(read_json_object(entry)) if entry.is_file() else None
            except FormatError:
                row["d_max_over_runs_mm"] = None
    report.setdefault("lowest_fps", min((float(r["fps"]) for r in report["rows"]), default=0.0))
    return report


def entry_folder(folder: str | os.PathLike[str], row: dict[str, Any]) -> Path:
    """The results folder of a comparison row, inside ``folder`` (``<sequence>/<entry>``, the last two parts
    of the recorded ``out_dir``, so the comparison folder can be moved or read from another directory)."""
    recorded = Path(str(row["out_dir"]))
    return Path(folder) / recorded.parent.name / recorded.name


def _entry_key(row: dict[str, Any]) -> str:
    """The entry's name without its frame rate: one colour for 'sppso 20fps' and 'sppso 60fps', and for
    'aapso 25fps reprojection' and 'aapso 12fps reprojection'."""
    key = " ".join(re.sub(r"\b\d+(\.\d+)?fps\b", " ", str(row["label"])).split())
    return key or str(row["label"])


def _finished_runs(folder: Path, report: dict[str, Any]) -> tuple[dict[int, Any], list[str]]:
    """Every row's loaded results folder (by ``id(row)``), and a note for each entry with fewer or more finished
    runs than the comparison recorded (its figures then show the runs there are)."""
    from swarmpose.report.results import load_results

    loaded, notes = {}, []
    for r in report["rows"]:
        res = load_results(entry_folder(folder, r))
        loaded[id(r)] = res
        want = int(r.get("runs") or report["runs"])
        if len(res.runs) < want:
            notes.append(f"{r['sequence']} / {r['label']}: {len(res.runs)} of {want} runs finished "
                         f"({', '.join(res.skipped) or 'the others are missing'}); the figures show those, the "
                         "table the comparison's numbers")
        elif len(res.runs) > want:  # a resume that adds runs rewrites comparison.json only at its end
            notes.append(f"{r['sequence']} / {r['label']}: {len(res.runs)} runs finished, the comparison's table "
                         f"has {want} (finish the resume to update it); the figures show all {len(res.runs)}")
    return loaded, notes


def comparison_figures(folder: str | os.PathLike[str], report: dict[str, Any] | None = None,
                       *, dpi: float = 110, notes: list[str] | None = None) -> list[Path]:
    """Draw ``comparison_over_time.png`` and ``comparison_d_mean.png`` into ``folder``.

    Parameters
    ----------
    folder : path-like
        The comparison folder (``comparison.json`` and ``<sequence>/<entry>/`` results folders).
    report : dict, optional
        Its ``comparison.json``; read from ``folder`` when not given.
    dpi : float, default 110
    notes : list, optional
        Receives a line for each entry with fewer or more finished runs than the comparison recorded.

    Returns
    -------
    list of pathlib.Path
        The two PNGs.

    Raises
    ------
    DataError
        An entry's results folder is missing or holds no finished run (the message names it).
    """
    folder = Path(folder)
    report = load_comparison(folder) if report is None else report
    rows = report["rows"]
    if not rows:
        raise DataError(f"{folder}: the comparison has no entries")
    keys = list(dict.fromkeys(_entry_key(r) for r in rows))
    colour = {k: rgb01(_ENTRY_RGB[i % len(_ENTRY_RGB)]) for i, k in enumerate(keys)}
    loaded, missing = _finished_runs(folder, report)
    if notes is not None:
        notes.extend(missing)
    per_run = {key: _per_run_d_mean(res) for key, res in loaded.items()}  # each finished run's D_mean
    seqs = list(dict.fromkeys(str(r["sequence"]) for r in rows))
    rates = sorted({float(r["fps"]) for r in rows})
    suite, quick = report["suite"], " (quick try: --max-frames)" if report.get("max_frames") else ""

    # -------------------------------------------------------------- error over time, one panel per clip x rate
    most = max(sum(1 for r in rows if str(r["sequence"]) == s and float(r["fps"]) == f) for s in seqs for f in rates)
    legend_rows = -(-(most + 1) // 2)  # the entries and the IK floor, two columns under each panel
    fig = _figure((6.2 * len(rates), (3.1 + 0.17 * legend_rows) * len(seqs) + 0.5), dpi)
    axes = fig.subplots(len(seqs), len(rates), squeeze=False, sharey="row")  # one error scale per clip
    for i, seq in enumerate(seqs):
        top = 1.0
        for j, fps in enumerate(rates):
            ax = axes[i][j]
            mine = [r for r in rows if str(r["sequence"]) == seq and float(r["fps"]) == fps]
            for r in mine:
                res = loaded[id(r)]
                D = np.stack([run.d_per_frame for run in res.runs])
                mean = np.nanmean(D, axis=0) if np.isfinite(D).any(axis=0).all() else D.mean(axis=0)
                top = max(top, float(np.nanmax(mean)) if np.isfinite(mean).any() else 0.0)
                n_runs = "" if len(res.runs) == report["runs"] else f", {count(len(res.runs), 'run')}"
                ax.plot(res.frame_times, mean, lw=1.8, color=colour[_entry_key(r)],
                        marker="." if len(mean) < 30 else None,
                        label=f"{r['label']}: {per_run[id(r)].mean():.1f} mm{n_runs}")
            with_ik = next((loaded[id(r)] for r in mine if loaded[id(r)].ik_frame_error_mm is not None), None)
            if with_ik is not None:
                ik = with_ik.ik_frame_error_mm
                ax.plot(with_ik.frame_times, ik, lw=1.2, ls="--", color=rgb01(IK_RGB), marker="." if len(ik) < 30 else None,
                        label=f"IK floor, {float(np.nanmean(ik)):.1f} mm")
            if not mine:
                ax.text(0.5, 0.5, "no entry at this rate", ha="center", va="center", transform=ax.transAxes,
                        color="0.5")
            ax.set_title(f"{seq}, {fps:g} fps", fontsize=10)
            ax.set_xlabel("time (s)")
            if j == 0:
                ax.set_ylabel("3D error D (mm), mean of the runs")
            ax.grid(True, color="0.88", lw=0.6)
            ax.set_axisbelow(True)
            if mine:  # under the panel, not on it: with many entries an inner legend hides their curves
                ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize=7.5, frameon=False, ncol=2)
        axes[i][0].set_ylim(0.0, top * 1.15)  # shared along the row: the rates are compared on one scale
    counts = {len(res.runs) for res in loaded.values()}
    runs_said = (f"mean of {count(report['runs'], 'run')} per entry" if counts == {report["runs"]}
                 else "mean of each entry's finished runs (the legend gives the counts that differ "
                      f"from {report['runs']})")
    fig.suptitle(f"{suite}: 3D error over time, {runs_said}{quick}", fontsize=11)
    fig.tight_layout()
    over_time = folder / "comparison_over_time.png"
    fig.savefig(over_time, dpi=dpi, format="png")

    # -------------------------------------------------------------- every run's D_mean per entry
    labels = [str(r["label"]) if len(seqs) == 1 else f"{r['sequence']}: {r['label']}" for r in rows]
    width = max(8.0, 5.0 + 0.075 * max(len(t) for t in labels))  # long clip names get room, the plot keeps its own
    fig = _figure((width, 0.42 * len(rows) + 1.6), dpi)
    ax = fig.add_subplot(1, 1, 1)
    y = np.arange(len(rows))[::-1].astype(np.float64)
    rng = np.random.default_rng(0)  # a fixed jitter: the figure is the same on every run
    for yi, r in zip(y, rows, strict=True):
        c = colour[_entry_key(r)]
        runs_d = per_run[id(r)]
        ax.barh(yi, float(runs_d.mean()), height=0.62, color=c, alpha=0.35, edgecolor=c, lw=0.8, zorder=2)
        ax.scatter(runs_d, yi + rng.uniform(-0.18, 0.18, runs_d.size), s=14, color=c, edgecolor="black",
                   lw=0.4, zorder=3)
        ax.plot([r["ik_floor_mm"]] * 2, [yi - 0.34, yi + 0.34], color=rgb01(IK_RGB), lw=2.0, zorder=4)
    ax.set_yticks(y)
    ax.set_yticklabels(labels, fontsize=8.5)
    ax.set_xlabel("D_mean (mm)")
    ax.set_xlim(0.0, max(float(ax.get_xlim()[1]), 1.0))
    ax.grid(True, axis="x", color="0.88", lw=0.6)
    ax.set_axisbelow(True)
    ax.set_title(f"{suite}: D_mean of every run{quick}\nbar: mean over the runs, dots: each run, grey tick: IK floor",
                 fontsize=10)
    fig.tight_layout()
    d_mean = folder / "comparison_d_mean.png"
    fig.savefig(d_mean, dpi=dpi, format="png")
    return [over_time, d_mean]


def _per_run_d_mean(res: Any) -> np.ndarray:
    """Each finished run's D_mean (its summary's, else the mean of its scored frames)."""
    return np.array([run.summary.get("d_mean", np.nanmean(run.d_per_frame)) for run in res.runs], dtype=np.float64)


def write_comparison(folder: str | os.PathLike[str], report: dict[str, Any] | None = None) -> dict[str, Any]:
    """Write the two figures, ``comparison.md`` (the table and the figures) and ``comparison.html`` (the same
    page, self-contained) into ``folder``.

    Returns
    -------
    dict
        ``{"comparison": md path, "html": html path, "figures": [png paths], "notes": [str]}`` (paths as
        strings; a note for each entry with fewer finished runs than the comparison recorded).
    """
    from swarmpose.report.html import write_html

    folder = Path(folder)
    report = load_comparison(folder) if report is None else report
    notes: list[str] = []
    pngs = comparison_figures(folder, report, notes=notes)
    text = comparison_table(report)
    if notes:
        text += "\n" + "".join(f"> Note: {n}\n" for n in notes)
    for p, alt in zip(pngs, ("mean 3D error over time of every entry", "D_mean of every run of every entry"),
                      strict=True):
        text += f"\n![{alt}]({p.name})\n"
    md = folder / "comparison.md"
    md.write_text(text, encoding="utf-8")
    html = write_html(md, title=f"swarmpose compare {report['suite']}")
    return {"comparison": str(md), "html": str(html), "figures": [str(p) for p in pngs], "notes": notes}
