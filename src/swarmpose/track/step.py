"""One frame of a track: predict, search, recover lost limbs, fit the keypoints; and the offline backward pass.

:class:`FrameSearch` is what the tracker does on each frame once the frame's observation is bound to the
fitness: the motion model's prediction (and the carried particle set moved with it; with ``silhouette_height`` the
root's height moved by the rise of the silhouettes' triangulated centre since the frame before, or with
``keypoint_height`` by the rise of the trunk's triangulated keypoints where both frames have them; with
``keypoint_proposals`` a share of the carried set's weight given to the pose fitted to the frame's triangulated
keypoints from the prediction), the optimiser's search
(on the first frame of a start from the silhouettes: a turn of headings, the best few searched, then more
rounds from the best), the searches of the body's heading (:mod:`swarmpose.track.turn`) and of the trunk's lean
(:mod:`swarmpose.track.lean`), the loss detection and re-search of :mod:`swarmpose.track.recovery`, with
``head_search`` a pattern search of the head's parameters alone, and the per-frame keypoint IK of the configurations
that ask for it. A frame reads its own observation and, for the keypoint fits, one thing more: a joint its
keypoints lack is taken from the nearest tracked frame, up to two either side (the earlier first), that has it
(:func:`swarmpose.track.start.fill_gaps`), so with keypoints a live run would lag two tracked frames behind.

:func:`backward_pass` tracks a run's frames again from the last one to the first and keeps per frame the better
of the two passes' poses by the fitness (both scored with the same options); the backward pass goes on from the
pose kept, so a frame where the forward pass was right restarts it. Losses are local in time and mostly not
shared by the two directions (``shared/reference/forward-backward.md``), so the pass repairs the frames one
direction lost. They are also per limb, so the choice is too (:func:`mix_limbs`): the better whole pose, with
any of its four limbs taken from the other pass where that scores higher. The pass starts at the last frame
from the better of the forward pass's last pose and a fresh wide search there (a standing pose at the forward
pass's pelvis, turned to every heading, as a start from the silhouettes): a clip whose forward pass ends lost
does not start the backward pass lost.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from swarmpose.joints import JOINT_INDEX
from swarmpose.optim.base import optimize
from swarmpose.optim.refine import PatternSearch
from swarmpose.track.recovery import LIMBS
from swarmpose.track.start import (
    START_ROUNDS,
    START_SEARCHES,
    centre_of_silhouettes,
    fill_gaps,
    heading_candidates,
    keypoint_ik,
    silhouette_start,
)
from swarmpose.track.turn import keypoint_turn

__all__ = ["FrameSearch", "StepResult", "recentre", "backward_pass", "BackwardResult", "mix_limbs", "RISE_DEAD_ZONE_MM",
           "RISE_JOINTS"]

#: The joints whose triangulated keypoints' mean height gives the body's rise with ``keypoint_height``: the hips and the
#: shoulders (a left/right swap leaves their mean as it is). ``scripts/rise_evidence.py`` on the 8 synthetic clips and
#: their mirror images at 20 fps (the detector's keypoints, all 4 views): the mean error of the predicted step of the
#: pelvis height is 1.0-3.5 mm per frame with them against 1.1-17.0 with the silhouettes' centre (the jog, whose pelvis
#: bobs up to 43 mm a frame: 3.4 against 16.9; cmu_131_01's crouch: 2.7 against 6.2; the kick, whose raised leg lifts
#: the silhouettes' centre: 2.2 against 5.1).
RISE_JOINTS = tuple(JOINT_INDEX[n] for n in ("l_hip", "r_hip", "l_shoulder", "r_shoulder"))

#: A rise of the silhouettes' centre smaller than this (mm per frame) does not move the predicted root height, and
#: a larger one moves it by the excess. Measured on the shared clips at 20 fps (the rise against the truth's pelvis
#: height): moving arms and swinging legs move the centre by up to 7-10 mm per frame on the dance, the walk and
#: the turn while the pelvis stays (with every rise applied the dance went from 42.3 to 53.0 mm); the jump's flight
#: moves it by up to 108.
RISE_DEAD_ZONE_MM = 10.0


def recentre(carry: Any, x: np.ndarray, groups: list[np.ndarray], lower: np.ndarray, upper: np.ndarray) -> Any:
    """Move the carried particle set's recovered parameters onto ``x``, keeping their spread (a recovered
    limb would otherwise be lost again by the next frame's search, which starts from the carried set)."""
    if carry is None:
        return None
    from swarmpose import optim

    particles = np.array(carry.particles, dtype=np.float64)
    for idx in groups:
        particles[:, idx] += x[idx] - np.average(particles[:, idx], axis=0, weights=carry.weights)
    return optim.ParticleSet(np.clip(particles, lower, upper), carry.weights)


