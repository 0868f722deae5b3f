"""Several searches of every frame side by side, one pose: a run's members and their consensus.

Beyond the papers. Independent runs of the stochastic tracker lose a limb on different frames more often than on
the same ones (``docs/results.md``, the runs' consensus), so the joint-wise median of three runs' joints is right
where two of them are. An ensemble tracks ``K`` members side by side inside one run, each with its own generator,
particle set and last poses (its motion model predicts from its own track), and per frame

    x* = consensus of the members' poses            (:func:`swarmpose.track.consensus.consensus_params`:
                                                     the model fitted to the joint-wise median of their joints)

is the run's pose. A member with a joint more than ``reset`` mm from the consensus's goes on from ``x*`` (its last
pose replaced, its particle set moved onto it, :func:`swarmpose.track.step.recentre`): a member that lost a limb
votes with the others again from the next frame on instead of voting wrong for a stretch of frames. The pose of a
frame reads that frame's member poses only: an ensemble is as causal as one search (:mod:`swarmpose.track.step`).

:class:`Ensemble` is what :func:`swarmpose.track.tracker.run_tracker` steps instead of one
:class:`~swarmpose.track.step.FrameSearch` when the configuration has ``members > 1``; :meth:`Ensemble.state` and
:meth:`Ensemble.restore` carry the members through a resumed run.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

from swarmpose.track.consensus import consensus_params
from swarmpose.track.step import FrameSearch, StepResult, recentre

__all__ = ["Ensemble", "Member"]


@dataclasses.dataclass
class Member:
    """One member: its frame search (a copy of the run's: its own silhouette-height memory), generator, last two
    poses ``(2, D)`` (oldest first; both the start pose before the first frame) and carried particle set."""

    search: FrameSearch
    rng: np.random.Generator
    last: np.ndarray
    carry: Any = None


class Ensemble:
    """``K`` members of one run (module docstring); ``rngs`` one generator per member, ``x0`` the start pose."""

    def __init__(self, search: FrameSearch, rngs: Sequence[np.random.Generator], x0: np.ndarray,
                 reset: float) -> None:
        if len(rngs) < 3:
            raise ValueError(f"an ensemble needs at least 3 members (the median of two is their mean), got {len(rngs)}")
        if not reset > 0:
            raise ValueError(f"reset must be > 0 mm (inf: never), got {reset}")
        x0 = np.asarray(x0, dtype=np.float64)
        self.search = search
        self.reset = float(reset)
        self.members = [Member(search=search if m == 0 else dataclasses.replace(search), rng=rng,
                               last=np.stack([x0, x0])) for m, rng in enumerate(rngs)]
        self.resets = np.zeros(len(self.members), dtype=np.int64)  # per member: the frames it went on from x*

    def step(self, i: int, first: bool = False) -> StepResult:
        """Track position ``i`` with every member; the consensus as the frame's result (its score the frame's
        choice score, :attr:`FrameSearch.choice_options`; its evaluations the members' and that one; the limbs
        any member recovered). :attr:`resets` counts, per member, the frames it went on from the consensus."""
        search = self.search
        model = search.model
        poses, evals, recovered = [], 0, set()
        for m in self.members:
            history = m.last if i >= 2 else m.last[-1:]  # as one run: a velocity from position 2 on
            r = m.search.step(i, history, m.last[-1], m.carry, m.rng, first=first)
            m.last = np.vstack([m.last[-1:], r.x[None]])
            m.carry = r.carry
            poses.append(r.x)
            evals += r.evaluations
            recovered.update(r.recovered)
        P = np.stack(poses)
        with search.timer.part("consensus"):
            fused = consensus_params(model, P[:, None, :], search.constraint)
            x = fused.params[0]
            far = np.linalg.norm(model.joints15(P) - fused.joints[0][None], axis=-1).max(axis=1) > self.reset
            self.resets += far
            for m, f in zip(self.members, far, strict=True):
                if f:
                    m.last[-1] = x
                    m.carry = recentre(m.carry, x, [np.arange(model.n_params)], model.lower, model.upper)
        score = float(search.fitness.evaluate(x[None], search.choice_options)[0])
        return StepResult(x=np.array(x), score=score, evaluations=evals + 1, carry=None, recovered=sorted(recovered))

    def note_centre(self, i: int, features: Any) -> None:
        """Every member's silhouette-height memory of position ``i`` (a resumed run's frame before its first)."""
        for m in self.members:
            m.search.note_centre(i, features)

    def state(self) -> dict[str, np.ndarray]:
        """The members' state as arrays (a run's progress file keeps them): last poses ``(K, 2, D)``, reset counts,
        generators' states (JSON), particle sets where carried."""
        out = {"last": np.stack([m.last for m in self.members]), "resets": self.resets.copy(),
               "rng": np.array(json.dumps([m.rng.bit_generator.state for m in self.members]))}
        if all(m.carry is not None for m in self.members):
            out["carry_x"] = np.stack([m.carry.particles for m in self.members])
            out["carry_w"] = np.stack([m.carry.weights for m in self.members])
        return out

    def restore(self, state: dict[str, np.ndarray]) -> None:
        """Continue from :meth:`state`'s arrays (raises ValueError where they do not fit these members)."""
        from swarmpose import optim

        K, D = len(self.members), self.members[0].last.shape[1]
        last = np.asarray(state["last"], dtype=np.float64)
        rngs = json.loads(str(state["rng"]))
        if last.shape != (K, 2, D) or len(rngs) != K:
            raise ValueError(f"the saved members ({last.shape[0]}) do not fit this run's {K} of {D} parameters")
        self.resets = np.asarray(state["resets"], dtype=np.int64).copy()
        for k, m in enumerate(self.members):
            m.last = last[k].copy()
            m.rng.bit_generator.state = rngs[k]
            m.carry = (optim.ParticleSet(np.array(state["carry_x"][k]), np.array(state["carry_w"][k]))
                       if "carry_x" in state else None)
