"""Tiny HumanEva-I/II and Lee walk folders written in the real formats (synthetic content).

The subject is a rigid Plug-in-Gait skeleton (virtual markers ``XXXO, XXXP, XXXA, XXXL`` = origin,
z point, x point, y point) turned by ``YAW`` about the vertical and translated along x with mocap
time. Its 15 HumanEva joints are derived here by hand from the support code's rules (pelvis shift,
torso and arm tilts), independently of ``swarmpose.datasets``. Videos show a white dot at every
projected joint and, in the top-left 8x8 block, the grey level ``10 * (video frame index + 1)``
(0-based index), so a test can read back which video frame it got.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import scipy.io

from swarmpose.camera import Camera

YAW = math.radians(25.0)
MOCAP_FRAMES = 60
STEP_MM = 15.0  # translation per mocap frame
TORSO_RADIUS = 193.0  # |LSHO - RSHO| / 2 - 7 from the static trial below
L_SHOULDER_OFFSET, R_SHOULDER_OFFSET = 40.0, 45.0
LOST = ("RKNE", 13)  # marker lost at this 1-based mocap frame

# joint centres in the body frame (x forward, y left, z up), mm
LOCAL = {
    "PELO": (0, 0, 0), "TRXO": (0, 0, 500), "HEDO": (0, 0, 560),
    "LFEP": (0, 100, -50), "LFEO": (0, 100, -500), "LTIO": (0, 100, -920),
    "RFEP": (0, -100, -50), "RFEO": (0, -100, -500), "RTIO": (0, -100, -920),
    "LCLO": (0, 180, 480), "LHUO": (0, 180, 180), "LRAO": (0, 180, -70),
    "RCLO": (0, -180, 480), "RHUO": (0, -180, 180), "RRAO": (0, -180, -70),
}
# segment groups XXX (labels XXXO, XXXP, XXXA, XXXL): the joint centre that is the z-axis point XXXP
# (None: 100 mm above the origin)
GROUPS = {
    "PEL": None, "TRX": None, "HED": None, "LCL": None, "RCL": None,
    "LFE": "LFEP", "RFE": "RFEP", "LTI": "LFEO", "RTI": "RFEO",
    "LHU": "LCLO", "RHU": "RCLO", "LRA": "LHUO", "RRA": "RHUO",
}
VALIDITY = ("RASI", "LASI", "LPSI", "RPSI", "RELB", "LELB", "STRN", "LTHI", "RTHI", "LWRA", "LWRB", "RWRA", "RWRB",
            "T10", "RUPA", "LUPA", "RKNE", "LKNE", "RBAK", "CLAV", "RSHO", "LSHO", "C7", "RTIB", "LTIB", "LBHD",
            "RBHD", "RFHD", "LFHD", "LANK", "RANK", "LHEE", "RHEE", "LTOE", "RTOE", "LFIN", "RFIN", "RFRM", "LFRM")
MP = {"Bodymass": 70.0, "Height": 1780.0, "LKneeWidth": 100.0, "RKneeWidth": 102.0, "LAnkleWidth": 70.0,
      "RAnkleWidth": 71.0, "LElbowWidth": 65.0, "RElbowWidth": 66.0, "LWristWidth": 50.0, "RWristWidth": 51.0,
      "LShoulderOffset": L_SHOULDER_OFFSET, "RShoulderOffset": R_SHOULDER_OFFSET, "HeadOffset": 10.0}


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def translation(m: float) -> np.ndarray:
    """World position of the body frame at 1-based mocap time m."""
    return np.array([-400.0 + STEP_MM * m, 50.0, 950.0])


def to_world(local, m: float) -> np.ndarray:
    return rot_z(YAW) @ np.asarray(local, dtype=float) + translation(m)


def labels() -> list[str]:
    out = []
    for g in GROUPS:
        out += [f"{g}O", f"{g}P", f"{g}A", f"{g}L"]
    out += list(VALIDITY)
    return out


def markers_at(m: float, lost: bool = False) -> np.ndarray:
    """All marker positions (M, 3) at mocap time m (1-based)."""
    R = rot_z(YAW)
    pos = {}
    for g, p_label in GROUPS.items():
        o = np.asarray(LOCAL[f"{g}O"], float)
        p = o + np.array([0, 0, 100.0]) if p_label is None else np.asarray(LOCAL[p_label], float)
        pos[f"{g}O"] = o
        pos[f"{g}P"] = p
        pos[f"{g}A"] = o + np.array([100.0, 0, 0])
        pos[f"{g}L"] = o + np.array([0, 100.0, 0])
    for i, name in enumerate(VALIDITY):
        pos[name] = np.array([20.0 + i, 30.0 - i, 40.0 + 2 * i])
    out = np.stack([R @ pos[n] + translation(m) for n in labels()])
    if lost:
        out[labels().index(LOST[0])] = 0.0
    return out


def mocap_array(n: int = MOCAP_FRAMES) -> np.ndarray:
    return np.stack([markers_at(m, lost=(m == LOST[1])) for m in range(1, n + 1)])


def expected_joints15(m: float) -> np.ndarray:
    """JOINTS15 at mocap time m, by hand from the support code's rules (identity segment frames)."""
    L = {k: np.asarray(v, float) for k, v in LOCAL.items()}
    th_t = math.atan2(TORSO_RADIUS / 2.0, 500.0)
    torso_distal = np.array([-50.0, 0, 0])
    torso_prox = torso_distal + 500.0 * np.array([-math.sin(th_t), 0, math.cos(th_t)])
    head_prox = L["TRXO"]
    head_top = L["TRXO"] + np.array([0, 0, 316.103])
    joints = {"thorax": (torso_prox + head_prox) / 2, "pelvis": torso_distal, "head_top": head_top}
    for side, off in (("l", L_SHOULDER_OFFSET), ("r", R_SHOULDER_OFFSET)):
        S = side.upper()
        th = math.atan2(off / 2.0, 300.0)
        sho = L[f"{S}CLO"]
        elbow = sho + np.array([-300 * math.sin(th), 0, -300 * math.cos(th)])
        wrist = elbow + np.array([250 * math.sin(th), 0, -250 * math.cos(th)])
        joints.update({f"{side}_shoulder": sho, f"{side}_elbow": elbow, f"{side}_wrist": wrist,
                       f"{side}_hip": L[f"{S}FEP"], f"{side}_knee": L[f"{S}FEO"], f"{side}_ankle": L[f"{S}TIO"]})
    from swarmpose.joints import JOINTS15

    return np.stack([to_world(joints[n], m) for n in JOINTS15])


