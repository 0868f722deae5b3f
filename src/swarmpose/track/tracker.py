"""Frame-by-frame tracking: a named optimiser against each frame's fitness (design.md §1, thesis ch. 5).

For every processed frame (the sequence subsampled to the requested rate) the tracker

1. predicts from the previous estimates with the configured motion model (``swarmpose.track.motion``;
   default the thesis's zero velocity, sec. 5.3.2: the swarm starts at N(x̂_{t-1}, Σ) with σ scaled
   by 60/fps; the optimiser registry does the scaling),
2. binds the frame's observation to the fitness (image features or 2D markers),
3. runs the optimiser's stages/layers with the body model's hard priors as constraint, switching the
   fitness options per stage (``opt.fitness_options``),
4. keeps ``opt.best.x`` as the estimate and carries the optimiser's state (the APF particle set,
   Deutscher & Reid eq. 9) to the next frame.

Frame 0 is tracked like the others, from the initial pose (the IK fit of its ground truth, or a given
pose). The thesis takes the ground truth as frame 0's estimate instead (sec. 6.1: "the error of SPPSO at
frame 0 is always zero"); measured on the walk (SPPSO, 5 runs at 60 fps and 100 at 20 fps), frame 0 ends
18 and 29 mm from the truth on average, which adds 0.07 and 0.34 mm to D_mean.

Results are written as the run goes (``progress.npz``, replaced atomically after each frame, with
the generator's state and the carried particle set), so an interrupted run resumes exactly where it
stopped and gives the same result as an uninterrupted one.
"""

from __future__ import annotations

import functools
import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.body.ik import fit_ik
from swarmpose.body.model import BodyModel
from swarmpose.body.priors import HardPriors
from swarmpose.body.spec import Subject, load_spec
from swarmpose.errors import ConfigError, DataError, FormatError
from swarmpose.io.files import load_npz, read_json_object, save_npz
from swarmpose.metrics import joint_acceleration, track_errors, valid_frames
from swarmpose.track.constraint import PriorsConstraint
from swarmpose.track.ensemble import Ensemble
from swarmpose.track.feature_store import FeatureStore
from swarmpose.track.lean import LeanSearch, require_lean_parameters
from swarmpose.track.motion import parse_motion
from swarmpose.track.observation import IMAGE_FITNESS, MARKER_FITNESS, Prefetcher, frame_observation
from swarmpose.track.path import DEFAULT_PATH_WEIGHT, best_path, check_weight
from swarmpose.track.progress import RunProgress
from swarmpose.track.provenance import (
    file_identity,
    ground_truth_identity,
    model_identity,
    observation_identity,
    sequence_identity,
    sequence_location,
    versions,
)
from swarmpose.track.recovery import LIMBS, Recovery
from swarmpose.track.smooth import smooth_params
from swarmpose.track.start import (
    elbow_fraction,
    has_keypoints,
    keypoint_joints,
    keypoint_start,
    silhouette_centre,
    silhouette_start,
    tracked_views,
)
from swarmpose.track.step import FrameSearch, backward_pass
from swarmpose.track.timing import PartTimer, TimedFitness
from swarmpose.track.turn import TurnSearch

LIMB_NAMES = tuple(LIMBS)

__all__ = ["TrackConfig", "RunResult", "prepare_track", "run_tracker", "TrackSetup", "versions", "model_identity",
           "sequence_identity", "sequence_location", "ground_truth_identity", "observation_identity", "tracker_priors"]



