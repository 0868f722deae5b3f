"""The release: cameras, frame rates, official partitions and where a trial's files are."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

VIDEO_RATE = 60.0
MOCAP_RATE = 120.0
#: First usable synchronized frame of HumanEva-I (XVID duplicates frames 1-5).
FIRST_FRAME_I = 6
HUMANEVA_I_CAMERAS: tuple[str, ...] = ("C1", "C2", "C3", "BW1", "BW2", "BW3", "BW4")
HUMANEVA_II_CAMERAS: tuple[str, ...] = ("C1", "C2", "C3", "C4")
DATASET_CAMERAS = {"HumanEva-I": HUMANEVA_I_CAMERAS, "HumanEva-II": HUMANEVA_II_CAMERAS}
DEFAULT_CAMERAS = {"HumanEva-I": ("C1", "C2", "C3"), "HumanEva-II": HUMANEVA_II_CAMERAS}
#: Misclassification risk of the background model per camera (``BackgroundSubtraction.m`` defaults).
DEFAULT_RISK: dict[str, dict[str, float]] = {
    "HumanEva-I": dict.fromkeys(HUMANEVA_I_CAMERAS, 1.0),
    "HumanEva-II": {"C1": 1e80, "C2": 1e60, "C3": 1e30, "C4": 1e80},
}
IMAGE_EXTENSIONS = (".bmp", ".png", ".tif", ".tiff", ".pgm", ".ppm", ".jpg", ".jpeg")


def _ranges() -> dict[tuple[str, str, str], dict[int, dict[str, tuple[int, int]]]]:
    he1 = {
        "S1": {"Walking": ((6, 590), (591, 1203), (6, 1004), (1, 3238)), "Jog": ((6, 367), (368, 740), (6, 874), (1, 3175)),
               "ThrowCatch": ((6, 473), (474, 945), (6, 951), (1, 3453)),
               "Gestures": ((6, 395), (396, 801), (6, 1070), (1, 2127)), "Box": ((6, 385), (386, 789), (6, 606), (1, 1653)),
               "Combo": (None, None, (6, 2602), None)},
        "S2": {"Walking": ((6, 438), (439, 876), (6, 1093), (1, 1523)), "Jog": ((6, 398), (399, 795), (6, 727), (1, 1573)),
               "ThrowCatch": ((6, 550), (551, 1128), (6, 1399), (1, 3340)),
               "Gestures": ((6, 500), (501, 901), (6, 1062), (1, 3551)), "Box": ((6, 382), (383, 734), (6, 989), (1, 3108)),
               "Combo": (None, None, (6, 2054), None)},
        "S3": {"Walking": ((6, 448), (449, 939), (6, 805), (1, 2358)), "Jog": ((6, 401), (402, 842), (6, 864), (1, 1973)),
               "ThrowCatch": ((6, 493), (494, 1027), (6, 1000), (1, 2074)),
               "Gestures": ((6, 533), (534, 1102), (6, 553), (1, 1789)), "Box": ((6, 512), (513, 1021), (6, 753), (1, 1573)),
               "Combo": (None, None, (6, 1798), None)},
        "S4": {a: (None, None, r, None) for a, r in (("Walking", (6, 667)), ("Jog", (6, 590)), ("ThrowCatch", (6, 773)),
                                                       ("Gestures", (6, 459)), ("Box", (6, 574)), ("Combo", (6, 1102)))},
    }
    out: dict[tuple[str, str, str], dict[int, dict[str, tuple[int, int]]]] = {}
    for s, actions in he1.items():
        for a, (val, train, test, train3) in actions.items():
            d: dict[int, dict[str, tuple[int, int]]] = {}
            if val is not None:
                d[1] = {"validate": val, "train": train}
            d[2] = {"test": test}
            if train3 is not None:
                d[3] = {"train": train3}
            out[("HumanEva-I", s, a)] = d
    out[("HumanEva-II", "S2", "Combo")] = {1: {"test": (1, 1202)}}
    out[("HumanEva-II", "S4", "Combo")] = {4: {"test": (2, 1258)}}
    return out


#: Official partitions, synchronized frames (1-based, inclusive):
#: ``FRAME_RANGES[(dataset, subject, action)][trial][split] = (first, last)``.
FRAME_RANGES = _ranges()

#: 1-based video frame of C1, C2, C3 at synchronized frame 1, trial 1, *after* the critical OFS
#: update (hard-coded by VideoPose3D); used by ``datasets check`` as a sanity note.
OFS_UPDATE_SANITY: dict[tuple[str, str], tuple[int, int, int]] = {
    ("S1", "Walking"): (82, 81, 82), ("S1", "Jog"): (51, 51, 50), ("S1", "ThrowCatch"): (61, 61, 60),
    ("S1", "Gestures"): (45, 45, 44), ("S1", "Box"): (57, 57, 56),
    ("S2", "Walking"): (115, 115, 114), ("S2", "Jog"): (100, 100, 99), ("S2", "ThrowCatch"): (127, 127, 127),
    ("S2", "Gestures"): (122, 122, 121), ("S2", "Box"): (119, 119, 117),
    ("S3", "Walking"): (80, 80, 80), ("S3", "Jog"): (65, 65, 65), ("S3", "ThrowCatch"): (79, 79, 79),
    ("S3", "Gestures"): (83, 83, 82), ("S3", "Box"): (1, 1, 1),
}


def humaneva_frame_range(dataset: str, subject: str, action: str, trial: str | int,
                         split: str = "auto") -> tuple[int, int] | None:
    """Official synchronized-frame range of a partition, or None when the table has no entry.

    ``split``: ``"validate"``, ``"train"``, ``"test"`` or ``"auto"`` (trial 1 -> validate, trial 2 ->
    test, trial 3 -> train, HumanEva-II -> test).
    """
    trials = FRAME_RANGES.get((dataset, subject, action))
    if trials is None:
        return None
    splits = trials.get(int(trial))
    if not splits:
        return None
    if split == "auto":
        for s in ("validate", "test", "train"):
            if s in splits:
                return splits[s]
        return None
    return splits.get(split)


def _video_path(subject_dir: Path, action: str, trial: str, cam: str) -> Path | None:
    base = subject_dir / "Image_Data" / f"{action}_{trial}_({cam})"
    if base.is_dir():
        return base
    for ext in (".avi", ".AVI"):
        if base.with_name(base.name + ext).is_file():
            return base.with_name(base.name + ext)
    return None


def detect_dataset(subject_dir: str | os.PathLike[str], action: str | None = None,
                   trial: str | None = None) -> str:
    """``"HumanEva-I"`` or ``"HumanEva-II"`` from the camera names present for a subject (or trial).

    Greyscale cameras (``BW*``) mean HumanEva-I; a fourth colour camera (``C4``) HumanEva-II;
    otherwise HumanEva-I.
    """
    sd = Path(subject_dir)
    names: set[str] = set()
    pat = f"{action}_{trial}_(*).ofs" if action and trial else "*_(*).ofs"
    sync = sd / "Sync_Data"
    if sync.is_dir():
        names |= {m.group(1) for f in sync.glob(pat) if (m := re.search(r"_\(([^)]+)\)\.ofs$", f.name))}
    cal = sd / "Calibration_Data"
    if not names and cal.is_dir():
        names |= {f.stem for f in cal.glob("*.cal")}
    if any(n.startswith("BW") for n in names):
        return "HumanEva-I"
    if "C4" in names:
        return "HumanEva-II"
    return "HumanEva-I"


def _background_dirs(subject_dir: Path) -> list[Path]:
    return [d for d in (subject_dir / "Background", subject_dir.parent / "Background") if d.is_dir()]


def _background_sessions(subject_dir: Path, cam: str) -> tuple[Path | None, list[Path]]:
    """(precomputed Background_(CAM).mat or None, session footage paths) for a camera."""
    for d in _background_dirs(subject_dir):
        mat = d / f"Background_({cam}).mat"
        sessions = sorted(p for p in d.glob(f"Background_*_({cam})*")
                          if p.is_dir() or p.suffix.lower() == ".avi")
        if mat.is_file() or sessions:
            return (mat if mat.is_file() else None), sessions
    return None, []


def trial_files(subject_dir: str | os.PathLike[str], action: str, trial: str | int,
                dataset: str | None = None) -> dict[str, Any]:
    """Expected paths of one trial (existing or not), for the loader and ``datasets check``."""
    sd = Path(subject_dir)
    trial = str(trial)
    ds = dataset or detect_dataset(sd, action, trial)
    cams = DATASET_CAMERAS[ds]
    subject = sd.name
    mocap_c3d = sd / "Mocap_Data" / f"{action}_{trial}.c3d"
    return {
        "dataset": ds,
        "cameras": cams,
        "calibration": {c: sd / "Calibration_Data" / f"{c}.cal" for c in cams},
        "offsets": {c: sd / "Sync_Data" / f"{action}_{trial}_({c}).ofs" for c in cams},
        "video": {c: _video_path(sd, action, trial, c) or sd / "Image_Data" / f"{action}_{trial}_({c}).avi"
                  for c in cams},
        "mocap": mocap_c3d.with_suffix(".mat") if mocap_c3d.with_suffix(".mat").is_file() else mocap_c3d,
        "static": (sd / "Mocap_Data" / "Static.mat") if (sd / "Mocap_Data" / "Static.mat").is_file()
        else sd / "Mocap_Data" / "Static.c3d",
        "mp": sd / "Mocap_Data" / f"{subject}.mp",
    }
