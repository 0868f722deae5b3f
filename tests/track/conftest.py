"""A short synthesised sequence shared by the tracking tests, and a constructed frame of a bent body."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def short_sequence(tmp_path_factory, mocap_dir: Path) -> Path:
    """The first 0.2 s (12 frames at 60 fps) of the walking clip, synthesised once per session."""
    from swarmpose.synth.synthesize import synthesize

    out = tmp_path_factory.mktemp("seq") / "walk12"
    synthesize(mocap_dir / "cmu_16_16_walk.bvh", out, fps=60, seed=0, max_frames=12, measure=False,
               progress=False)
    return out



@pytest.fixture(scope="session")
def bent_body_frame():
    """A maker of constructed frames: ``make(bends)`` gives ``(model, pose, fitness)``, balan31 standing 1 m up with
    the ``bends`` (parameter name: radians), seen by 4 demo cameras at 322 x 242, the silhouette and edge fitness
    bound to that frame."""
    import numpy as np

    from swarmpose.body.model import load_model
    from swarmpose.fitness import make_fitness
    from swarmpose.fitness.scene import demo_cameras, demo_frame

    def make(bends: dict[str, float]):
        model = load_model("balan31")
        pose = model.zero_pose()
        pose[5] = 1000.0
        for name, value in bends.items():
            pose[model.param_index(name)] = value
        frame = demo_frame(model, pose, demo_cameras(4, width=322, height=242), rng=np.random.default_rng(3))
        return model, pose, make_fitness("silhouette_edge", model).bind(frame)

    return make