@dataclass(frozen=True)
class TrackConfig:
    """Everything that defines a tracking run except the run index.

    ``fitness="auto"`` picks silhouette + edge (thesis) for the image trackers and, for the AAPSO
    family, the symmetric robust reprojection fitness on the 2D markers rather than Sharifi et al.'s
    epipolar score (``fitness="markers"``, used by the ``markers`` suite to reproduce the paper): on
    the synthetic walk at 25 fps it tracks to 15 mm instead of 80 mm, because the paper's score is flat
    within ``rho`` = 5 px of a detection (30-55 mm at HumanEva-like image scales) and lets two model
    points share one detection (README, "Marker tracking"). ``budget`` is informational: it is the
    optimiser's evaluations per frame and is checked, never changed, here.
    """

    algo: str = "sppso"
    fps: float = 20.0
    model: str = "balan31"
    variant: str | None = "thesis"
    fitness: str = "auto"
    backend: str = "numba"
    downsample: int = 1
    seed: int = 0
    start: str = "ik"  # "ik": IK fit of the first processed frame's ground truth
    optim_variant: str = ""  # see swarmpose.optim.variants.apply_variant
    fitness_options: str = ""  # "key=value,..." merged over each stage's options
    feature_options: str = ""  # "edge_threshold=8,..." (swarmpose.features.parse_feature_options)
    motion: str = "auto"  # the algorithm's (optim.registry.default_motion), "zero-velocity" or
    #                       "constant-velocity[:D][@GROUP+...]" (swarmpose.track.motion)
    max_frames: int | None = None  # only the first N frames at this rate (a quick try); None: all
    subject: str = ""  # a subject file (swarmpose subject) instead of the sequence's own
    height_mm: float | None = None  # or a subject from this stature (body.anthropometry)
    views: str = ""  # "cam01,cam02": track with these cameras only (the others held out for scoring); "" all
    backward: bool = False  # offline: track the frames again backwards (track.step), each frame's pose from either pass
    backward_path: float = DEFAULT_PATH_WEIGHT  # with backward: the two passes' poses chosen as one path over the
    #                                             frames, this weight on the joints' steps (track.path); 0: per frame
    smooth: float = 0.0  # offline: smooth the poses over time, Gaussian sigma in seconds (track.smooth); 0 off

    def __post_init__(self) -> None:
        if not self.fps > 0:
            raise ConfigError(f"fps must be positive, got {self.fps}")
        if self.max_frames is not None:
            n = self.max_frames
            if (isinstance(n, bool) or not isinstance(n, int | float | np.integer) or not np.isfinite(n) or n < 1
                    or int(n) != n):
                raise ConfigError(f"max_frames must be a whole number >= 1 (or None for all), got {n!r}")
            object.__setattr__(self, "max_frames", int(n))
        if self.subject and self.height_mm is not None:
            raise ConfigError("give a subject file or a height, not both")
        check_weight(self.backward_path, "backward_path")
        if isinstance(self.smooth, bool) or not (np.isfinite(self.smooth) and 0.0 <= self.smooth <= 10.0):
            raise ConfigError(f"smooth must be a time in seconds, 0 (off) to 10, got {self.smooth!r}")
        if self.height_mm is not None:
            from swarmpose.body.anthropometry import standing_joints15

            standing_joints15(self.height_mm)  # the range check, now
        if self.subject and not Path(self.subject).is_file():
            raise ConfigError(f"subject file {self.subject} does not exist (write one with `swarmpose subject`)")
        if self.downsample not in (1, 2, 4, 8):
            raise ConfigError(f"downsample must be 1, 2, 4 or 8, got {self.downsample}")
        if self.fitness not in ("auto", *IMAGE_FITNESS, *MARKER_FITNESS):
            raise ConfigError(f"unknown fitness {self.fitness!r}; known: auto, "
                              f"{', '.join(IMAGE_FITNESS + MARKER_FITNESS)}")
        from swarmpose.features import parse_feature_options
        from swarmpose.fitness.base import parse_fitness_options

        # fail early, before anything is written: options, features and backend for this fitness
        options = parse_fitness_options(self.fitness_options)
        parse_feature_options(self.feature_options)
        from swarmpose.fitness import BACKENDS
        from swarmpose.fitness.base import ImageOptions, parse_image_options

        if self.fitness_kind in IMAGE_FITNESS:
            if options.get("keypoint_elbow") == "auto":  # a number once the track has measured its sequence
                options = {**options, "keypoint_elbow": 1.0}
            parse_image_options(options, ImageOptions())
            known = tuple(BACKENDS)
        else:
            if options:
                raise ConfigError(f"fitness options {self.fitness_options!r} apply to the image fitnesses "
                                  f"({', '.join(IMAGE_FITNESS)}), not to the {self.fitness_kind} fitness")
            known = ("numba", "reference")
        if self.backend not in known:
            raise ConfigError(f"unknown fitness backend {self.backend!r} for the {self.fitness_kind} fitness "
                              f"(known: {', '.join(known)})")
        if self.backend == "torch":
            from swarmpose.fitness.torch_backend import import_torch

            import_torch()  # the install hint now, not in a worker
        if self.motion == "auto":
            from swarmpose.optim.registry import default_motion

            object.__setattr__(self, "motion", default_motion(self.algo))
        # canonical text, so that "constant-velocity" and "constant-velocity:1" resume each other
        object.__setattr__(self, "motion", str(parse_motion(self.motion)))

    def optimizer(self, model: BodyModel):
        """The named optimiser configuration for ``model`` at this frame rate, variant applied."""
        from swarmpose import optim
        from swarmpose.optim.variants import apply_variant

        return apply_variant(optim.get(self.algo, model=model, fps=self.fps), self.optim_variant)

    @property
    def fitness_kind(self) -> str:
        if self.fitness != "auto":
            return self.fitness
        from swarmpose.optim.registry import default_fitness

        return default_fitness(self.algo)


def run_seed(seed: int, run: int) -> np.random.SeedSequence:
    """Run ``k``'s generator is derived from the user's seed and ``k`` (recorded in the results)."""
    return np.random.SeedSequence([int(seed), int(run)])


