"""The head's own search after a frame's searches (``head_search``, ``--variant head=B``)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from swarmpose.body.model import load_model


@pytest.fixture(scope="module")
def scene():
    """The cone model standing in the demo rig, its exact silhouettes and edges, and a fitness bound to them."""
    from swarmpose.fitness import make_fitness
    from swarmpose.fitness.scene import demo_cameras, demo_frame

    model = load_model("balan31")
    truth = model.zero_pose()
    truth[model.param_index("pelvis_tz")] = 950.0
    truth[model.param_index("neck_flex")] = np.radians(20.0)
    fit = make_fitness("silhouette_edge", model)
    fit.bind(demo_frame(model, truth, demo_cameras(4), inflate=1.0, clutter=0, noise=0.0))
    return model, truth, fit


def _search(model, fit, budget: int):
    from swarmpose.body.priors import HardPriors
    from swarmpose.track.step import FrameSearch

    algo = SimpleNamespace(refine_step=0.5, sigma=np.asarray(model.sigma), refine_options={})
    return FrameSearch(model=model, algo=algo, fitness=fit, motion=None, motion_mask=None,
                       constraint=HardPriors(model).valid, timer=None, extra_options={}, head_search=budget)


def test_the_head_search_moves_the_head_alone_towards_the_evidence(scene):
    """A pose right but for its head, bent 25 degrees off: the search moves only the head's parameters, scores
    higher than the pose it started from, and brings the head's top nearer the truth's."""
    model, truth, fit = scene
    x = truth.copy()
    x[model.param_index("neck_flex")] -= np.radians(25.0)
    x[model.param_index("neck_lat")] += np.radians(10.0)
    found = _search(model, fit, 60)._polish(x, 60, None, model.group("head"))
    head = model.group("head")
    others = np.setdiff1d(np.arange(model.n_params), head)
    assert np.array_equal(found.x[others], x[others])
    start = float(fit.evaluate(x[None])[0])
    assert found.score > start
    assert found.score == pytest.approx(float(fit.evaluate(np.asarray(found.x)[None])[0]))
    top = model.joints15(np.stack([x, found.x, truth]))[:, -1]  # head_top
    assert np.linalg.norm(top[1] - top[2]) < 0.5 * np.linalg.norm(top[0] - top[2])
    assert found.evaluations <= 60


def test_the_head_search_keeps_a_pose_it_cannot_better(scene):
    """From the truth, whose head the evidence already fits, the search finds nothing higher and returns the pose
    it was given."""
    model, truth, fit = scene
    found = _search(model, fit, 40)._polish(truth, 40, None, model.group("head"))
    assert np.array_equal(found.x, truth)
    assert found.score == pytest.approx(float(fit.evaluate(truth[None])[0]))
