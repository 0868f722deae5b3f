"""Fixtures of the render tests: the balan31 model, a 4-camera rig with and without distortion, poses."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.fitness.scene import demo_cameras


@pytest.fixture(scope="session")
def model():
    return load_model("balan31")


@pytest.fixture(scope="session")
def base_pose(model) -> np.ndarray:
    p = model.zero_pose()
    p[5] = 1000.0
    p[model.param_index("l_shoulder_abd")] = 0.3
    p[model.param_index("r_shoulder_abd")] = -0.3
    return p


@pytest.fixture(scope="session")
def rig():
    """Four 644x484 cameras, f = 1000 px, mild radial distortion."""
    return demo_cameras(4)


@pytest.fixture(scope="session")
def pinhole_rig():
    return demo_cameras(4, k1=0.0, k2=0.0)


@pytest.fixture(scope="session")
def poses(model, base_pose) -> np.ndarray:
    """30 poses: the base pose and random ones around it (2 sigma)."""
    rng = np.random.default_rng(7)
    p = base_pose + rng.normal(0.0, 2.0, (30, model.n_params)) * model.sigma
    p[0] = base_pose
    return p