@dataclass
class TrackSetup:
    """What every run of one (sequence, config) shares: model, frames, ground truth, IK floor."""

    sequence_path: Path
    config: TrackConfig
    model: BodyModel
    frame_indices: np.ndarray
    frame_times: np.ndarray
    gt_joints: np.ndarray  # (T, 15, 3); NaN rows where the ground truth is invalid (HumanEva)
    ik_params: np.ndarray
    ik_error_mm: np.ndarray
    world_from_source: np.ndarray
    evals_per_frame: int
    search_start: bool = False  # frame 0 searched over headings (a start from the silhouettes alone)

    @property
    def progress_frames(self) -> int:
        """Frames a run reports progress over: twice the tracked frames, less one, with the backward pass."""
        T = len(self.frame_indices)
        return 2 * T - 1 if self.config.backward and T > 1 else T

    @property
    def valid(self) -> np.ndarray:
        """``(T,)`` frames whose ground truth is finite: errors and the IK floor use only these."""
        return valid_frames(self.gt_joints)

    @property
    def has_ground_truth(self) -> bool:
        """Whether any tracked frame has ground truth to score against."""
        return bool(self.valid.any())

    @property
    def ik_floor_mm(self) -> float | None:
        """The IK floor (mm) over the valid frames; None without ground truth."""
        if not self.has_ground_truth:
            return None
        return float(np.nanmean(self.ik_error_mm[self.valid].mean(axis=1)))


def _subject_for(seq: Any, spec, config: TrackConfig | None = None, keypoints: np.ndarray | None = None) -> Subject:
    """The subject: the file ``config`` names; else, for a sequence without ground truth, limbs measured from
    the joints triangulated from its ``keypoints`` (medians over frames; each arm's length split by Winter's
    proportion, :func:`~swarmpose.body.anthropometry.split_arms`), with cones from the stature
    ``config`` names when it names one; else the stature alone; else from the source BVH skeleton when there
    is one, else from the 15-joint ground truth.

    Cones come from the sequence's subject measurements when it has them (HumanEva's rules).
    """
    from swarmpose.body.subject import subject_from_joints

    if config is not None and config.subject:
        return Subject.load(config.subject)
    if keypoints is not None and seq.gt_joints is None:
        from swarmpose.body.anthropometry import split_arms

        subj = split_arms(subject_from_joints(spec, keypoints, name=str(getattr(seq, "path", "subject")),
                                              measurements=getattr(seq, "subject_measurements", None), robust=True,
                                              source="joints triangulated from the detector's keypoints, medians"))
        if config is not None and config.height_mm is not None:
            from dataclasses import replace

            from swarmpose.body.anthropometry import subject_from_height

            tall = subject_from_height(spec, config.height_mm, measurements=getattr(seq, "subject_measurements", None))
            subj = replace(subj, cones=tall.cones, source=f"{subj.source}; cones from a stature of "
                                                          f"{config.height_mm:g} mm")
        return subj
    if config is not None and config.height_mm is not None:
        from swarmpose.body.anthropometry import subject_from_height

        return subject_from_height(spec, config.height_mm,
                                   measurements=getattr(seq, "subject_measurements", None))
    from swarmpose.io.mocap import load_clip, subject_from_clip

    measurements = getattr(seq, "subject_measurements", None)
    clip_path = getattr(seq, "source_clip", None)
    if clip_path is not None and Path(clip_path).is_file():
        return subject_from_clip(spec, load_clip(clip_path), measurements)
    if seq.gt_joints is None:
        raise DataError(f"{getattr(seq, 'path', 'the sequence')}: no ground truth and no keypoints to measure the "
                        "subject from: pass --height MM (or --subject FILE)")
    return subject_from_joints(spec, np.asarray(seq.gt_joints), name=str(getattr(seq, "path", "subject")),
                               measurements=measurements)


def _ik_cache_key(sequence_path: str | Path, config: TrackConfig) -> str:
    """What the cached IK fit (``ik.npz``) and ``subject.json`` of a results folder depend on."""
    return json.dumps({"sequence": sequence_identity(sequence_path), "model": config.model,
                       "model_spec_sha1": model_identity(config.model), "variant": config.variant,
                       "fps": config.fps, "ik": "smooth start, polished floor",
                       **({"subject": file_identity(Path(config.subject))} if config.subject else {}),
                       **({"height_mm": config.height_mm} if config.height_mm is not None else {}),
                       **({"views": config.views} if config.views else {})},
                      sort_keys=True)


def _read_ik_cache(out_dir: Path | None, key: str, frames: np.ndarray, n_params: int):
    """``(params, joint_error_mm)`` of ``out_dir/ik.npz`` when it was fitted for this sequence, model and
    frame rate, else ``None`` (a folder reused with other settings is fitted afresh, never misread)."""
    ik_file = None if out_dir is None else out_dir / "ik.npz"
    if ik_file is None or not ik_file.is_file() or not (out_dir / "subject.json").is_file():
        return None
    try:
        z = load_npz(ik_file, ("params", "joint_error_mm"))
    except FormatError:
        return None  # a damaged cache is refitted, not trusted
    if "key" in z and str(z["key"]) != key:
        return None
    # folders written before the key existed: the frames and the parameter count must still agree
    if "frame_indices" in z and not np.array_equal(z["frame_indices"], frames):
        return None
    if z["params"].shape != (len(frames), n_params):
        return None
    return z["params"], z["joint_error_mm"]