# ---------------------------------------------------------------------- file writers (real formats)
def write_cal(path: Path, cam: Camera, fmt: str = "%f") -> None:
    """As WriteSpicaCalib: one number per line, R row-major."""
    vals = [cam.fx, cam.fy, cam.cx, cam.cy, cam.skew, *cam.dist, *cam.R.ravel(), *cam.t]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join((fmt % v) + " \n" for v in vals))


def write_ofs(path: Path, im_st: float, mc_st: float, mc_sc: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"{im_st:f} \n{mc_st:f} \n{mc_sc:f} \n")


def write_mp(path: Path, values: dict[str, float] = MP) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"${k} = {v}\n" for k, v in values.items()))


def parameter_group(point_labels: list[str]) -> np.ndarray:
    """ParameterGroup struct array as readc3d builds it (cellstr names, POINT:LABELS cell array)."""
    pg = np.zeros((1, 2), dtype=[("name", object), ("description", object), ("Parameter", object)])
    par = np.zeros((1, 2), dtype=[("name", object), ("datatype", object), ("dim", object), ("data", object)])
    par[0, 0]["name"] = np.array(["USED"], dtype=object)
    par[0, 0]["datatype"] = 2.0
    par[0, 0]["dim"] = np.zeros((0, 0))
    par[0, 0]["data"] = float(len(point_labels))
    par[0, 1]["name"] = np.array(["LABELS"], dtype=object)
    par[0, 1]["datatype"] = -1.0
    par[0, 1]["dim"] = np.array([[4.0, len(point_labels)]])
    par[0, 1]["data"] = np.array([[lab + "  " for lab in point_labels]], dtype=object)  # blank-padded as in C3D
    pg[0, 0]["name"] = np.array(["POINT"], dtype=object)
    pg[0, 0]["description"] = np.array(["3-D point parameters"], dtype=object)
    pg[0, 0]["Parameter"] = par
    pg[0, 1]["name"] = np.array(["ANALOG"], dtype=object)
    pg[0, 1]["description"] = np.array(["analog"], dtype=object)
    pg[0, 1]["Parameter"] = np.zeros((0, 0))
    return pg


