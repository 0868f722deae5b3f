"""A run's members: the consensus as the frame's pose, the reset of a member that strayed, the members' state
through a resumed run, and the variant that turns them on."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from swarmpose.body.model import load_model
from swarmpose.optim import ParticleSet
from swarmpose.track.consensus import consensus_params
from swarmpose.track.ensemble import Ensemble
from swarmpose.track.step import StepResult
from swarmpose.track.timing import PartTimer

MODEL = load_model("balan31")
#: A pose inside every limit (the zero pose leaves some, which the consensus's fit would then move).
_FINITE = np.isfinite(MODEL.lower) & np.isfinite(MODEL.upper)
_LO, _HI = MODEL.lower[_FINITE], MODEL.upper[_FINITE]
BASE = MODEL.zero_pose()
BASE[_FINITE] = np.clip(BASE[_FINITE], _LO + 0.1 * (_HI - _LO), _HI - 0.1 * (_HI - _LO))


class _Fitness:
    """Scores a pose by how near its parameters lie to zero (the ensemble scores its consensus once)."""

    def __init__(self) -> None:
        self.calls = 0

    def evaluate(self, poses: np.ndarray, options: Any = None) -> np.ndarray:
        self.calls += 1
        return -np.abs(np.asarray(poses)).sum(axis=1)


@dataclasses.dataclass
class _Search:
    """A frame search whose answer is scripted per member: ``answers[m](i, history, rng)``; it records what each
    call was given. Copied per member as the tracker's FrameSearch is (``dataclasses.replace``)."""

    answers: list
    model: Any = MODEL
    timer: Any = dataclasses.field(default_factory=PartTimer)
    constraint: Any = None
    fitness: Any = dataclasses.field(default_factory=_Fitness)
    choice_options: Any = None
    calls: list = dataclasses.field(default_factory=list)
    member: int = -1
    centres: list = dataclasses.field(default_factory=list)

    def step(self, i, history, x_prev, carry, rng, first=False) -> StepResult:
        self.calls.append((self.member, i, np.array(history), np.array(x_prev), carry, first))
        x = self.answers[self.member](i, np.asarray(history), rng)
        particles = np.repeat(x[None], 4, axis=0) + rng.normal(0.0, 1e-3, (4, len(x)))
        return StepResult(x=x, score=0.0, evaluations=10 + self.member, carry=ParticleSet(particles, np.full(4, 0.25)),
                          recovered=["left_arm"] if self.member == 1 else [])

    def note_centre(self, i, features):
        self.centres.append((self.member, i))


def _ensemble(answers, reset=80.0, seed=0):
    search = _Search(answers)
    ens = Ensemble(search, [np.random.default_rng([seed, m]) for m in range(len(answers))], BASE, reset)
    for m, member in enumerate(ens.members):
        member.search.member = m
    return ens, search


def _pose(elbow: float = 0.5, tx: float = 0.0) -> np.ndarray:
    x = BASE.copy()
    x[MODEL.param_index("r_elbow_flex")] = elbow
    x[MODEL.param_index("pelvis_tx")] += tx
    return x


def test_the_frame_is_the_members_consensus_and_a_member_that_strayed_goes_on_from_it():
    """Two members agree and one has its forearm bent far off: the frame's pose is the fit to the joint-wise median
    (the two's pose), scored once; the third member, with a wrist more than 80 mm from it, is reset onto it (its
    last pose and its particle set), the other two are not; evaluations are the members' and the one score."""
    bent = _pose(elbow=2.2)
    ens, search = _ensemble([lambda i, h, r: _pose(tx=1.0), lambda i, h, r: _pose(tx=2.0), lambda i, h, r: bent])
    res = ens.step(0, first=True)
    P = np.stack([_pose(tx=1.0), _pose(tx=2.0), bent])
    expected = consensus_params(MODEL, P[:, None, :]).params[0]
    np.testing.assert_allclose(res.x, expected)
    wrist = list(MODEL.joints15(bent[None])[0] - MODEL.joints15(res.x[None])[0])
    assert np.linalg.norm(wrist, axis=1).max() > 80
    assert res.evaluations == 10 + 11 + 12 + 1 and res.carry is None and res.recovered == ["left_arm"]
    assert res.score == pytest.approx(-np.abs(res.x).sum())
    assert ens.resets.tolist() == [0, 0, 1]
    np.testing.assert_array_equal(ens.members[2].last[-1], res.x)  # it goes on from the consensus
    np.testing.assert_array_equal(ens.members[0].last[-1], _pose(tx=1.0))  # the others from their own poses
    carried = np.average(ens.members[2].carry.particles, axis=0, weights=ens.members[2].carry.weights)
    np.testing.assert_allclose(carried, res.x, atol=1e-12)
    assert all(c[5] for c in search.calls)  # first=True reached every member
    # each member has its own search (its own silhouette-height memory)
    assert len({id(m.search) for m in ens.members}) == 3