def prepare_track(sequence_path: str | Path, config: TrackConfig, out_dir: Path | None = None) -> TrackSetup:
    """Load the sequence's metadata, build the subject's model and fit the IK floor (cached in out_dir).

    The optimiser configuration is built (unknown algorithm, bad ``--variant``) before anything is
    written. ``out_dir/ik.npz`` and ``subject.json`` are reused only when they were made for the same
    sequence, body model and frame rate.
    """
    from swarmpose.io.sequence import open_sequence

    seq = open_sequence(sequence_path)
    try:
        spec = load_spec(config.model)
        view_idx = tracked_views(seq, config.views)
        frames = np.asarray(seq.subsample(config.fps), dtype=np.int64)[:config.max_frames]
        if config.fitness_kind in MARKER_FITNESS and seq.markers(int(frames[0])) is None:
            from swarmpose.datasets import is_dataset_spec

            hint = "" if is_dataset_spec(sequence_path) else " (synthesise it with `swarmpose synth --markers joints15`)"
            raise DataError(f"{sequence_path}: the sequence has no 2D marker detections, which the "
                            f"{config.fitness_kind} fitness needs{hint}")
        has_gt = seq.gt_joints is not None
        gt = np.asarray(seq.gt_joints)[frames] if has_gt else np.full((len(frames), 15, 3), np.nan)
        kp_joints = None
        centre = None  # without ground truth and keypoints: the silhouettes' centre
        if not has_gt and not has_keypoints(seq):
            if not (config.height_mm or config.subject):
                raise DataError(f"{sequence_path}: the sequence has no ground truth and no body keypoints: pass "
                                "--height MM (or --subject FILE) to start from the silhouettes, or import the "
                                "recording with the detector (`swarmpose import`, without --no-detect)")
            centre = silhouette_centre(seq, int(frames[0]), view_idx)
            if centre is None:
                raise DataError(f"{sequence_path}: frame {int(frames[0])}: fewer than two tracked cameras see a "
                                "silhouette to start from")
        elif not has_gt:
            kp_joints = keypoint_joints(seq, frames, views=view_idx)
            if not np.isfinite(kp_joints).all(axis=(1, 2)).any():
                raise DataError(f"{sequence_path}: no tracked frame has every joint seen by two of the tracked cameras "
                                f"({', '.join(seq.view_names[i] for i in view_idx)}); track with more cameras (--views)")
        times = np.asarray(seq.frame_times)[frames]
        key = _ik_cache_key(sequence_path, config)
        cached = _read_ik_cache(out_dir, key, frames, len(spec.parameters))
        subject = (Subject.load(out_dir / "subject.json") if cached is not None
                   else _subject_for(seq, spec, config, kp_joints))
        model = BodyModel(spec, subject, config.variant)
        parse_motion(config.motion).mask(model)  # unknown parameter groups fail here, before any run
        algo = config.optimizer(model)  # unknown algorithm or variant: before the IK fit is written
        if getattr(algo, "lean_search", None):  # a model without the lean's parameters: refused here, not in a worker
            require_lean_parameters(model)
        from swarmpose.fitness.base import parse_fitness_options

        cones = parse_fitness_options(config.fitness_options).get("edge_cones")
        if cones is not None:
            from swarmpose.render import edge_cone_mask

            edge_cone_mask(model.cone_arrays.names, cones)  # an unknown cone set fails here, not in a worker
        if cached is not None:
            ik_params, ik_err = cached
        elif not has_gt:
            if centre is not None:
                ik_params = np.full((len(frames), model.n_params), np.nan)
                ik_params[0] = silhouette_start(model, centre)
                ik_err, floor_params = np.full((len(frames), 15), np.nan), ik_params.copy()
            else:
                ik_params, ik_err, floor_params = keypoint_start(model, kp_joints, sequence_path, int(frames[0]))
            if out_dir is not None:
                out_dir.mkdir(parents=True, exist_ok=True)
                subject.save(out_dir / "subject.json")
                save_npz(out_dir / "ik.npz", params=ik_params, joint_error_mm=ik_err, floor_params=floor_params,
                              frame_indices=frames, key=np.array(key))
        else:
            valid = valid_frames(gt)
            if not valid[0]:
                raise DataError(f"{sequence_path}: the ground truth of the first tracked frame "
                                f"({int(frames[0])}) is invalid; the start pose comes from it")
            ik = fit_ik(model, gt[valid])
            ik_params = np.full((len(gt), model.n_params), np.nan)
            floor_params = np.full((len(gt), model.n_params), np.nan)
            ik_err = np.full((len(gt), 15), np.nan)
            ik_params[valid], ik_err[valid], floor_params[valid] = ik.params, ik.joint_error_mm, ik.floor_params
            if out_dir is not None:
                out_dir.mkdir(parents=True, exist_ok=True)
                subject.save(out_dir / "subject.json")
                save_npz(out_dir / "ik.npz", params=ik_params, joint_error_mm=ik_err, floor_params=floor_params,
                              frame_indices=frames, key=np.array(key))
        return TrackSetup(sequence_path=Path(sequence_path), config=config, model=model, frame_indices=frames,
                          frame_times=times, gt_joints=gt, ik_params=ik_params, ik_error_mm=ik_err,
                          world_from_source=np.asarray(seq.world_from_source, dtype=np.float64),
                          evals_per_frame=int(algo.evals_per_frame),
                          search_start=centre is not None)
    finally:
        seq.close()