@dataclass
class StepResult:
    """One frame's answer: pose, score, fitness evaluations, the particle set to carry, limbs recovered."""

    x: np.ndarray
    score: float
    evaluations: int
    carry: Any
    recovered: list[str] = field(default_factory=list)


@dataclass
class FrameSearch:
    """The per-frame search of a run (module docstring). ``fitness`` is bound to the frame before :meth:`step`."""

    model: Any
    algo: Any
    fitness: Any
    motion: Any
    motion_mask: np.ndarray
    constraint: Callable[[np.ndarray], np.ndarray]
    timer: Any
    extra_options: dict
    recovery: Any = None
    kp_joints: np.ndarray | None = None
    search_start: bool = False
    silhouette_height: bool = False
    keypoint_height: bool = False  # with silhouette_height and kp_joints: the rise of the trunk's keypoints instead
    turn: Any = None  # a swarmpose.track.turn.TurnSearch
    lean: Any = None  # a swarmpose.track.lean.LeanSearch
    heading_speed: float | None = None  # degrees per frame (the algorithm's heading_speed)
    keypoint_ik: bool = True  # with kp_joints: each frame's pose fitted to them after the searches
    keypoint_ik_polish: int = 0  # pattern-search evaluations from a keypoint fit that scores no higher
    keypoint_proposals: float = 0.0  # with kp_joints: the carried set's share given to the fit from the prediction
    head_search: int = 0  # pattern-search evaluations over the head's parameters after the limbs' searches
    _centre: tuple[int, np.ndarray | None] | None = field(default=None, init=False, repr=False)

    def note_centre(self, i: int, features: Any) -> tuple[int, np.ndarray | None] | None:
        """Remember position ``i``'s silhouette centre (from its features; a resumed run notes the frame before
        the first it tracks). Returns what was noted before."""
        silhouettes = getattr(features, "silhouettes", None)
        c = None if silhouettes is None else centre_of_silhouettes(silhouettes, list(features.cameras))
        before, self._centre = self._centre, (i, c)
        return before

    def _rise(self, i: int) -> float:
        """How far the body rose (mm) since the frame searched before, when that was position ``i - 1`` or ``i + 1``
        (a backward pass): with ``keypoint_height``, the mean rise of the :data:`RISE_JOINTS` keypoints where both
        frames have them all; else the rise of the silhouettes' triangulated centre, when both centres are known,
        less :data:`RISE_DEAD_ZONE_MM` towards 0; else 0."""
        before = self.note_centre(i, getattr(self.fitness, "features", None))  # the tracker's TimedFitness
        if before is None or abs(before[0] - i) != 1:
            return 0.0
        if self.keypoint_height and self.kp_joints is not None:
            now, then = self.kp_joints[i, RISE_JOINTS, 2], self.kp_joints[before[0], RISE_JOINTS, 2]
            if np.isfinite(now).all() and np.isfinite(then).all():
                return float(np.mean(now - then))
        c = self._centre[1]
        if c is None or before[1] is None:
            return 0.0
        rise = float(c[2] - before[1][2])
        return float(np.sign(rise)) * max(0.0, abs(rise) - RISE_DEAD_ZONE_MM)

    def _carry_heading(self, history: np.ndarray, x_pred: np.ndarray) -> np.ndarray:
        """``x_pred`` with the part of the heading's (``pelvis_rz``'s) last step beyond ``heading_speed`` degrees
        added, where the pose stays within the hard priors."""
        rz = self.model.param_index("pelvis_rz")
        d = float(history[-1][rz] - history[-2][rz])
        excess = float(np.sign(d)) * max(0.0, abs(d) - np.radians(self.heading_speed))
        if not excess:
            return x_pred
        moved = x_pred.copy()
        moved[rz] += excess
        return moved if bool(np.asarray(self.constraint(moved[None]))[0]) else x_pred

    def step(self, i: int, history: np.ndarray, x_prev: np.ndarray, carry: Any, rng: np.random.Generator,
             first: bool = False) -> StepResult:
        """Track position ``i`` from ``x_prev``; ``history`` = the poses tracked so far in the pass's order (the
        motion model predicts from its last rows); ``first``: the first frame of a start from the silhouettes."""
        from swarmpose import optim

        model, timer, fitness, extra = self.model, self.timer, self.fitness, self.extra_options
        with timer.part("motion"):
            x_pred = self.motion.predict(history, self.constraint, self.motion_mask)
            if self.silhouette_height:
                rise = self._rise(i)
                if rise:
                    tz = model.param_index("pelvis_tz")
                    x_pred = x_pred.copy()
                    x_pred[tz] = min(max(x_pred[tz] + rise, model.lower[tz]), model.upper[tz])
            if self.heading_speed is not None and len(history) >= 2:
                x_pred = self._carry_heading(history, x_pred)
            step = x_pred - x_prev
            if carry is not None and np.any(step):
                carry = optim.ParticleSet(self.motion.move_particles(carry.particles, step, self.constraint),
                                          carry.weights)
        if self.keypoint_proposals > 0 and self.kp_joints is not None and carry is not None:
            with timer.part("keypoint_ik"):
                x_kp = keypoint_ik(model, fill_gaps(self.kp_joints, i, reach=2), x_pred, self.constraint)
            if x_kp is not None:
                carry = carry.with_proposal(x_kp, self.keypoint_proposals)
        starts = [x_pred]
        evals = 0
        searching = first and self.search_start
        if searching:  # the heading is unknown: the best few of a turn, each searched
            turn = heading_candidates(model, x_pred)
            scores = fitness.evaluate(turn, extra or None)
            evals = len(turn)
            starts = [turn[j] for j in np.argsort(-np.nan_to_num(scores, nan=-np.inf))[:START_SEARCHES]]
        best_opt = None
        rounds = START_ROUNDS if searching else 0
        while starts:
            x_start = starts.pop(0)
            with timer.part("optimiser"):
                opt = self.algo.start(x_start, rng, constraint=self.constraint, carry=carry)
                # a staged search names its stage's options once it has asked for the stage's poses
                optimize(opt, lambda poses, opt=opt: fitness.evaluate(
                    poses, {**opt.fitness_options, **extra} if extra else opt.fitness_options))
            evals += opt.evaluations
            if best_opt is None or opt.best.score > best_opt.best.score:
                best_opt = opt
            if not starts and rounds > 0:  # frame 0 from the silhouettes: search again from the best so far
                rounds -= 1
                starts.append(np.array(best_opt.best.x, dtype=np.float64))
        opt = best_opt
        x = np.array(opt.best.x, dtype=np.float64)
        score = opt.best.score
        carry = opt.carry() if hasattr(opt, "carry") else None
        if self.turn is not None:
            with timer.part("recovery"):
                by = None
                if self.turn.keypoints and self.kp_joints is not None:
                    by = keypoint_turn(model, x, self.kp_joints[i])
                turned = self.turn.run(fitness, model, x, self.constraint, self.algo.sigma, extra or None,
                                       extra=() if by is None else (by,))
            evals += turned.evaluations
            if turned.turned:
                x, score = turned.x, turned.score
                carry = recentre(carry, x, [np.arange(model.n_params)], model.lower, model.upper)
        if self.lean is not None:  # the trunk leaned by the pelvis against the spine, before the limbs' searches
            with timer.part("recovery"):
                leaned = self.lean.run(fitness, model, x, self.constraint, self.algo.sigma, extra or None)
            evals += leaned.evaluations
            if leaned.leaned:
                x, score = leaned.x, leaned.score
                carry = recentre(carry, x, [np.arange(model.n_params)], model.lower, model.upper)
        recovered: list[str] = []
        if self.recovery is not None:
            with timer.part("recovery"):
                rec = self.recovery.run(fitness, model, x, rng, self.constraint, self.algo.sigma, extra or None,
                                         position=i)
            evals += rec.evaluations
            if rec.recovered:
                x = rec.x
                score = float(fitness.evaluate(x[None], extra or None)[0])
                evals += 1
                carry = recentre(carry, x, [model.group(LIMBS[limb][1]) for limb in rec.recovered],
                                 model.lower, model.upper)
            recovered = list(rec.recovered)
        if self.head_search and "head" in model.groups:
            with timer.part("recovery"):
                headed = self._polish(x, self.head_search, self.choice_options, model.group("head"))
            evals += headed.evaluations
            if not np.array_equal(headed.x, x):
                x, score = np.array(headed.x, dtype=np.float64), float(headed.score)
                carry = recentre(carry, x, [model.group("head")], model.lower, model.upper)
        if self.keypoint_ik and self.kp_joints is not None:
            with timer.part("keypoint_ik"):
                x_ik = keypoint_ik(model, fill_gaps(self.kp_joints, i, reach=2), x, self.constraint)
            if x_ik is not None:
                ik_options = {**self.algo.refine_options, **extra}
                ik_score = float(fitness.evaluate(x_ik[None], ik_options)[0])
                evals += 1
                if self.keypoint_ik_polish and not ik_score > score:  # the fit's basin, searched from the fit
                    with timer.part("recovery"):
                        polished = self._polish(x_ik, self.keypoint_ik_polish, ik_options)
                    evals += polished.evaluations
                    if polished.score > ik_score:
                        x_ik, ik_score = np.array(polished.x, dtype=np.float64), float(polished.score)
                if ik_score > score:
                    x, score = x_ik, ik_score
                    carry = recentre(carry, x, [np.arange(model.n_params)], model.lower, model.upper)
        return StepResult(x=x, score=float(score), evaluations=int(evals), carry=carry, recovered=recovered)

    def _polish(self, x: np.ndarray, budget: int, options: dict | None, params: np.ndarray | None = None) -> Any:
        """A pattern search of ``budget`` evaluations from ``x`` with the refinement's first step, over ``params``
        alone (default: every parameter), under the run's hard priors, scored with ``options``: the best pose it
        found (``x`` itself unless one scored higher), its score and its evaluations. The head's search uses it on
        the head's parameters: one cone, which the whole-body searches move only in passing, and which a search of it
        alone measures alone (:mod:`swarmpose.fitness._numba_partial`)."""
        model = self.model
        step = self.algo.refine_step * np.asarray(self.algo.sigma, dtype=np.float64)
        if params is not None:
            step = np.where(np.isin(np.arange(model.n_params), params), step, 0.0)
        ps = PatternSearch(x, step, int(budget), lower=model.lower, upper=model.upper, constraint=self.constraint)
        return optimize(ps, lambda poses: self.fitness.evaluate(poses, options or None))

    @property
    def choice_options(self) -> dict | None:
        """The options both passes' poses of a frame are scored with when one is chosen: the refinement's (the
        last search a frame sees), with the run's extra options over them."""
        opts = {**getattr(self.algo, "refine_options", {}), **self.extra_options}
        return opts or None