def test_each_member_predicts_from_its_own_track_as_one_run_does():
    """Frame 1 gives a member its last pose only (no velocity yet, as one run); from frame 2 on its last two poses,
    its own, not the consensus's, unless it was reset."""
    ens, search = _ensemble([lambda i, h, r, m=m: _pose(tx=10.0 * i + m) for m in range(3)])
    for i in range(3):
        ens.step(i)
    calls = {(m, i): h for m, i, h, *_ in search.calls + [c for mb in ens.members for c in mb.search.calls]}
    assert calls[(2, 1)].shape == (1, MODEL.n_params)
    np.testing.assert_array_equal(calls[(2, 2)], np.stack([_pose(tx=2.0), _pose(tx=12.0)]))
    assert ens.resets.tolist() == [0, 0, 0]


def test_the_members_state_resumes_exactly():
    """state() then restore() on fresh members: the next frames equal those of members that went on, generators,
    last poses, particle sets and reset counts included."""
    def noisy(m):
        return lambda i, h, r: h[-1] + r.normal(0.0, 0.02 if m < 2 else 0.6, MODEL.n_params) * (MODEL.is_rotation)

    a, _ = _ensemble([noisy(m) for m in range(3)], seed=3)
    for i in range(3):
        a.step(i)
    saved = {k: np.array(v) for k, v in a.state().items()}
    b, _ = _ensemble([noisy(m) for m in range(3)], seed=99)  # other generators, overwritten by the state
    b.restore(saved)
    for i in range(3, 6):
        ra, rb = a.step(i), b.step(i)
        np.testing.assert_array_equal(ra.x, rb.x)
    assert a.resets.tolist() == b.resets.tolist() and a.resets.sum() > 0  # the wild member was reset
    c, _ = _ensemble([noisy(m) for m in range(4)])
    with pytest.raises(ValueError, match="do not fit"):
        c.restore(saved)


def test_an_ensemble_needs_three_members_and_a_positive_reset():
    with pytest.raises(ValueError, match="at least 3"):
        _ensemble([lambda i, h, r: _pose()] * 2)
    with pytest.raises(ValueError, match="reset"):
        _ensemble([lambda i, h, r: _pose()] * 3, reset=0.0)


def test_the_members_variant():
    """``members=K`` and ``members_reset=M``: parsed and checked; the budget is K times one search's and the
    consensus's score."""
    from swarmpose.errors import ConfigError
    from swarmpose.optim import registry
    from swarmpose.optim.variants import apply_variant

    cfg = registry.get("refined-heading", model=MODEL, fps=20)
    on = apply_variant(cfg, "members=3+members_reset=60")
    assert (cfg.members, on.members, on.members_reset) == (1, 3, 60.0)
    assert on.evals_per_frame == 3 * cfg.evals_per_frame + 1
    assert apply_variant(on, "members_reset=off").members_reset == np.inf
    assert apply_variant(on, "members=1").evals_per_frame == cfg.evals_per_frame
    for bad in ("members=2", "members=0", "members=three", "members_reset=0", "members_reset=-5", "members_reset=x"):
        with pytest.raises(ConfigError, match="members"):
            apply_variant(cfg, bad)
    with pytest.raises(ConfigError, match="refined configuration"):
        apply_variant(registry.get("sppso", model=MODEL, fps=20), "members=3")


def test_a_run_with_members_tracks_and_resumes_as_one_uninterrupted(short_sequence: Path, tmp_path: Path):
    """The tracker with three members (a small search each): one more evaluation per frame than the three
    members' (the consensus's score), the resets recorded, and a run cut after 2 frames and resumed equals the
    uninterrupted one pose for pose."""
    from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker

    cfg = TrackConfig(algo="refined", fps=20.0, seed=5, downsample=2,
                      optim_variant="apf=20x2+refine=10+recovery=off+members=3")
    full = run_tracker(prepare_track(short_sequence, cfg, tmp_path / "a"), 0, tmp_path / "a")
    assert np.all(full.evaluations[1:] == 3 * (40 + 10) + 1)  # frame 0 from the IK pose: the same count
    assert len(full.errors["member_resets"]) == 3
    run_tracker(prepare_track(short_sequence, cfg, tmp_path / "b"), 0, tmp_path / "b", stop_after=2)
    resumed = run_tracker(prepare_track(short_sequence, cfg, tmp_path / "b"), 0, tmp_path / "b", resume=True)
    np.testing.assert_array_equal(resumed.params, full.params)
    assert resumed.errors["member_resets"] == full.errors["member_resets"]
    one = run_tracker(prepare_track(short_sequence, dataclasses.replace(
        cfg, optim_variant="apf=20x2+refine=10+recovery=off"), tmp_path / "c"), 0)
    assert not np.array_equal(one.params, full.params)