#: The error measures of a run's summary (:class:`swarmpose.metrics.TrackErrors`), null without ground truth.
ERROR_KEYS = ("d_mean", "d_max", "d_std", "mmta", "mmtp", "mu", "sigma")


@dataclass
class RunResult:
    run: int
    params: np.ndarray
    joints: np.ndarray
    scores: np.ndarray
    evaluations: np.ndarray
    seconds: np.ndarray
    errors: dict[str, Any] = field(default_factory=dict)
    recovered: np.ndarray | None = None  # (T, limbs) bool: frames where a lost limb was searched again and kept
    part_seconds: dict[str, float] = field(default_factory=dict)  # this session's wall time per part (timing.PARTS)
    passes: dict[str, np.ndarray] | None = None  # with the backward pass: each pass's poses and scores, and
    #                                              which frames kept the backward pass's pose (backward_kept)
    #                                              or limbs of both passes (backward_mixed), and which kept the
    #                                              forward pose for the path's sake (backward_path_forward);
    #                                              with smoothing: the poses before it (raw_params)
    feature_store: dict[str, Any] | None = None  # the feature store's folder, frames read from it and computed

    @property
    def recoveries(self) -> dict[str, int]:
        """Frames on which each limb was found lost and searched again with success."""
        r = np.zeros((0, len(LIMB_NAMES)), bool) if self.recovered is None else self.recovered
        return {limb: int(r[:, j].sum()) for j, limb in enumerate(LIMB_NAMES)}

    @property
    def frames_per_s(self) -> float:
        return float(len(self.seconds) / max(self.seconds.sum(), 1e-12))


def tracker_priors(model: Any, algo: Any) -> HardPriors:
    """The hard priors a run of ``algo`` tracks under: the model's limits and collisions, and its coupled limits where
    the configuration asks for them (``coupled_limits``: the default tracker)."""
    return HardPriors(model, coupled_limits=bool(getattr(algo, "coupled_limits", False)))


def _make_fitness(setup: TrackSetup):
    from swarmpose.fitness import make_fitness

    return make_fitness(setup.config.fitness_kind, setup.model, backend=setup.config.backend)


def _one_blas_thread(func: Callable[..., Any]) -> Callable[..., Any]:
    """Run ``func`` with the linear algebra (BLAS) on one thread: the tracker's products are small (the APF's
    diffusion, 200 x 200 by 200 x 31), and BLAS's own threads, waiting between them, took the cores from the
    fitness's threads and from a second run (the results are the same to the last digit)."""

    @functools.wraps(func)
    def limited(*args: Any, **kwargs: Any) -> Any:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return func(*args, **kwargs)

    return limited


