"""A small calibrated rig, a moving 15-joint person, and a fake detector that reads who it sees from the pixels.

The fake detector makes the import's logic testable without MediaPipe: each synthetic frame carries its view
and frame number in its top-left pixels (lossless PNG folders keep them), and the detector answers with the
projections of the known joints, optionally with left and right exchanged or somebody else's joints.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from swarmpose.camera import Camera
from swarmpose.detection.base import Detection
from swarmpose.detection.joints import SWAP15
from swarmpose.joints import JOINTS15
from swarmpose.triangulation import reproject

W, H = 320, 240
#: A standing person's 15 joints (mm), pelvis at the origin's height 1000.
REST = np.array([
    [0, 0, 1450], [0, 0, 1000], [180, 0, 1430], [200, 0, 1150], [210, 0, 900], [-180, 0, 1430], [-200, 0, 1150],
    [-210, 0, 900], [100, 0, 950], [110, 0, 520], [110, 0, 90], [-100, 0, 950], [-110, 0, 520], [-110, 0, 90],
    [0, 0, 1700]], dtype=np.float64)


def rig(n: int = 4, *, dist: bool = True) -> list[Camera]:
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False) + 0.3
    d = (-0.08, 0.02, 0.001, -0.0005, 0.0) if dist else (0.0,) * 5
    return [Camera.look_at(f"cam{c + 1:02d}", [4000 * np.cos(a), 4000 * np.sin(a), 1600], [0, 0, 950],
                           f=260.0, width=W, height=H, dist=d) for c, a in enumerate(angles)]


def motion(T: int) -> np.ndarray:
    """(T, 15, 3): the person walks along x and swings the arms, fast enough that a frame's offset shows."""
    t = np.arange(T)[:, None]
    pts = np.repeat(REST[None], T, axis=0).copy()
    pts[:, :, 0] += 45.0 * t  # 45 mm per frame
    swing = 250.0 * np.sin(0.5 * t)
    pts[:, [4, 10], 1] += swing
    pts[:, [7, 13], 1] -= swing
    return pts


def frame_image(view: int, k: int, uv: np.ndarray) -> np.ndarray:
    """A grey image with the person drawn as thick limbs and its view and frame in pixels (0, 0), (0, 1)."""
    img = np.full((H, W), 40, np.uint8)
    from swarmpose.joints import BONES15

    for a, b in BONES15:
        if np.isfinite(uv[[a, b]]).all():
            cv2.line(img, tuple(int(round(v)) for v in uv[a]), tuple(int(round(v)) for v in uv[b]), 220, 6)
    img[0, 0], img[0, 1] = view, k
    return img


def write_image_folders(root: Path, cams: list[Camera], points: np.ndarray, *, lag: dict[int, int] | None = None,
                        n_frames: dict[int, int] | None = None) -> list[Path]:
    """One PNG folder per camera; camera c's frame k shows the person at time k - lag[c]."""
    lag = lag or {}
    out = []
    for c, cam in enumerate(cams):
        folder = root / cam.name
        folder.mkdir(parents=True)
        T = (n_frames or {}).get(c, len(points))
        for k in range(T):
            ti = min(max(k - lag.get(c, 0), 0), len(points) - 1)
            uv = reproject([cam], points[ti])[0]
            cv2.imwrite(str(folder / f"{k:06d}.png"), frame_image(c, k, uv))
        out.append(folder)
    return out


class FakeDetector:
    """Answers with the true projections: ``swapped[(view, frame)]`` exchanges left and right, ``other`` gives
    somebody 1.5 m to the side (unless asked inside a region of interest)."""

    name = "fake"
    version = "1"
    keypoint_names = JOINTS15

    def __init__(self, cams, points, *, lag=None, swapped=(), other=()):
        self.cams, self.points, self.lag = cams, points, lag or {}
        self.swapped, self.other = set(swapped), set(other)
        self.calls = 0
        self.roi_calls = 0

    @property
    def settings(self):
        return {"swapped": sorted(self.swapped), "other": sorted(self.other)}

    def reset(self):
        pass

    def detect(self, image, roi=None):
        grey = image if image.ndim == 2 else image[..., 0]
        view, k = int(grey[0, 0]), int(grey[0, 1])
        self.calls += 1
        ti = min(max(k - self.lag.get(view, 0), 0), len(self.points) - 1)
        pts = self.points[ti].copy()
        if roi is None and (view, k) in self.other:
            pts[:, 1] += 1500.0
        if roi is not None:
            self.roi_calls += 1
        uv = reproject([self.cams[view]], pts)[0]
        if roi is None and (view, k) in self.swapped:
            uv = uv[SWAP15]
        mask = (grey > 128).astype(np.uint8)
        return Detection(uv, np.full(15, 0.9), mask, True)