def write_mocap_mat(path: Path, point_labels: list[str], markers: np.ndarray, rate: float = 120.0) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    scipy.io.savemat(str(path), {"Markers": markers, "VideoFrameRate": rate, "ParameterGroup": parameter_group(point_labels),
                                 "AnalogSignals": np.zeros((0, 0)), "AnalogFrameRate": 0.0},
                     do_compression=True)


def static_markers() -> np.ndarray:
    labs = labels()
    base = mocap_array(5)
    R = rot_z(YAW)
    for name, loc in (("LSHO", (0, 200, 490)), ("RSHO", (0, -200, 490)), ("STRN", (80, 0, 420)), ("T10", (-90, 0, 380)),
                      ("LFHD", (70, 60, 700)), ("RFHD", (70, -60, 700)), ("LBHD", (-70, 60, 690)),
                      ("RBHD", (-70, -60, 690))):
        for m in range(5):
            base[m, labs.index(name)] = R @ np.asarray(loc, float) + translation(m + 1)
    return base


# ---------------------------------------------------------------------- images and videos
def texture(rng: np.random.Generator, w: int, h: int) -> np.ndarray:
    t = rng.uniform(60, 110, (h // 8 + 1, w // 8 + 1)).astype(np.float32)
    t = cv2.resize(t, (w, h), interpolation=cv2.INTER_CUBIC)
    return np.clip(t, 0, 255).astype(np.uint8)


def render(cam: Camera, bg: np.ndarray, m: float, index0: int, rng: np.random.Generator) -> np.ndarray:
    img = np.clip(bg.astype(np.float32) + rng.normal(0, 2.0, bg.shape), 0, 255).astype(np.uint8)
    img = np.repeat(img[..., None], 3, axis=2).copy()
    uv = cam.project(expected_joints15(m))
    for u, v in uv:
        cv2.circle(img, (int(round(u)), int(round(v))), 2, (255, 255, 255), -1)
    img[:8, :8] = 10 * (index0 + 1)
    return img


def write_avi(path: Path, frames: list[np.ndarray], colour: bool = True) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    h, w = frames[0].shape[:2]
    wr = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 60.0, (w, h), colour)
    assert wr.isOpened(), "OpenCV cannot write MJPG .avi here"
    for f in frames:
        wr.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR) if colour else cv2.cvtColor(f, cv2.COLOR_RGB2GRAY))
    wr.release()


def write_folder(path: Path, frames: list[np.ndarray], first: int = 1) -> None:
    path.mkdir(parents=True, exist_ok=True)
    for i, f in enumerate(frames):
        cv2.imwrite(str(path / f"frame_{first + i:04d}.png"), cv2.cvtColor(f, cv2.COLOR_RGB2BGR))


@dataclass
class Fixture:
    root: Path
    subject_dir: Path
    action: str
    trial: str
    cameras: dict[str, Camera]
    offsets: dict[str, tuple[float, float, float]]
    video_frames: int
    backgrounds: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def spec(self) -> str:
        return f"humaneva:{self.subject_dir / f'{self.action}_{self.trial}'}"


def rig(names: list[str], size: tuple[int, int], radius: float = 4500.0, f: float = 140.0) -> dict[str, Camera]:
    out = {}
    for i, n in enumerate(names):
        a = 2 * math.pi * i / len(names) + 0.3
        dist = (-0.08, 0.02, 0.001, -0.0005, 0.0) if i == 0 else (0.0, 0.0, 0.0, 0.0, 0.0)
        out[n] = Camera.look_at(n, eye=(radius * math.cos(a), radius * math.sin(a), 1500.0), target=(0.0, 0.0, 900.0),
                                f=f, width=size[0], height=size[1], dist=dist)
    return out