@_one_blas_thread
def run_tracker(
    setup: TrackSetup,
    run: int,
    out_dir: Path | None = None,
    *,
    resume: bool = False,
    progress: Callable[[int, int], None] | None = None,
    stop_after: int | None = None,
    observe: Callable[[int, Any], Any] | None = None,
    feature_cache: str | os.PathLike[str] | None = None,
) -> RunResult:
    """Track one run (``run`` selects the generator) and write ``out_dir/run_XXX/``, BLAS on one thread.

    ``stop_after`` ends the run after that many frames (used to test resuming; the progress file
    stays and ``resume=True`` continues from it). ``observe(k, observation)``, when given, receives
    each frame's observation (sequence frame ``k``) and returns the one to track against: the
    diagnostics in ``scripts/diagnose_tracking.py oracle`` use it to swap in ideal silhouettes or edges.
    ``feature_cache``: the folder of the feature stores (:mod:`swarmpose.track.feature_store`): frames another
    run has computed are read from it, the others computed and kept there (the results are the same); None:
    every frame computed.
    With ``config.backward`` the whole forward pass is followed by :func:`swarmpose.track.step.backward_pass`
    (its own generator, spawned from the run's seed), and each frame's pose is the forward pass's or the backward
    pass's as :func:`swarmpose.track.path.best_path` chooses (``config.backward_path``); ``RunResult.passes`` keeps
    both passes. A configuration
    with ``members > 1`` tracks the forward pass with an :class:`~swarmpose.track.ensemble.Ensemble` (the first
    member on the run's generator, the others on generators spawned from the run's seed after the backward pass's);
    the backward pass is one search.
    """
    from swarmpose import optim
    from swarmpose.features import parse_feature_options
    from swarmpose.fitness.base import parse_fitness_options
    from swarmpose.io.sequence import open_sequence

    cfg = setup.config
    model = setup.model
    algo = cfg.optimizer(model)
    recovery = Recovery.from_settings(getattr(algo, "recovery", {}))
    if recovery is not None and cfg.fitness_kind not in IMAGE_FITNESS:
        recovery = None  # loss detection reads the silhouettes
    motion = parse_motion(cfg.motion)
    motion_mask = motion.mask(model)
    extra_options = parse_fitness_options(cfg.fitness_options)
    if cfg.fitness_kind in IMAGE_FITNESS and getattr(algo, "frame_options", None):
        extra_options = {**algo.frame_options, **extra_options}  # the configuration's, under the run's own
    feature_options = parse_feature_options(cfg.feature_options)
    timer = PartTimer()
    constraint = PriorsConstraint(tracker_priors(model, algo), timer)  # timed as "priors"; PSO moves compiled
    untimed_fitness = _make_fitness(setup)
    fitness = TimedFitness(untimed_fitness, timer)
    T, D = len(setup.frame_indices), model.n_params

    params = np.zeros((T, D))
    scores = np.zeros(T)
    evals = np.zeros(T, dtype=np.int64)
    seconds = np.zeros(T)
    recovered = np.zeros((T, len(LIMB_NAMES)), dtype=bool)
    rng = np.random.default_rng(run_seed(cfg.seed, run))
    x_prev = setup.ik_params[0].copy() if cfg.start == "ik" else model.zero_pose()
    carry = None
    start_k = 0
    run_dir = None if out_dir is None else out_dir / f"run_{run:03d}"
    store = None if run_dir is None else RunProgress(run_dir, T, D, len(LIMB_NAMES), run=run)
    state = None
    if store is not None:
        run_dir.mkdir(parents=True, exist_ok=True)
        if store.exists():
            if not resume:
                raise ConfigError(f"{store.state_file} exists: pass --resume to continue it, or use a new --out")
            state = store.load()
            start_k = state.done
            params[:start_k], scores[:start_k] = state.params, state.scores
            evals[:start_k], seconds[:start_k] = state.evaluations, state.seconds
            recovered[:start_k] = state.recovered
            x_prev = state.x_prev
            rng.bit_generator.state = state.rng_state
            if state.carry is not None:
                carry = optim.ParticleSet(*state.carry)
        store.start(state)

    seq = open_sequence(setup.sequence_path)
    views = tracked_views(seq, cfg.views)
    backgrounds = seq.backgrounds() if cfg.fitness_kind in IMAGE_FITNESS else None
    keypoints = seq.marker_data.to_dense() if cfg.fitness_kind in IMAGE_FITNESS and has_keypoints(seq) else None
    kp_joints = None  # the tracked views' triangulated keypoints, for the configurations that fit them per frame
    fit_keypoints = bool(getattr(algo, "keypoint_ik", False))
    proposals = float(getattr(algo, "keypoint_proposals", 0.0))
    keypoint_height = bool(getattr(algo, "keypoint_height", False))
    if (fit_keypoints or proposals > 0 or keypoint_height) and has_keypoints(seq):
        kp_joints = keypoint_joints(seq, setup.frame_indices, views=views)
    elbow = None  # keypoint_elbow=auto: the detector's elbows on the model's upper arms, measured on this sequence
    if extra_options.get("keypoint_elbow") == "auto":
        if keypoints is None:
            del extra_options["keypoint_elbow"]
        else:
            joints = kp_joints if kp_joints is not None else keypoint_joints(seq, setup.frame_indices, views=views)
            elbow = extra_options["keypoint_elbow"] = elbow_fraction(model, joints)

    features_store = None
    if feature_cache is not None and cfg.fitness_kind in IMAGE_FITNESS:
        cams = [seq.cameras[c] for c in views]
        try:
            features_store = FeatureStore.for_sequence(feature_cache, setup.sequence_path, [c.name for c in cams],
                                                       feature_options, (len(cams), cams[0].height, cams[0].width))
        except BaseException:  # a store folder that cannot be written: the error, with the sequence closed
            seq.close()
            raise

    # an image fitness's per-frame preparation (the silhouettes' row prefix sums) runs on the prefetch thread too,
    # unless the observation is handed to `observe` first
    prepare = getattr(untimed_fitness, "prepare", None) if observe is None and cfg.fitness_kind in IMAGE_FITNESS else None

    def load(i: int) -> Any:  # on the prefetch thread: frame i + 1 is read while frame i is tracked
        obs = frame_observation(seq, int(setup.frame_indices[i]), cfg.fitness_kind, cfg.downsample, backgrounds,
                                feature_options, views, keypoints, features_store)
        return obs if prepare is None else prepare(obs)

    prefetch = Prefetcher(load, T if stop_after is None else min(T, stop_after))
    search = FrameSearch(model=model, algo=algo, fitness=fitness, motion=motion, motion_mask=motion_mask,
                         constraint=constraint, timer=timer, extra_options=extra_options, recovery=recovery,
                         kp_joints=kp_joints, search_start=setup.search_start,
                         silhouette_height=bool(getattr(algo, "silhouette_height", False))
                         and cfg.fitness_kind in IMAGE_FITNESS,
                         keypoint_height=keypoint_height,
                         turn=TurnSearch.from_settings(getattr(algo, "turn_search", {}))
                         if cfg.fitness_kind in IMAGE_FITNESS else None,
                         lean=LeanSearch.from_settings(getattr(algo, "lean_search", {}))
                         if cfg.fitness_kind in IMAGE_FITNESS else None,
                         heading_speed=getattr(algo, "heading_speed", None), keypoint_ik=fit_keypoints,
                         keypoint_ik_polish=int(getattr(algo, "keypoint_ik_polish", 0)), keypoint_proposals=proposals,
                         head_search=int(getattr(algo, "head_search", 0)) if keypoints is not None else 0)
    ensemble = None
    if int(getattr(algo, "members", 1)) > 1:  # members side by side; the first uses the run's generator
        children = run_seed(cfg.seed, run).spawn(int(algo.members))  # child 0 is the backward pass's
        ensemble = Ensemble(search, [rng] + [np.random.default_rng(c) for c in children[1:]], x_prev,
                            float(algo.members_reset))
    try:
        if ensemble is not None and state is not None and start_k > 0:
            try:
                ensemble.restore(state.extra)
            except (KeyError, ValueError) as exc:
                raise FormatError(f"its members' state does not fit this run ({exc}); delete it to track run "
                                  f"{run} afresh", path=store.state_file) from None
        if search.silhouette_height and start_k > 0:  # a resumed run: the rise into its first frame as in one run
            (ensemble or search).note_centre(start_k - 1, load(start_k - 1))
        for i in range(start_k, T):
            if stop_after is not None and i >= stop_after:
                break
            t0 = time.perf_counter()
            k = int(setup.frame_indices[i])
            with timer.part("features"):
                observation = prefetch.get(i)
            fitness.bind(observation if observe is None else observe(k, observation))
            if i == start_k:  # compile the fitness kernels (numba: seconds on a fresh install) off the clock,
                tw = time.perf_counter()  # so that frames/s is the tracking speed; the score is not used
                untimed_fitness.evaluate(x_prev[None])
                t0 += time.perf_counter() - tw
            if ensemble is None:
                res = search.step(i, params[:i] if i >= 2 else x_prev[None], x_prev, carry, rng, first=i == 0)
            else:
                res = ensemble.step(i, first=i == 0)
            x_prev, score, n_evals, carry = res.x, res.score, res.evaluations, res.carry
            for limb in res.recovered:
                recovered[i, LIMB_NAMES.index(limb)] = True
            params[i], scores[i], evals[i] = x_prev, score, n_evals
            seconds[i] = time.perf_counter() - t0
            if store is not None:
                with timer.part("writing"):
                    store.save(i, params=params[i], score=scores[i], evaluations=evals[i], seconds=seconds[i],
                               recovered=recovered[i], x_prev=x_prev, rng_state=rng.bit_generator.state,
                               carry=None if carry is None else (carry.particles, carry.weights),
                               extra=None if ensemble is None else ensemble.state())
            if progress is not None:
                progress(i + 1, setup.progress_frames)
        passes = None
        if cfg.backward and stop_after is None and np.count_nonzero(evals) == T and T > 1:
            prefetch.close()
            back = Prefetcher(lambda j: load(T - 1 - j), T)

            def bind(j: int) -> None:
                with timer.part("features"):
                    obs = back.get(T - 1 - j)
                fitness.bind(obs if observe is None else observe(int(setup.frame_indices[j]), obs))

            try:
                b = backward_pass(search, params, bind, np.random.default_rng(run_seed(cfg.seed, run).spawn(1)[0]),
                                  None if progress is None else lambda d, _n: progress(T + d, setup.progress_frames))
            finally:
                back.close()
            back_scores = np.where(np.isnan(b.scores), scores, b.scores)
            take = best_path(np.stack([scores, back_scores], axis=1),
                             np.stack([model.joints15(params), model.joints15(b.params)], axis=1),
                             cfg.backward_path) == 1
            passes = {"forward_params": params, "forward_scores": scores, "backward_params": b.params,
                      "backward_scores": back_scores, "backward_kept": b.backward & take,
                      "backward_mixed": b.mixed & take, "backward_path_forward": (b.backward | b.mixed) & ~take}
            params, scores = np.where(take[:, None], b.params, params), np.where(take, back_scores, scores)
            evals, seconds = evals + b.evaluations, seconds + b.seconds
            recovered = recovered | (b.recovered & take[:, None])
    finally:
        prefetch.close()
        seq.close()
        if store is not None:
            store.close()

    done = int(np.count_nonzero(evals))
    if cfg.smooth and done == T:  # offline: the whole track smoothed over time; the raw poses are kept
        passes = {**(passes or {}), "raw_params": params}
        params = smooth_params(params, setup.frame_times, cfg.smooth, model.is_rotation, model.lower, model.upper)
    joints = model.joints15(params[:done]) if done else np.zeros((0, 15, 3))
    result = RunResult(run=run, params=params[:done], joints=joints, scores=scores[:done],
                       evaluations=evals[:done], seconds=seconds[:done], recovered=recovered[:done],
                       part_seconds={k: round(v, 6) for k, v in timer.seconds.items()}, passes=passes,
                       feature_store=None if features_store is None else
                       {"folder": str(features_store.folder), "read": features_store.read,
                        "computed": features_store.computed})
    if done == T:
        if setup.has_ground_truth:
            errs = track_errors(joints, setup.gt_joints)  # frames without valid ground truth are not scored
            d_all, error_fields = errs.d_per_frame, errs.summary()
        else:  # nothing to score: the measures are absent (null), not zero
            d_all, error_fields = np.full(T, np.nan), {k: None for k in (*ERROR_KEYS, "per_joint")}
        result.errors = {**error_fields, "ground_truth": setup.has_ground_truth, "frames_per_s": result.frames_per_s,
                         "evals_per_frame": int(evals.max()), "ik_floor_mm": setup.ik_floor_mm,
                         "recoveries": result.recoveries, "part_seconds": result.part_seconds,
                         "frames_timed": int(done - start_k), "feature_store": result.feature_store,
                         "acceleration_mm_s2": joint_acceleration(joints, setup.frame_times),
                         "gt_acceleration_mm_s2": (joint_acceleration(setup.gt_joints, setup.frame_times)
                                                   if setup.has_ground_truth else None)}
        if elbow is not None:
            result.errors["keypoint_elbow"] = elbow
        if ensemble is not None:
            result.errors["member_resets"] = ensemble.resets.tolist()
        if passes is not None and "backward_kept" in passes:
            result.errors["backward_kept"] = int(passes["backward_kept"].sum())
            result.errors["backward_mixed"] = int(passes["backward_mixed"].sum())
            result.errors["backward_path_forward"] = int(passes["backward_path_forward"].sum())
        if run_dir is not None:
            _write_run(run_dir, setup, result, d_all)
    return result


