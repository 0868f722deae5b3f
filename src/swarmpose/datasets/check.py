"""``swarmpose datasets check``: validate a HumanEva release, one subject folder, or a Lee walk folder.

:func:`check_dataset` never raises for a bad dataset: it collects every problem as
``"<file>: <what is wrong>"`` (paths relative to the checked folder's parent for a subject folder,
to the folder itself otherwise) and reports what it found. Problems make the check fail; notes are
informational (e.g. mocap withheld for test trials, sync offsets that differ from the published
values after the critical OFS update).

Checked for HumanEva (per subject): the four data folders; every camera's ``.cal`` (parsed); per
trial with video: every camera's video (opened, first and last frame decoded, size consistent per
camera and per camera kind) and ``.ofs`` (parsed), the synchronized frames covering the official
partitions; mocap (``.mat`` cache or ``.c3d``; parsed, marker labels the ground truth needs) for
trials 1 and 3 of HumanEva-I; the subject's ``.mp`` (parsed, the 11 measurements present); background
footage or the support code's precomputed statistics per camera (size matches the videos).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from swarmpose.datasets.humaneva import (
    DATASET_CAMERAS,
    FRAME_RANGES,
    MP_NAMES,
    OFS_UPDATE_SANITY,
    VideoSource,
    detect_dataset,
    mp_value,
    parse_calibration,
    read_background_mat,
    read_mocap,
    read_mp,
    read_offsets,
    synchronize,
)
from swarmpose.datasets.humaneva.layout import _background_sessions
from swarmpose.datasets.leewalk import (
    LEEWALK_FRAMES,
    LEEWALK_SIZE,
    N_PARAMS,
    LeeWalkLayout,
    read_number_table,
)
from swarmpose.errors import DataError, SwarmposeError

__all__ = ["CheckReport", "check_dataset"]

_SUBJECT_DIRS = ("Calibration_Data", "Sync_Data", "Image_Data", "Mocap_Data")
_VIDEO_RE = re.compile(r"^(?P<trial>.+_\d+)_\((?P<cam>[^)]+)\)(?:\.avi)?$", re.IGNORECASE)
_OFS_RE = re.compile(r"^(?P<trial>.+_\d+)_\((?P<cam>[^)]+)\)\.ofs$", re.IGNORECASE)
_MOCAP_RE = re.compile(r"^(?P<trial>.+_\d+)\.(?:c3d|mat)$", re.IGNORECASE)


@dataclass
class CheckReport:
    """Result of :func:`check_dataset`.

    Attributes
    ----------
    path : str
    kind : str
        ``humaneva-release``, ``humaneva-subject``, ``leewalk`` or ``unknown``.
    cameras : list of str
        Cameras with a readable calibration.
    problems : list of str
        ``"<file>: <what is wrong>"``; empty when the dataset is usable.
    notes : list of str
        Informational remarks.
    sequences : list of str
        Trials found (``S1/Walking_1``) or ``leewalk``.
    """

    path: str
    kind: str = "unknown"
    cameras: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    sequences: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when there are no problems."""
        return not self.problems

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: ``ok``, ``kind``, ``path``, ``cameras``, ``problems``, ``notes``, ``sequences``."""
        return {"ok": self.ok, "kind": self.kind, "path": self.path, "cameras": list(self.cameras),
                "problems": list(self.problems), "notes": list(self.notes), "sequences": list(self.sequences)}


class _Collector:
    def __init__(self, report: CheckReport, base: Path):
        self.r = report
        self.base = base
        self.prefix = str(base) + os.sep if str(base) not in ("", ".") else ""

    def rel(self, p: Path | str) -> str:
        s = str(p)
        return s[len(self.prefix):] if self.prefix and s.startswith(self.prefix) else s

    def clean(self, msg: str) -> str:
        return msg.replace(self.prefix, "") if self.prefix else msg

    def problem(self, path: Path | str, what: str) -> None:
        msg = f"{self.rel(path)}: {what}"
        if msg not in self.r.problems:
            self.r.problems.append(msg)

    def error(self, exc: BaseException) -> None:
        msg = self.clean(str(exc))
        if msg not in self.r.problems:
            self.r.problems.append(msg)

    def note(self, msg: str) -> None:
        msg = self.clean(msg)
        if msg not in self.r.notes:
            self.r.notes.append(msg)

    def attempt(self, fn: Callable[[], Any]) -> Any:
        """Run ``fn``; a library error (or OSError) becomes a problem and None is returned."""
        try:
            return fn()
        except (SwarmposeError, OSError) as exc:
            self.error(exc)
            return None


def check_dataset(path: str | os.PathLike[str]) -> CheckReport:
    """Validate a dataset folder and report exactly what is missing or malformed.

    Parameters
    ----------
    path : path-like
        A HumanEva release root (``S1/``, ``S2/``, ... and, for HumanEva-I, ``Background/``), one
        subject folder (``S1/``), or a Lee walk folder (see :class:`~swarmpose.datasets.leewalk.LeeWalkLayout`).

    Returns
    -------
    CheckReport
    """
    p = Path(path)
    report = CheckReport(path=str(p))
    if not p.exists():
        report.problems.append(f"{p}: no such folder")
        return report
    if not p.is_dir():
        report.problems.append(f"{p}: is a file, expected a dataset folder")
        return report
    subjects = sorted((d for d in p.iterdir() if d.is_dir() and re.fullmatch(r"S\d+", d.name)),
                      key=lambda d: int(d.name[1:]))
    if any((p / d).is_dir() for d in _SUBJECT_DIRS):
        report.kind = "humaneva-subject"
        _check_subject(p, _Collector(report, p.parent))
    elif subjects:
        report.kind = "humaneva-release"
        col = _Collector(report, p)
        for sd in subjects:
            _check_subject(sd, col)
    elif _looks_like_leewalk(p):
        report.kind = "leewalk"
        _check_leewalk(p, _Collector(report, p))
    else:
        report.problems.append(
            f"{p}: not a HumanEva release (S1/, S2/, ... folders), a HumanEva subject folder ({', '.join(_SUBJECT_DIRS)}) "
            f"or a Lee walk folder (e.g. calibration/cam1.cal and images/cam1/)")
    order = {c: i for i, c in enumerate((*DATASET_CAMERAS["HumanEva-I"], "C4"))}
    report.cameras = sorted(set(report.cameras), key=lambda c: (order.get(c, 99), c))
    return report


# ---------------------------------------------------------------------- HumanEva
def _trials(sd: Path) -> dict[str, dict[str, set[str]]]:
    """``{"Walking_1": {"video": {cams}, "ofs": {cams}, "mocap": {...}}}`` from the file names."""
    out: dict[str, dict[str, set[str]]] = {}

    def slot(t: str) -> dict[str, set[str]]:
        return out.setdefault(t, {"video": set(), "ofs": set(), "mocap": set()})

    img = sd / "Image_Data"
    if img.is_dir():
        for f in img.iterdir():
            m = _VIDEO_RE.match(f.name)
            if m and (f.is_dir() or f.suffix.lower() == ".avi"):
                slot(m["trial"])["video"].add(m["cam"])
    sync = sd / "Sync_Data"
    if sync.is_dir():
        for f in sync.iterdir():
            m = _OFS_RE.match(f.name)
            if m:
                slot(m["trial"])["ofs"].add(m["cam"])
    moc = sd / "Mocap_Data"
    if moc.is_dir():
        for f in moc.iterdir():
            m = _MOCAP_RE.match(f.name)
            if m and not f.name.lower().startswith("static"):
                slot(m["trial"])["mocap"].add(f.suffix.lower())
    return out


def _check_subject(sd: Path, col: _Collector) -> None:
    r = col.r
    dataset = detect_dataset(sd)
    cams = DATASET_CAMERAS[dataset]
    subject = sd.name
    for d in _SUBJECT_DIRS:
        if not (sd / d).is_dir():
            col.problem(sd / d, "missing folder")
    # calibration
    for cam in cams:
        cal = sd / "Calibration_Data" / f"{cam}.cal"
        if not cal.is_file():
            col.problem(cal, f"missing calibration of camera {cam}")
        elif col.attempt(lambda cal=cal: parse_calibration(cal)) is not None:
            r.cameras.append(cam)
    if (sd / "Calibration_Data").is_dir():
        extra = sorted(f.name for f in (sd / "Calibration_Data").glob("*.cal") if f.stem not in cams)
        if extra:
            col.note(f"{col.rel(sd / 'Calibration_Data')}: ignored calibration files {extra} ({dataset} cameras are "
                     f"{', '.join(cams)})")
    # trials
    sizes: dict[str, tuple[int, int]] = {}
    any_mocap = False
    for name, parts in sorted(_trials(sd).items()):
        action, trial = name.rsplit("_", 1)
        r.sequences.append(f"{subject}/{name}")
        has_video = bool(parts["video"])
        offsets: dict[str, Any] = {}
        n_video: dict[str, int] = {}
        if has_video or parts["ofs"]:
            for cam in cams:
                vid_dir = sd / "Image_Data" / f"{name}_({cam})"
                vid = vid_dir if vid_dir.is_dir() else vid_dir.with_name(vid_dir.name + ".avi")
                ofs = sd / "Sync_Data" / f"{name}_({cam}).ofs"
                if not ofs.is_file():
                    col.problem(ofs, f"missing sync file of camera {cam}")
                    offsets[cam] = None
                else:
                    offsets[cam] = col.attempt(lambda ofs=ofs: read_offsets(ofs))
                if not has_video:
                    continue
                if not vid.exists():
                    col.problem(vid, f"missing video of camera {cam}")
                    continue
                info = col.attempt(lambda vid=vid: _probe_video(vid))
                if info is None:
                    continue
                n_video[cam], size = info
                if cam in sizes and sizes[cam] != size:
                    col.problem(vid, f"frames are {size[0]}x{size[1]}, other videos of {cam} are "
                                     f"{sizes[cam][0]}x{sizes[cam][1]}")
                sizes.setdefault(cam, size)
        # mocap
        mocap = None
        mocap_expected = dataset == "HumanEva-I" and trial in ("1", "3")
        if parts["mocap"]:
            any_mocap = True
            path = sd / "Mocap_Data" / f"{name}.c3d"
            mocap = col.attempt(lambda path=path: read_mocap(path if path.is_file() else path.with_suffix(".mat")))
            if mocap is not None:
                missing = mocap.missing_labels()
                if missing:
                    col.problem(mocap.path, f"marker labels needed for the ground truth are missing: {missing}")
        elif mocap_expected:
            col.problem(sd / "Mocap_Data" / f"{name}.c3d", "missing mocap (the .c3d, or the support code's .mat "
                                                           "cache beside it)")
        elif has_video:
            col.note(f"{subject}/{name}: no mocap (test data: ground truth is withheld, evaluation is online)")
        # synchronization and partitions
        if has_video and offsets and all(o is not None for o in offsets.values()):
            _check_sync(sd, name, action, trial, dataset, offsets, n_video, mocap, col)
    if not r.sequences and (sd / "Image_Data").is_dir():
        col.problem(sd / "Image_Data", "no videos named <Action>_<Trial>_(<CAM>).avi (or image folders)")
    # subject measurements
    mp = sd / "Mocap_Data" / f"{subject}.mp"
    if not mp.is_file():
        if any_mocap:
            col.problem(mp, "missing subject measurement file (needed for the ground-truth limb radii)")
    else:
        values = col.attempt(lambda: read_mp(mp))
        if values is not None:
            for n in MP_NAMES:
                col.attempt(lambda n=n: mp_value(values, n, mp))
    if any_mocap and not any((sd / "Mocap_Data" / f"Static{e}").is_file() for e in (".c3d", ".mat")):
        col.note(f"{col.rel(sd / 'Mocap_Data' / 'Static.c3d')}: missing; the torso radius will come from each trial")
    # backgrounds
    for cam in cams:
        mat, sessions = _background_sessions(sd, cam)
        if mat is None and not sessions:
            where = (f"{col.rel(sd.parent / 'Background')}/Background_*_({cam}).avi" if dataset == "HumanEva-I"
                     else f"{col.rel(sd / 'Background')}/Background_*_({cam})/")
            col.problem(where, f"missing background footage of camera {cam} (needed for silhouettes)")
            continue
        if mat is not None:
            model = col.attempt(lambda mat=mat: read_background_mat(mat))
            bg_size = None if model is None else model.size
            where = mat
        else:
            info = col.attempt(lambda s=sessions[0]: _probe_video(s))
            bg_size = None if info is None else info[1]
            where = sessions[0]
        if bg_size is not None and cam in sizes and bg_size != sizes[cam]:
            col.problem(where, f"background is {bg_size[0]}x{bg_size[1]}, the videos of {cam} are "
                               f"{sizes[cam][0]}x{sizes[cam][1]}")
    # one image size per camera kind (a sequence needs equal sizes)
    for kind in ("C", "BW"):
        group = {c: s for c, s in sizes.items() if c.startswith(kind)}
        if len(set(group.values())) > 1:
            col.problem(sd / "Image_Data", f"cameras {sorted(group)} differ in image size {group}; a sequence needs "
                                           "one size per view")


def _probe_video(path: Path) -> tuple[int, tuple[int, int]]:
    with VideoSource(path) as src:
        if src.n_frames < 1:
            raise DataError(f"{path}: video has no frames")
        src.read(0)
        src.read(src.n_frames - 1)
        return src.n_frames, src.size


def _check_sync(sd: Path, name: str, action: str, trial: str, dataset: str, offsets: dict[str, Any],
                n_video: dict[str, int], mocap: Any, col: _Collector) -> None:
    sync = synchronize(offsets, DATASET_CAMERAS[dataset])
    subject = sd.name
    expected = OFS_UPDATE_SANITY.get((subject, action)) if dataset == "HumanEva-I" and trial == "1" else None
    if expected is not None:
        got = tuple(sync.video_start.get(c) for c in ("C1", "C2", "C3"))
        if got != expected:
            col.note(f"{subject}/Sync_Data/{name}_(C*).ofs: C1-C3 start at video frames {got}, the values published "
                     f"after the critical OFS update are {expected}; if you have not applied "
                     "Critical_Update_OFS_files.zip, do (see docs/datasets.md)")
    avail = [(f"video of {c}", n - sync.video_start[c] + 1) for c, n in n_video.items()]
    if mocap is not None:
        avail.append(("mocap", sync.mocap_frames(mocap.n_frames)))
    if not avail:
        return
    what, last = min(avail, key=lambda t: t[1])
    for split, (a, b) in FRAME_RANGES.get((dataset, subject, action), {}).get(int(trial), {}).items():
        if b > last:
            col.problem(sd / "Image_Data" if what.startswith("video") else sd / "Mocap_Data",
                        f"{name}: the {split} partition needs synchronized frames {a}-{b}, but the {what} ends at "
                        f"synchronized frame {last} (truncated file, or sync offsets that do not match)")


# ---------------------------------------------------------------------- Lee walk
def _looks_like_leewalk(p: Path) -> bool:
    lay = LeeWalkLayout()
    cam = lay.cameras[0]
    return any(lay.find(p, k, cam) is not None for k in ("calibration", "images", "silhouettes"))


def _check_leewalk(root: Path, col: _Collector) -> None:
    lay = LeeWalkLayout()
    r = col.r
    r.sequences.append("leewalk")
    counts: dict[str, int] = {}
    sizes: dict[str, tuple[int, int]] = {}
    for cam in lay.cameras:
        cal = lay.find(root, "calibration", cam)
        if cal is None:
            r.problems.append(f"calibration of camera {cam}: missing; expected one of "
                              f"{col.clean(lay.expected(root, 'calibration', cam))}")
        elif col.attempt(lambda cal=cal: parse_calibration(cal)) is not None:
            r.cameras.append(f"cam{cam}")
        found_any = False
        for kind in ("images", "silhouettes"):
            src = lay.find(root, kind, cam)
            if src is None:
                continue
            found_any = True
            info = col.attempt(lambda src=src: _probe_video(src))
            if info is not None:
                counts[f"{kind}/cam{cam}"], sizes[f"{kind}/cam{cam}"] = info
        if not found_any:
            r.problems.append(f"images of camera {cam}: missing; expected one of "
                              f"{col.clean(lay.expected(root, 'images', cam))}; or background-subtracted images: "
                              f"{col.clean(lay.expected(root, 'silhouettes', cam))}")
    if len(set(counts.values())) > 1:
        r.problems.append(f"{col.rel(root) or '.'}: frame counts differ between views/streams: {counts}")
    if counts and set(counts.values()) != {LEEWALK_FRAMES}:
        col.note(f"frame counts {sorted(set(counts.values()))} differ from the published {LEEWALK_FRAMES}")
    if len(set(sizes.values())) > 1:
        r.problems.append(f"{col.rel(root) or '.'}: image sizes differ between views: {sizes}")
    if sizes and set(sizes.values()) != {LEEWALK_SIZE}:
        col.note(f"image size {sorted(set(sizes.values()))} differs from the published {LEEWALK_SIZE[0]}x{LEEWALK_SIZE[1]}")
    n = min(counts.values()) if counts else None
    for kind, cols, what in (("gt_params", N_PARAMS, "ground-truth parameter file"),
                             ("gt_joints", 45, "ground-truth joint file")):
        f = lay.find(root, kind)
        if f is None:
            col.note(f"no {what}; looked for {col.clean(lay.expected(root, kind))}")
            continue
        table = col.attempt(lambda f=f, cols=cols, what=what: read_number_table(f, cols, what))
        if table is not None and n is not None and len(table) < n:
            col.problem(f, f"{len(table)} frames, the images have {n}")
