"""Synthesise a multi-view sequence from a motion-capture clip (``swarmpose synth``).

Pipeline per frame (``shared/design.md`` §4):

1. pose the observation body (:mod:`swarmpose.synth.body`) on the clip's skeleton;
2. z-buffer it into every camera of the rig (:mod:`swarmpose.synth.raster`): shading, depth,
   part index, exact mask;
3. form the camera images over the textured room background with PSF and sensor noise
   (:mod:`swarmpose.synth.scene`);
4. 2D marker detections with self-occlusion, drop-outs, false detections and noise
   (:mod:`swarmpose.synth.markers`);
5. stream images and exact masks into the sequence folder (:mod:`swarmpose.io.sequence`);
6. run the product's own feature code (:func:`swarmpose.features.silhouette`,
   :func:`swarmpose.features.compute_features`) on the images, as on real video, and measure
   (a) the IoU of the image-derived silhouettes against the exact masks and (b) the tracker
   model's silhouette fitness ``f_s`` (thesis eq. 5.5) at its inverse-kinematics pose on the
   ground truth (``balan31`` with the clip's limb lengths), every ``fs_stride``-th frame.

Randomness: one seed; ``numpy.random.SeedSequence(seed).spawn(3)`` gives independent streams for
the room texture, the sensor noise and the markers.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.body.measurements import SubjectMeasurements
from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, DataError
from swarmpose.io.bvh import read_bvh
from swarmpose.io.mocap import load_clip
from swarmpose.io.sequence import MarkerData, SequenceWriter, open_sequence
from swarmpose.synth.body import BodySettings, ObservationBody
from swarmpose.synth.markers import (
    MarkerSettings,
    MarkerStats,
    detect_markers,
    marker_points,
    marker_visibility,
    own_part_table,
)
from swarmpose.synth.raster import project_vertices, rasterize
from swarmpose.synth.rig import RigSettings, capture_volume, default_rig
from swarmpose.synth.scene import Room, SceneSettings, blur, form_image, render_background, shade_vertices

__all__ = ["SYNTH_VERSION", "SynthReport", "synthesize", "cached_sequence", "iou_summary"]

#: Bumped whenever the synthesiser's output for the same inputs changes (part of the cache key).
SYNTH_VERSION = 3  # 2: sequences carry the subject measurements; 3: the head's triangles face outwards


def _percentiles(values: np.ndarray) -> dict[str, float]:
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"n": 0, "min": float("nan"), "mean": float("nan")}
    p = np.percentile(v, [1, 5, 25, 50, 75, 95])
    return {"n": int(v.size), "min": float(v.min()), "p01": float(p[0]), "p05": float(p[1]), "p25": float(p[2]),
            "p50": float(p[3]), "p75": float(p[4]), "p95": float(p[5]), "max": float(v.max()),
            "mean": float(v.mean())}


def iou_summary(iou: np.ndarray) -> dict[str, float]:
    """Distribution of per-frame, per-view IoU values ``(T, C)``: n, min, p01..p95, max, mean."""
    return _percentiles(iou)


@dataclass
class SynthReport:
    """What :func:`synthesize` measured (``swarmpose synth --json`` prints :meth:`to_dict`).

    Attributes
    ----------
    path : pathlib.Path
        The sequence folder.
    clip : str
    frames, views : int
    seconds : float
        Wall time of the whole synthesis, writing and measurements included.
    iou : numpy.ndarray, shape (T, C)
        IoU of the image-derived silhouette against the exact mask per frame and view (NaN where the
        person is in neither).
    fs : numpy.ndarray, shape (E, C)
        Tracker model's ``f_s`` at its IK pose (the smooth fit, the tracker's start pose) on the evaluated
        frames ``fs_frames``.
    fs_frames : numpy.ndarray, shape (E,)
    ik_floor_mm : float
        Mean per-frame 3D error of the best (polished) IK fit on the evaluated frames: the IK floor.
    marker_stats : MarkerStats or None
    timings : dict of str to float
        Seconds per stage.
    disk_bytes : int
    measurements : SubjectMeasurements or None
        The observation body measured as a lab measures a subject (stored in the sequence).
    """

    path: Path
    clip: str
    frames: int
    views: int
    seconds: float
    iou: np.ndarray
    fs: np.ndarray
    fs_frames: np.ndarray
    ik_floor_mm: float
    marker_stats: MarkerStats | None
    timings: dict[str, float] = field(default_factory=dict)
    disk_bytes: int = 0
    measurements: SubjectMeasurements | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe summary (the ``--json`` output)."""
        fs = self.fs[np.isfinite(self.fs)]
        out: dict[str, Any] = {
            "path": str(self.path),
            "clip": self.clip,
            "frames": self.frames,
            "views": self.views,
            "seconds": round(self.seconds, 3),
            "silhouette_iou": iou_summary(self.iou),
            "model_fs_at_gt": {
                "mean": float(fs.mean()) if fs.size else None,
                "min": float(fs.min()) if fs.size else None,
                "max": float(fs.max()) if fs.size else None,
                "n_frames": int(len(self.fs_frames)),
                "n_values": int(fs.size),
                "per_view_mean": [float(np.nanmean(c)) if np.isfinite(c).any() else None for c in self.fs.T],
                "ik_floor_mm": self.ik_floor_mm,
            },
            "markers": self.marker_stats.to_dict() if self.marker_stats is not None else None,
            "subject_measurements": self.measurements.to_dict() if self.measurements is not None else None,
            "timings_s": {k: round(v, 3) for k, v in self.timings.items()},
            "disk_mb": round(self.disk_bytes / 2**20, 1),
        }
        return _finite(out)