def _write_run(run_dir: Path, setup: TrackSetup, result: RunResult, d_per_frame: np.ndarray) -> None:
    from swarmpose.io.jsonable import to_jsonable

    save_npz(run_dir / "track.npz", params=result.params, joints=result.joints, scores=result.scores,
                  evaluations=result.evaluations, seconds=result.seconds, frame_indices=setup.frame_indices,
                  d_per_frame=d_per_frame, param_names=np.array(setup.model.param_names),
                  recovered=result.recovered, limbs=np.array(LIMB_NAMES), **(result.passes or {}))
    save_npz(run_dir / "joints.npz", joints=result.joints, gt_joints=setup.gt_joints,
                  frame_times=setup.frame_times,
                  world_from_source=setup.world_from_source)
    (run_dir / "summary.json").write_text(json.dumps(to_jsonable({"run": result.run, **result.errors}),
                                                     indent=1) + "\n")


def write_config(out_dir: Path, setup: TrackSetup, runs: int, resume: bool = False) -> None:
    """Write ``out_dir/config.json``. On a resume the first session's ``created`` is kept and each earlier
    session's time, versions, sequence path and runs are appended to ``sessions``, so that a folder tracked
    in several sessions (maybe by different code or from a moved sequence) says so."""
    record = config_record(setup, runs)
    old_file = out_dir / "config.json"
    if resume and old_file.is_file():
        try:
            old = read_json_object(old_file)
        except (FormatError, OSError):
            old = {}
        if old:
            earlier = old.get("sessions") if isinstance(old.get("sessions"), list) else []
            record["sessions"] = [*earlier,
                                  {k: old.get(k) for k in ("created", "versions", "sequence", "runs")}]
            record["created"] = old.get("created", record["created"])
            record["resumed"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    (out_dir / "config.json").write_text(json.dumps(record, indent=1) + "\n")


def config_record(setup: TrackSetup, runs: int) -> dict[str, Any]:
    """What ``config.json`` holds: the configuration, seeds, budget and versions."""
    return {
        **asdict(setup.config),
        "fitness_kind": setup.config.fitness_kind,
        "runs": runs,
        "run_seeds": {str(k): [setup.config.seed, k] for k in range(runs)},
        "sequence": sequence_location(setup.sequence_path),
        "sequence_identity": sequence_identity(setup.sequence_path),
        "ground_truth_sha1": ground_truth_identity(setup.gt_joints),
        "observations_sha1": observation_identity(setup.sequence_path),
        "model_spec_sha1": model_identity(setup.config.model),
        "frames": int(len(setup.frame_indices)),
        "evals_per_frame": setup.evals_per_frame,
        "ik_floor_mm": setup.ik_floor_mm,
        "versions": versions(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