def make_humaneva_i(root: Path, video_frames: int = 24, action: str = "Walking") -> Fixture:
    """HumanEva-I: S1/<action>_1 with C1-C3 (160x120) and BW1-BW4 (164x124), backgrounds at the root.

    With an action outside the official tables (e.g. "Dance") no partition applies, so
    ``datasets check`` has nothing to complain about; with "Walking" the tiny videos cannot cover
    the official Validate/Train frames.
    """
    rng = np.random.default_rng(1)
    sd = root / "S1"
    cams = {**rig(["C1", "C2", "C3"], (160, 120)), **rig(["BW1", "BW2", "BW3", "BW4"], (164, 124), radius=4800.0)}
    offsets = {"C1": (7, 3, 2), "C2": (5, 1, 2), "C3": (9, 5, 2), "BW1": (6, 1, 2), "BW2": (6, 1, 2), "BW3": (8, 3, 2),
               "BW4": (6, 1, 2)}
    fx = Fixture(root, sd, action, "1", cams, offsets, video_frames)
    for i, (name, cam) in enumerate(cams.items()):
        write_cal(sd / "Calibration_Data" / f"{name}.cal", cam, "%f" if i % 2 == 0 else "%.17g")
        write_ofs(sd / "Sync_Data" / f"{action}_1_({name}).ofs", *offsets[name])
        bg = texture(rng, cam.width, cam.height)
        fx.backgrounds[name] = bg
        im_st, mc_st, sc = offsets[name]
        frames = [render(cam, bg, mc_st + (v - im_st) * sc, v - 1, rng) for v in range(1, video_frames + 1)]
        write_avi(sd / "Image_Data" / f"{action}_1_({name}).avi", frames, colour=name.startswith("C"))
        for s in (1, 2):
            noisy = [np.repeat(np.clip(bg + rng.normal(0, 2.0, bg.shape), 0, 255).astype(np.uint8)[..., None], 3, 2)
                     for _ in range(8)]
            write_avi(root / "Background" / f"Background_{s}_({name}).avi", noisy, colour=name.startswith("C"))
    write_mocap_mat(sd / "Mocap_Data" / f"{action}_1.mat", labels(), mocap_array())
    (sd / "Mocap_Data" / f"{action}_1.c3d").write_bytes(b"")  # the original beside its cache (never read)
    write_mocap_mat(sd / "Mocap_Data" / "Static.mat", labels(), static_markers())
    write_mp(sd / "Mocap_Data" / "S1.mp")
    return fx


def make_humaneva_ii(root: Path, video_frames: int = 20, trial: str = "4") -> Fixture:
    """HumanEva-II: S4/Combo_<trial> with C1-C4 (128x96) as PNG folders, backgrounds in S4/Background."""
    rng = np.random.default_rng(2)
    sd = root / "S4"
    cams = rig(["C1", "C2", "C3", "C4"], (128, 96), f=110.0)
    offsets = dict.fromkeys(cams, (1, 1, 2))
    fx = Fixture(root, sd, "Combo", trial, cams, offsets, video_frames)
    for name, cam in cams.items():
        write_cal(sd / "Calibration_Data" / f"{name}.cal", cam, "%.17g")
        write_ofs(sd / "Sync_Data" / f"Combo_{trial}_({name}).ofs", *offsets[name])
        bg = texture(rng, cam.width, cam.height)
        fx.backgrounds[name] = bg
        frames = [render(cam, bg, 1 + (v - 1) * 2, v - 1, rng) for v in range(1, video_frames + 1)]
        write_folder(sd / "Image_Data" / f"Combo_{trial}_({name})", frames)
        noisy = [np.repeat(np.clip(bg + rng.normal(0, 2.0, bg.shape), 0, 255).astype(np.uint8)[..., None], 3, 2)
                 for _ in range(6)]
        write_folder(sd / "Background" / f"Background_1_({name})", noisy)
    write_mocap_mat(sd / "Mocap_Data" / f"Combo_{trial}.mat", labels(), mocap_array())
    write_mocap_mat(sd / "Mocap_Data" / "Static.mat", labels(), static_markers())
    write_mp(sd / "Mocap_Data" / "S4.mp")
    return fx


def make_leewalk(root: Path, n: int = 10, size: tuple[int, int] = (96, 72)) -> dict[str, Camera]:
    rng = np.random.default_rng(3)
    cams = rig(["1", "2", "3", "4"], size, f=80.0)
    for k, cam in cams.items():
        write_cal(root / "calibration" / f"cam{k}.cal", cam)
        bg = texture(rng, *size)
        frames, masks = [], []
        for i in range(n):
            img = render(cam, bg, 1 + 2 * i, i, rng)
            frames.append(img)
            masks.append(np.repeat(((img.max(axis=2) == 255) * 255).astype(np.uint8)[..., None], 3, 2))
        write_folder(root / "images" / f"cam{k}", [np.repeat(f.max(axis=2)[..., None], 3, 2) for f in frames])
        write_folder(root / "silhouettes" / f"cam{k}", masks)
    (root / "groundtruth").mkdir(parents=True, exist_ok=True)
    params = rng.normal(size=(n, 31))
    np.savetxt(root / "groundtruth" / "params.txt", params)
    joints = np.stack([expected_joints15(1 + 2 * i) for i in range(n)]).reshape(n, 45)
    np.savetxt(root / "groundtruth" / "joints15.txt", joints)
    return cams