def _finite(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("swarmpose")
    except Exception:  # pragma: no cover - not installed
        return "unknown"


def _folder_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def synthesize(
    clip_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    fps: float = 60.0,
    seed: int = 0,
    rig: list[Camera] | None = None,
    markers: MarkerSettings | None = None,
    body: BodySettings | None = None,
    scene: SceneSettings | None = None,
    rig_settings: RigSettings | None = None,
    max_frames: int | None = None,
    fs_stride: int = 5,
    measure: bool = True,
    overwrite: bool = False,
    progress: bool = True,
) -> SynthReport:
    """Render a BVH clip into a HumanEva-like multi-view sequence folder and measure it.

    Parameters
    ----------
    clip_path : path-like
        CMU-style BVH file.
    out_dir : path-like
        Sequence folder to write (must be empty or absent unless ``overwrite``).
    fps : float, default 60
        Frame rate of the sequence (the clip is resampled).
    seed : int, default 0
        Seed of the background texture, sensor noise and marker randomness.
    rig : list of Camera, optional
        Cameras; default :func:`~swarmpose.synth.rig.default_rig` of the clip.
    markers : MarkerSettings, optional
        Default ``MarkerSettings()`` (15 joints, 5 % drop-out, 0.5 false per view, 1 px noise).
    body : BodySettings, optional
    scene : SceneSettings, optional
    rig_settings : RigSettings, optional
        Used when ``rig`` is None.
    max_frames : int, optional
        Only the first ``max_frames`` frames.
    fs_stride : int, default 5
        Evaluate the tracker model's ``f_s`` every ``fs_stride``-th frame (inverse kinematics costs
        about 50 ms a frame); 0 disables it.
    measure : bool, default True
        Compute silhouettes (IoU) and ``f_s``; False only renders and writes.
    overwrite : bool, default False
    progress : bool, default True
        Progress bar on stderr.

    Returns
    -------
    SynthReport
    """
    t_start = time.perf_counter()
    timings: dict[str, float] = {}

    def tick(name: str, t0: float) -> float:
        t1 = time.perf_counter()
        timings[name] = timings.get(name, 0.0) + (t1 - t0)
        return t1

    clip_path = Path(clip_path)
    if not clip_path.is_file():
        raise DataError(f"{clip_path}: no such clip")
    seed = int(seed)
    markers = markers or MarkerSettings()
    body_settings = body or BodySettings()
    scene = scene or SceneSettings()
    if fs_stride < 0:
        raise ConfigError(f"fs_stride must be >= 0, got {fs_stride!r}")
    t0 = time.perf_counter()
    clip = load_clip(clip_path, fps=fps)
    source_rate = float(read_bvh(clip_path).frame_rate)  # the capture rate; clip.bvh is the resampled clip
    T = clip.frames if max_frames is None else max(0, min(clip.frames, int(max_frames)))
    if T < 1:
        raise ConfigError(f"{clip_path}: nothing to synthesise ({clip.frames} frames, max_frames={max_frames})")
    obs = ObservationBody.from_clip(clip, body_settings)
    measurements = obs.measurements()
    cams = list(rig) if rig is not None else default_rig(clip, rig_settings)
    C = len(cams)
    W, H = cams[0].width, cams[0].height
    ss_room, ss_noise, ss_markers = np.random.SeedSequence(seed).spawn(3)
    rng_noise = np.random.default_rng(ss_noise)
    rng_markers = np.random.default_rng(ss_markers)
    lo, hi = capture_volume(clip.positions[:T])
    room = Room(lo, hi, cams, scene, np.random.default_rng(ss_room))
    bg_float = [render_background(cam, room) for cam in cams]
    backgrounds = np.stack([np.rint(np.clip(blur(b, scene.psf_sigma_px), 0, 255)).astype(np.uint8)
                            for b in bg_float])
    t0 = tick("setup", t0)

    # markers: 3D points, own-part table
    names = markers.names
    pts3d = marker_points(clip, names)[:T] if names else None
    own = own_part_table(names, obs.part_names) if names else None
    mstats = MarkerStats() if names else None
    det_pos: list[list[np.ndarray]] = []
    det_ids: list[list[np.ndarray]] = []
    proj_all = np.zeros((T, C, len(names), 2)) if names else None
    vis_all = np.zeros((T, C, len(names)), dtype=bool) if names else None

    # tracker model at the ground truth (for f_s)
    fs_frames = np.arange(0, T, fs_stride, dtype=np.int64) if (measure and fs_stride > 0) else np.zeros(0, np.int64)
    fs = np.full((len(fs_frames), C), np.nan)
    fs_params = None
    ik_floor = float("nan")
    fitness = None
    if len(fs_frames):
        from swarmpose.body.ik import fit_ik
        from swarmpose.body.model import load_model
        from swarmpose.fitness import make_fitness
        from swarmpose.io.mocap import subject_from_clip

        base = load_model("balan31")
        model = base.with_subject(subject_from_clip(base.spec, clip, measurements))
        ik = fit_ik(model, clip.joints[fs_frames])
        fs_params = ik.params
        ik_floor = ik.floor_mean_mm
        fitness = make_fitness("silhouette_edge", model)
        t0 = tick("ik", t0)
    fs_lookup = {int(k): i for i, k in enumerate(fs_frames)}

    iou = np.full((T, C), np.nan)
    writer = SequenceWriter(out_dir, cams, clip.frame_rate, T, streams=("image", "mask"), overwrite=overwrite)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=T, desc=f"synth {clip_path.stem}", unit="frame", file=sys.stderr, dynamic_ncols=True)
    try:
        for k in range(T):
            t0 = time.perf_counter()
            verts, normals = obs.mesh(k)
            shade = shade_vertices(normals, obs.vertex_albedo, scene)
            uv, z = project_vertices(verts, cams)
            ras = rasterize(uv, z, shade, obs.faces, obs.face_part, H, W)
            masks = (ras.part >= 0).astype(np.uint8)
            t0 = tick("render", t0)
            images = np.stack([form_image(ras.shade[c], masks[c].astype(bool), bg_float[c], scene, rng_noise)
                               for c in range(C)])
            t0 = tick("image", t0)
            if names:
                muv = np.empty((C, len(names), 2))
                mz = np.empty((C, len(names)))
                for c, cam in enumerate(cams):
                    muv[c], mz[c] = cam.project_with_depth(pts3d[k])
                vis = marker_visibility(muv, mz, ras.depth, ras.part, own, occlusion=markers.occlusion)
                boxes = np.full((C, 4), np.nan)
                for c in range(C):
                    rows = np.flatnonzero(masks[c].any(axis=1))
                    if rows.size:
                        cols = np.flatnonzero(masks[c].any(axis=0))
                        boxes[c] = (cols[0], rows[0], cols[-1], rows[-1])
                pos, ids = detect_markers(muv, vis, boxes, (W, H), markers, rng_markers, mstats)
                det_pos.append(pos)
                det_ids.append(ids)
                proj_all[k] = muv
                vis_all[k] = vis
                t0 = tick("markers", t0)
            writer.write_frame(k, image=images, mask=masks)
            t0 = tick("write", t0)
            if measure:
                from swarmpose.features import compute_features, silhouette

                if k in fs_lookup:
                    feats = compute_features(images, backgrounds, cams)
                    sils = feats.silhouettes
                else:
                    feats = None
                    sils = np.stack([silhouette(images[c], backgrounds[c]) for c in range(C)])
                inter = np.logical_and(sils, masks).sum(axis=(1, 2))
                union = np.logical_or(sils, masks).sum(axis=(1, 2))
                iou[k] = np.where(union > 0, inter / np.maximum(union, 1), np.nan)
                t0 = tick("features", t0)
                if feats is not None and fitness is not None:
                    e = fs_lookup[k]
                    f_s, _ = fitness.bind(feats).terms(fs_params[e][None], {"terms": "silhouette"})
                    fs[e] = f_s[0]
                    t0 = tick("fitness", t0)
            if bar is not None:
                bar.update(1)
                if measure and k % 10 == 0:
                    bar.set_postfix(iou_min=f"{np.nanmin(iou[: k + 1]):.3f}")
        marker_data = None
        if names:
            marker_data = MarkerData.from_lists(names, det_pos, det_ids, proj_all, vis_all)
        report_summary = {
            "silhouette_iou": iou_summary(iou) if measure else None,
            "model_fs_at_gt_mean": float(np.nanmean(fs)) if np.isfinite(fs).any() else None,
            "markers": mstats.to_dict() if mstats is not None else None,
        }
        provenance = {
            "generator": "swarmpose.synth",
            "synth_version": SYNTH_VERSION,
            "swarmpose_version": _version(),
            "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
            "clip": {"path": str(clip_path.resolve()), "name": clip.name, "sha256": _sha256(clip_path),
                     "source_frame_rate": source_rate,
                     "frames": T, "fps": float(fps)},
            "seed": seed,
            "settings": {"body": body_settings.to_dict(), "scene": scene.to_dict(), "markers": markers.to_dict(),
                         "rig": "custom" if rig is not None else (rig_settings or RigSettings()).to_dict()},
            "body_parts": obs.describe(),
            "body_scale": obs.scale,
            "report": _finite(report_summary),
        }
        path = writer.finish(backgrounds=backgrounds, frame_times=clip.frame_times[:T],
                             gt_joints=clip.joints[:T], markers=marker_data,
                             world_from_source=clip.world_from_source, source_clip=str(clip_path.resolve()),
                             provenance=provenance, subject_measurements=measurements)
        tick("write", t0)
    except BaseException:
        writer.abort()
        raise
    finally:
        if bar is not None:
            bar.close()
    return SynthReport(path=Path(path), clip=str(clip_path), frames=T, views=C,
                       seconds=time.perf_counter() - t_start, iou=iou, fs=fs, fs_frames=fs_frames,
                       ik_floor_mm=ik_floor, marker_stats=mstats, timings=timings,
                       disk_bytes=_folder_bytes(Path(path)), measurements=measurements)