def mix_limbs(fitness: Any, model: Any, a: np.ndarray, b: np.ndarray, options: dict | None,
              constraint: Callable[[np.ndarray], np.ndarray] | None = None) -> tuple[np.ndarray, float, np.ndarray]:
    """The best of two poses of one frame, limb by limb: the better-scoring of ``a`` and ``b`` (``a`` on a tie)
    with each subset of its four limbs (:data:`~swarmpose.track.recovery.LIMBS`' parameter groups) taken from
    the other: the two poses, then the 15 mixes scored at once (those ``constraint`` rejects are skipped). Returns the pose, its score
    and ``(D,)`` bool: the parameters that came from ``b``."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    pair = np.nan_to_num(np.asarray(fitness.evaluate(np.stack([a, b]), options), dtype=np.float64), nan=-np.inf)
    base, other = (b, a) if pair[1] > pair[0] else (a, b)
    groups = [model.group(group) for _, group in LIMBS.values() if group in model.groups]
    masks = np.zeros((2 ** len(groups), model.n_params), dtype=bool)
    for k in range(1, len(masks)):
        for j, g in enumerate(groups):
            if k >> j & 1:
                masks[k, g] = True
    cands = np.where(masks, other[None], base[None])
    ok = np.ones(len(cands), dtype=bool) if constraint is None else np.asarray(constraint(cands), dtype=bool)
    ok[0] = True  # the better whole pose is always a candidate
    scores = np.full(len(cands), -np.inf)
    scores[0] = pair.max()
    rest = np.flatnonzero(ok[1:]) + 1
    if rest.size:
        scores[rest] = np.nan_to_num(np.asarray(fitness.evaluate(cands[rest], options), dtype=np.float64),
                                     nan=-np.inf)
    k = int(np.argmax(scores))
    from_b = masks[k] if base is a else ~masks[k]
    return cands[k].copy(), float(scores[k]), from_b


@dataclass
class BackwardResult:
    """The poses kept per frame after the backward pass, and what it cost.

    Attributes
    ----------
    params : (T, D) the kept poses; scores : (T,) their scores (``choice_options``).
    backward : (T,) bool -- the backward pass's pose was kept (the last frame: the fresh search's pose was).
    evaluations : (T,) int and seconds : (T,) -- of the backward pass, per frame.
    recovered : (T, limbs) bool -- limbs the backward pass found lost and searched again with success.
    mixed : (T,) bool -- the pose kept has limbs of both passes (:func:`mix_limbs`).
    """

    params: np.ndarray
    scores: np.ndarray
    backward: np.ndarray
    evaluations: np.ndarray
    seconds: np.ndarray
    recovered: np.ndarray
    mixed: np.ndarray


def backward_pass(search: FrameSearch, forward: np.ndarray, observe: Callable[[int], Any],
                  rng: np.random.Generator, progress: Callable[[int, int], None] | None = None) -> BackwardResult:
    """Track positions ``T - 2 .. 0`` backwards, from the better of the forward pass's last pose and a fresh
    wide search of the last frame (module docstring).

    ``forward (T, D)`` are the forward pass's poses; ``observe(i)`` binds position ``i``'s observation to
    ``search.fitness``; ``progress(done, T - 1)`` after each frame.
    """
    limb_names = tuple(LIMBS)
    model = search.model
    T, D = forward.shape
    params = np.array(forward, dtype=np.float64, copy=True)
    scores = np.full(T, np.nan)
    backward = np.zeros(T, dtype=bool)
    evals = np.zeros(T, dtype=np.int64)
    seconds = np.zeros(T)
    recovered = np.zeros((T, len(limb_names)), dtype=bool)
    mixed = np.zeros(T, dtype=bool)
    if T < 2:
        return BackwardResult(params, scores, backward, evals, seconds, recovered, mixed)
    options = search.choice_options
    t0 = time.perf_counter()
    observe(T - 1)
    last = params[T - 1]
    pelvis = model.joints15(last[None])[0][JOINT_INDEX["pelvis"]]
    x0 = silhouette_start(model, pelvis)
    wide = replace(search, search_start=True)

    def keep(i: int, res: StepResult, forward_carry: Callable[[Any, np.ndarray], Any]) -> tuple[np.ndarray, Any]:
        """Position ``i``'s pose, limb by limb from the forward pass's and ``res``'s, and the particle set to
        carry on with (``forward_carry`` when the forward pass's whole pose is kept)."""
        x, scores[i], from_back = mix_limbs(search.fitness, model, params[i], res.x, options, search.constraint)
        evals[i] = res.evaluations + 17  # at most: the two poses, then 15 mixes
        if from_back.all():
            backward[i] = True
            for limb in res.recovered:
                recovered[i, limb_names.index(limb)] = True
            return x, res.carry
        if from_back.any():  # limbs of both passes: go on from the mix
            mixed[i] = True
            return x, recentre(res.carry, x, [np.flatnonzero(~from_back)], model.lower, model.upper)
        return x, forward_carry(res.carry, x)

    res = wide.step(T - 1, x0[None], x0, None, rng, first=True)
    # the forward pass's last pose has no particle set of its own to carry
    params[T - 1], carry = keep(T - 1, res, lambda _carry, _x: None)
    seconds[T - 1] = time.perf_counter() - t0
    x_prev = params[T - 1].copy()
    for done, i in enumerate(range(T - 2, -1, -1), start=1):
        t0 = time.perf_counter()
        observe(i)
        # the last two poses kept, oldest first (params holds the kept poses from i + 1 on)
        history = params[[i + 2, i + 1]] if i + 2 < T else x_prev[None]
        res = search.step(i, history, x_prev, carry, rng)
        x_prev, carry = keep(i, res, lambda c, x: recentre(c, x, [np.arange(D)], model.lower, model.upper))
        params[i] = x_prev
        seconds[i] = time.perf_counter() - t0
        if progress is not None:
            progress(done, T - 1)
    return BackwardResult(params, scores, backward, evals, seconds, recovered, mixed)
