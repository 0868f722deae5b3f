"""Fixtures of the fitness tests: model, demo scenes, and a synthesised walking frame with its IK poses."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.features import FrameFeatures
from swarmpose.fitness.scene import demo_cameras, demo_frame


@pytest.fixture(scope="session")
def model():
    return load_model("balan31")


@pytest.fixture(scope="session")
def true_pose(model) -> np.ndarray:
    p = model.zero_pose()
    p[5] = 1000.0
    p[model.param_index("l_shoulder_abd")] = 0.35
    p[model.param_index("r_shoulder_abd")] = -0.35
    p[model.param_index("l_hip_flex")] = 0.2
    p[model.param_index("r_knee_flex")] = 0.3
    return p


@pytest.fixture(scope="session")
def rig():
    return demo_cameras(4)


@pytest.fixture(scope="session")
def scene(model, true_pose, rig) -> FrameFeatures:
    """Observed: the model with 8 % thicker cones, clutter blobs and sensor noise (644x484)."""
    return demo_frame(model, true_pose, rig, rng=np.random.default_rng(11))


@pytest.fixture(scope="session")
def exact_scene(model, true_pose, rig) -> FrameFeatures:
    """Observed silhouettes = the model's own rendering at ``true_pose``."""
    return demo_frame(model, true_pose, rig, inflate=1.0, clutter=0, noise=0.0)


@pytest.fixture(scope="session")
def candidates(model, true_pose) -> np.ndarray:
    rng = np.random.default_rng(12)
    p = true_pose + rng.normal(0.0, 1.0, (40, model.n_params)) * model.sigma
    p[0] = true_pose
    return p


@dataclass
class WalkFrames:
    model: object
    frames: list[FrameFeatures]
    ik: np.ndarray  # (F, D)
    index: np.ndarray  # frame numbers


WALK_FRAMES = (0, 6, 12, 18, 24)


@pytest.fixture(scope="session")
def walk(walk_clip_path: Path, tmp_path_factory) -> WalkFrames:
    """Five frames of cmu_16_16_walk synthesised by :mod:`swarmpose.synth` (the detailed observation
    body, not the cone model), features by :func:`compute_features`, and the IK poses of the ground
    truth on the clip-fitted balan31 model."""
    synth = pytest.importorskip("swarmpose.synth")
    from swarmpose.body.ik import fit_ik
    from swarmpose.features import compute_features
    from swarmpose.io.mocap import load_clip, subject_from_clip
    from swarmpose.io.sequence import open_sequence

    out = tmp_path_factory.mktemp("walk") / "seq"
    synth.synthesize(walk_clip_path, out, fps=60, seed=1, max_frames=max(WALK_FRAMES) + 1, fs_stride=0,
                     measure=False, progress=False)
    seq = open_sequence(out)
    bgs = seq.backgrounds()
    frames = [compute_features(seq.images(k), bgs, seq.cameras) for k in WALK_FRAMES]
    clip = load_clip(walk_clip_path, fps=60)
    base = load_model("balan31")
    model = base.with_subject(subject_from_clip(base.spec, clip))
    ik = fit_ik(model, clip.joints[list(WALK_FRAMES)]).params
    seq.close()
    return WalkFrames(model=model, frames=frames, ik=ik, index=np.array(WALK_FRAMES))