def _settings_key(fps: float, seed: int, settings: dict[str, Any]) -> str:
    doc = json.dumps({"fps": float(fps), "seed": int(seed), "synth_version": SYNTH_VERSION, **settings},
                     sort_keys=True, default=str)
    return hashlib.sha256(doc.encode()).hexdigest()[:10]


def cached_sequence(
    clip_path: str | os.PathLike[str],
    cache_dir: str | os.PathLike[str] = "cache/sequences",
    fps: float = 60.0,
    seed: int = 0,
    *,
    markers: MarkerSettings | None = None,
    body: BodySettings | None = None,
    scene: SceneSettings | None = None,
    progress: bool = True,
) -> Path:
    """Synthesise a clip once and reuse the folder afterwards.

    The folder name is ``<clip stem>-<fps>fps-s<seed>-<key>`` where ``key`` hashes the clip's bytes,
    the settings and :data:`SYNTH_VERSION`; an existing folder that opens cleanly is reused. The
    sequence is written to a temporary folder and renamed when complete.

    Parameters
    ----------
    clip_path : path-like
    cache_dir : path-like, default "cache/sequences" (relative to the working directory)
    fps : float, default 60
    seed : int, default 0
    markers, body, scene : settings, optional
    progress : bool, default True

    Returns
    -------
    pathlib.Path
        The sequence folder (open it with :func:`swarmpose.io.sequence.open_sequence`).
    """
    clip_path = Path(clip_path)
    if not clip_path.is_file():
        raise DataError(f"{clip_path}: no such clip")
    markers = markers or MarkerSettings()
    body = body or BodySettings()
    scene = scene or SceneSettings()
    settings = {"clip_sha256": _sha256(clip_path), "markers": markers.to_dict(), "body": body.to_dict(),
                "scene": scene.to_dict()}
    key = _settings_key(fps, seed, settings)
    fps_txt = f"{float(fps):g}".replace(".", "p")
    target = Path(cache_dir) / f"{clip_path.stem}-{fps_txt}fps-s{int(seed)}-{key}"
    if (target / "sequence.json").is_file():
        try:
            open_sequence(target).close()
            return target
        except (DataError, ValueError):
            shutil.rmtree(target, ignore_errors=True)  # damaged cache entry: rebuild it
    if target.exists() and not (target / "sequence.json").is_file():
        shutil.rmtree(target)  # an incomplete folder left by someone else
    new_dirs = [d for d in (target.parent, *target.parent.parents) if not d.exists()]  # deepest first
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.parent / f".{target.name}.tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        synthesize(clip_path, tmp, fps=fps, seed=seed, markers=markers, body=body, scene=scene,
                   measure=False, progress=progress)
        try:
            tmp.rename(target)
        except OSError:
            if not (target / "sequence.json").is_file():  # not a concurrent writer's result
                raise
    except BaseException:  # a clip that cannot be synthesised leaves no empty cache folders behind
        shutil.rmtree(tmp, ignore_errors=True)
        for d in new_dirs:
            try:
                d.rmdir()
            except OSError:  # not empty: another clip's cache is there now
                break
        raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return target
