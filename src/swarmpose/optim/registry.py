"""Named optimiser configurations: ``get("sppso", model=..., fps=...)``, ``names()``, ``describe()``.

A configuration is a frozen dataclass holding everything one frame's search needs (stages or layers,
per-parameter sigma at the tracked frame rate, bounds); ``config.start(x0, rng, constraint, carry)``
returns a fresh :class:`~swarmpose.optim.base.Optimizer` for one frame.

Named configurations (evaluations per frame)
--------------------------------------------
=============  =====  ===========================================================================
name           evals  source
=============  =====  ===========================================================================
sppso          1000   [FL12] Table 6.1: 10 x 20 (x1-x6, torso edges) + 20 x 40 (all, sigma_4..6 / 10)
sppso3         1000   [FL12] sec. 6.6, Table 6.3: 10 x 20 + 10 x 40 + 10 x 40
pso-global     1000   [FL12] sec. 6.6: one stage, 25 x 40
hard2          1000   [FL12] sec. 6.6: sppso with x1-x6 fixed in stage 2
hpso12         7200   John et al. 2010 as run in [FL12] sec. 6.6: 12 hard partitions x 10 x 60
apf            1000   HumanEva APF ([FL12] Table 4.3: 200 particles x 5 layers), fixed schedule eq. 13
apf-adaptive   1000   the apf set-up (200 x 5, Sigma as SPPSO, x31 fixed) with [DR05] eq. 18-19: [FL12] 4.4.4
apf-dr05       2000   [DR05] sec. 3.1, Fig. 9-10: 200 particles x 10 layers, adaptive (6.1), crossover
aapso          4300   [SH17] sec. 4.2: 5 stages x 80 x 10 + 30 x 10; eq. 18
aapso-fixed    4300   [SH17] as aapso with eq. 16 (the authors' earlier version, sec. 4.9)
aapso-         4500   beyond the papers: aapso, then a 200-evaluation pattern search on the same marker
refined               fitness
refined        1400   beyond the papers: apf-dr05 at 200 x 6, then a 200-evaluation pattern search
                      (:mod:`swarmpose.optim.refine`); the tracker adds root velocity and limb recovery
refined-       1400   refined with the keypoint term (``keypoints=2``) in its searches: sequences that carry
keypoints             a detector's body keypoints (``swarmpose import``)
=============  =====  ===========================================================================

Frame-rate scaling
------------------
* Thesis-based searches (SPPSO variants, HPSO, APF): the body model's ``sigma`` is the maximum inter-frame
  change at 60 fps ([FL12] sec. 5.3.2, eq. 5.10); at another rate it is multiplied by ``60 / fps``
  ("at a frame rate of 20 fps sigma is multiplied by three"). The APF's ``P_0`` is scaled "exactly as for
  SPPSO" ([FL12] sec. 6.5).
* AAPSO: a generic motion model with ``sigma = 0.1 rad`` for every joint angle at the PEAR rate of 25 fps
  ([SH17] sec. 3.2). At 12 fps "the values of matrix P_0 ... used for 25 fps are doubled" ([SH17] sec. 4.4).
  ``P_0`` is a covariance (eq. 6, 16), so we scale its entries -- the variances -- by ``25 / fps``, i.e.
  ``sigma = 0.1 * sqrt(25 / fps)`` (``fps_scaling="variance"``, the literal reading). ``fps_scaling="sigma"``
  scales the standard deviations by ``25 / fps`` instead (doubling sigma at half the rate). The paper gives
  no sigma for the root position; we use the model's 60-fps sigma converted to a 25-fps step
  (``model.sigma * 60 / 25``) and scale it the same way.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .aapso import StagedAAPSO
from .apf import AnnealedParticleFilter, ParticleSet
from .base import ConfigError, Constraint, Optimizer, ShapeError, check_rng, frozen_options
from .pso import StagedPSO
from .refine import Chain, PatternSearch
from .schedules import (
    EDGE_ALL,
    aapso_stages,
    global_stages,
    hard2_stages,
    head_twist_indices,
    hpso12_stages,
    sppso3_stages,
    sppso_stages,
)
from .staged import Stage

__all__ = [
    "AAPSOConfig",
    "APFConfig",
    "OptimizerConfig",
    "PSOConfig",
    "RefinedConfig",
    "describe",
    "get",
    "names",
    "register",
]

THESIS_FPS = 60.0
"""Frame rate at which the thesis's sigma (max inter-frame change) is defined ([FL12] sec. 5.3.2)."""
AAPSO_FPS = 25.0
"""Frame rate of PEAR, at which AAPSO's generic sigma of 0.1 rad is defined ([SH17] sec. 3.2, 4)."""
AAPSO_SIGMA = 0.1
"""AAPSO's generic per-angle sigma in radians ([SH17] sec. 3.2)."""


def _ro(a: Any) -> np.ndarray:
    v = np.array(a, dtype=np.float64, copy=True)
    v.setflags(write=False)
    return v


def _check_x0(x0: Any, d: int) -> np.ndarray:
    x = np.array(x0, dtype=np.float64)
    if x.shape != (d,):
        raise ShapeError(f"x0 must have shape ({d},), got {x.shape}")
    return x


@dataclass(frozen=True, eq=False)
class OptimizerConfig:
    """Fields shared by every named configuration.

    Attributes
    ----------
    name : str
    reference : str
        Paper and section/table the configuration follows.
    fps : float
        Frame rate the sigma was scaled for.
    sigma : ndarray, shape (D,)
        Per-parameter sigma at ``fps``.
    lower, upper : ndarray, shape (D,)
        Bounds (from the model).
    param_names : tuple of str
    """

    name: str
    reference: str
    fps: float
    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    param_names: tuple[str, ...]

    def __post_init__(self) -> None:
        d = len(self.param_names)
        for attr in ("sigma", "lower", "upper"):
            v = _ro(getattr(self, attr))
            if v.shape != (d,):
                raise ConfigError(f"{self.name}: {attr} must have shape ({d},), got {v.shape}")
            object.__setattr__(self, attr, v)
        if not np.all(np.isfinite(self.sigma)) or np.any(self.sigma < 0):
            raise ConfigError(f"{self.name}: sigma must be finite and >= 0")
        if np.any(np.isnan(self.lower)) or np.any(np.isnan(self.upper)) or np.any(self.lower > self.upper):
            raise ConfigError(f"{self.name}: bounds must satisfy lower <= upper")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ConfigError(f"{self.name}: fps must be > 0, got {self.fps}")

    @property
    def dimension(self) -> int:
        """Number of parameters ``D``."""
        return len(self.param_names)

    @property
    def evals_per_frame(self) -> int:
        """Fitness evaluations per frame."""
        raise NotImplementedError

    def start(
        self,
        x0: Any,
        rng: np.random.Generator,
        constraint: Constraint | None = None,
        carry: Any = None,
    ) -> Optimizer:
        """A fresh optimiser for one frame, searching around the previous estimate ``x0``.

        Parameters
        ----------
        x0 : ndarray, shape (D,)
        rng : numpy.random.Generator
        constraint : callable, optional
            ``constraint(poses (N, D)) -> (N,) bool`` (the body model's hard priors).
        carry : optional
            What the previous frame's optimiser returned from ``carry()`` (a ``ParticleSet`` for the APF,
            ``None`` for the PSO family).
        """
        raise NotImplementedError


def _validate_stages(cfg: Any) -> None:
    """A staged configuration needs at least one :class:`Stage`, each over the model's parameters."""
    if not cfg.stages:
        raise ConfigError(f"{cfg.name}: at least one stage is required")
    object.__setattr__(cfg, "stages", tuple(cfg.stages))
    for st in cfg.stages:
        if not isinstance(st, Stage) or st.dimension != cfg.dimension:
            raise ConfigError(f"{cfg.name}: stages must be Stage objects over {cfg.dimension} parameters")


def _no_carry(name: str, carry: Any) -> None:
    if carry is not None:
        raise ConfigError(f"{name} carries nothing between frames; got carry={type(carry).__name__}")


@dataclass(frozen=True, eq=False)
class PSOConfig(OptimizerConfig):
    """A staged constricted PSO ([FL12] Algorithm 2): SPPSO, its variants, one global stage, HPSO.

    Attributes
    ----------
    stages : tuple of Stage
    c_start, c_end : float
        c1 = c2 rise linearly from ``c_start`` to ``c_end`` (2.05 -> 2.15, [FL12] sec. 5.3.2).
    vmax_factor : float
        ``|v| <= vmax_factor * sigma`` (2).
    max_redraws : int
        Constraint re-draws of a move (10).
    """

    stages: tuple[Stage, ...] = ()
    c_start: float = 2.05
    c_end: float = 2.15
    vmax_factor: float = 2.0
    max_redraws: int = 10

    def __post_init__(self) -> None:
        super().__post_init__()
        _validate_stages(self)
        if 2 * self.c_start <= 4 or 2 * self.c_end <= 4:
            raise ConfigError(f"{self.name}: c1 + c2 must exceed 4 (thesis eq. 5.9)")
        if self.vmax_factor <= 0 or self.max_redraws < 0:
            raise ConfigError(f"{self.name}: vmax_factor must be > 0 and max_redraws >= 0")

    @property
    def evals_per_frame(self) -> int:
        return sum(st.evaluations for st in self.stages)

    def start(
        self, x0: Any, rng: np.random.Generator, constraint: Constraint | None = None, carry: Any = None
    ) -> StagedPSO:
        _no_carry(self.name, carry)
        return StagedPSO(
            _check_x0(x0, self.dimension),
            self.sigma,
            self.stages,
            check_rng(rng),
            lower=self.lower,
            upper=self.upper,
            constraint=constraint,
            c_start=self.c_start,
            c_end=self.c_end,
            vmax_factor=self.vmax_factor,
            max_redraws=self.max_redraws,
        )


@dataclass(frozen=True, eq=False)
class AAPSOConfig(OptimizerConfig):
    """Adaptive annealed PSO with six soft stages ([SH17] sec. 3.4).

    Attributes
    ----------
    stages : tuple of Stage
    adaptive : bool
        ``P_n = alpha_n Var(swarm)`` (eq. 18) or ``alpha_n P_0`` (eq. 16).
    max_redraws : int
    """

    stages: tuple[Stage, ...] = ()
    adaptive: bool = True
    max_redraws: int = 10

    def __post_init__(self) -> None:
        super().__post_init__()
        _validate_stages(self)
        if self.max_redraws < 0:
            raise ConfigError(f"{self.name}: max_redraws must be >= 0")

    @property
    def evals_per_frame(self) -> int:
        return sum(st.evaluations for st in self.stages)

    def start(
        self, x0: Any, rng: np.random.Generator, constraint: Constraint | None = None, carry: Any = None
    ) -> StagedAAPSO:
        _no_carry(self.name, carry)
        return StagedAAPSO(
            _check_x0(x0, self.dimension),
            self.sigma,
            self.stages,
            check_rng(rng),
            adaptive=self.adaptive,
            lower=self.lower,
            upper=self.upper,
            constraint=constraint,
            max_redraws=self.max_redraws,
        )


@dataclass(frozen=True, eq=False)
class APFConfig(OptimizerConfig):
    """Annealed particle filter ([DR05] sec. 3, 6).

    Attributes
    ----------
    n_particles, n_layers : int
        ``n_particles * n_layers`` evaluations per frame.
    alpha : float
        Target survival rate per layer (0.5, [DR05] sec. 3.1).
    diffusion : {"adaptive", "fixed"}
        eq. 18 or eq. 13.
    diffusion_scale : float or None
        Constant of eq. 18 (None: the kernel-bandwidth rule, see ``AnnealedParticleFilter``).
    crossover : float
        Fraction of particles made by crossover (eq. 19).
    estimate : {"mean", "max"}
        eq. 8 weighted mean or best particle.
    max_redraws : int
    fitness_options : Mapping
    """

    n_particles: int = 200
    n_layers: int = 5
    alpha: float = 0.5
    diffusion: str = "fixed"
    diffusion_scale: float | None = None
    crossover: float = 0.0
    estimate: str = "mean"
    max_redraws: int = 10
    fitness_options: Mapping[str, Any] = field(default_factory=lambda: dict(EDGE_ALL))

    def __post_init__(self) -> None:
        super().__post_init__()
        for attr in ("n_particles", "n_layers"):
            v = getattr(self, attr)
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, np.integer))
                or v < (2 if attr == "n_particles" else 1)
            ):
                raise ConfigError(
                    f"{self.name}: {attr} must be an int >= {2 if attr == 'n_particles' else 1}, got {v!r}"
                )
        if not 0 < self.alpha < 1:
            raise ConfigError(f"{self.name}: alpha must be in (0, 1), got {self.alpha}")
        if self.diffusion not in ("adaptive", "fixed"):
            raise ConfigError(f"{self.name}: diffusion must be 'adaptive' or 'fixed', got {self.diffusion!r}")
        if self.diffusion_scale is not None and not 0.0 < self.diffusion_scale < 1.0:
            raise ConfigError(f"{self.name}: diffusion_scale must be in (0, 1) or None")
        if not 0 <= self.crossover <= 1:
            raise ConfigError(f"{self.name}: crossover must be in [0, 1], got {self.crossover}")
        if self.estimate not in ("mean", "max"):
            raise ConfigError(f"{self.name}: estimate must be 'mean' or 'max'")
        if self.max_redraws < 0:
            raise ConfigError(f"{self.name}: max_redraws must be >= 0")
        object.__setattr__(self, "fitness_options", frozen_options(self.fitness_options))

    @property
    def evals_per_frame(self) -> int:
        return self.n_particles * self.n_layers

    def start(
        self,
        x0: Any,
        rng: np.random.Generator,
        constraint: Constraint | None = None,
        carry: ParticleSet | None = None,
    ) -> AnnealedParticleFilter:
        return AnnealedParticleFilter.start(
            _check_x0(x0, self.dimension),
            self.sigma,
            self.n_particles,
            self.n_layers,
            check_rng(rng),
            carry=carry,
            alpha=self.alpha,
            diffusion=self.diffusion,
            diffusion_scale=self.diffusion_scale,
            crossover=self.crossover,
            lower=self.lower,
            upper=self.upper,
            constraint=constraint,
            max_redraws=self.max_redraws,
            estimate=self.estimate,
            fitness_options=self.fitness_options,
        )


@dataclass(frozen=True, eq=False)
class RefinedConfig(OptimizerConfig):
    """A base search followed by a deterministic local refinement (:class:`~swarmpose.optim.refine.PatternSearch`).

    Attributes
    ----------
    base : OptimizerConfig
        The stochastic search (its carry is the chain's).
    refine_budget : int
        Evaluations of the pattern search.
    refine_step : float
        Its initial step per coordinate, in units of ``sigma`` (the search's spread at this rate).
    refine_options : Mapping
        Fitness options of the refinement.
    recovery : Mapping
        Settings of the tracker's loss detection and wide re-search (:mod:`swarmpose.track.recovery`),
        read by the tracker only; empty: none.
    keypoint_ik : bool
        The tracker fits each frame's pose to the triangulated keypoints from where the search left it
        (:func:`swarmpose.track.start.keypoint_ik`), where the sequence has keypoints; read by the tracker only.
    keypoint_ik_polish : int
        Pattern-search evaluations (its first step the refinement's) from the keypoint fit where the fit scores no
        higher than the frame's pose; the polished fit is kept when it scores higher. 0: the fit is kept or not as
        it is. Read by the tracker only, with ``keypoint_ik``.
    keypoint_proposals : float
        Share of the carried particle set's weight the tracker gives, before each frame's search, to the pose
        fitted to the frame's triangulated keypoints from the prediction (:meth:`ParticleSet.with_proposal`),
        where the sequence has keypoints and a set is carried; 0: none. Read by the tracker only.
    silhouette_height : bool
        The tracker moves the predicted root height by the rise of the silhouettes' triangulated centre since
        the frame before (an image fitness's observation); read by the tracker only.
    keypoint_height : bool
        With ``silhouette_height``, where the sequence has keypoints: the rise is that of the trunk's triangulated
        keypoints (the hips' and shoulders' mean height, :data:`swarmpose.track.step.RISE_JOINTS`) where both
        frames have them, the silhouettes' elsewhere. Read by the tracker only.
    turn_search : Mapping
        Settings of the tracker's search of the body's heading (:mod:`swarmpose.track.turn`; :data:`TURN_SEARCH`),
        read by the tracker only; empty: none.
    lean_search : Mapping
        Settings of the tracker's search of the trunk's lean, the pelvis pitched against the spine
        (:mod:`swarmpose.track.lean`; :data:`LEAN_SEARCH`), read by the tracker only; empty: none.
    heading_speed : float or None
        Degrees per frame: the part of the heading's last step beyond this is carried on into the prediction (a
        spin goes on, a walking pelvis's rocking does not); None: not. Read by the tracker only.
    frame_options : Mapping
        Fitness options of every search of a frame (the base search, the refinement, the heading and limb
        searches), under the run's own ``--fitness-options``; read by the tracker only. ``{"keypoints": W}``
        weighs the detector's keypoints where the sequence carries them and changes nothing where it does not.
    coupled_limits : bool
        The tracker's hard priors also reject the body model's coupled limits (``HardPriors(coupled_limits=True)``:
        the shoulders' second branch of angles, the upper arm hanging twisted beyond its rotation limits); read by
        the tracker only.
    members : int
        Searches of every frame side by side, each with its own generator, particle set and track, the frame's pose
        their consensus (:mod:`swarmpose.track.ensemble`); 1: one search. Read by the tracker only.
    members_reset : float
        Millimetres: a member with a joint farther than this from the consensus goes on from the consensus
        (``inf``: never). Read by the tracker only, with ``members > 1``.
    head_search : int
        Where the sequence has a detector's keypoints: pattern-search evaluations over the head's parameters (the
        model's ``head`` group) after the limbs' searches, from the frame's pose and with the refinement's first
        step, kept when they score higher; 0: none. Without keypoints the silhouettes alone let the head swing into
        a raised arm's outline, so it is not searched there. Read by the tracker only.
    """

    base: OptimizerConfig | None = None
    refine_budget: int = 200
    refine_step: float = 0.5
    refine_options: Mapping[str, Any] = field(default_factory=dict)
    recovery: Mapping[str, Any] = field(default_factory=dict)
    keypoint_ik: bool = False
    keypoint_ik_polish: int = 0
    keypoint_proposals: float = 0.0
    silhouette_height: bool = False
    keypoint_height: bool = False
    turn_search: Mapping[str, Any] = field(default_factory=dict)
    lean_search: Mapping[str, Any] = field(default_factory=dict)
    heading_speed: float | None = None
    frame_options: Mapping[str, Any] = field(default_factory=dict)
    coupled_limits: bool = False
    members: int = 1
    members_reset: float = 80.0
    head_search: int = 0

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.base, OptimizerConfig):
            raise ConfigError(f"{self.name}: base must be an optimiser configuration")
        if isinstance(self.refine_budget, bool) or int(self.refine_budget) != self.refine_budget or self.refine_budget < 0:
            raise ConfigError(f"{self.name}: refine_budget must be a whole number >= 0")
        if not self.refine_step > 0:
            raise ConfigError(f"{self.name}: refine_step must be > 0")
        if (isinstance(self.keypoint_ik_polish, bool) or int(self.keypoint_ik_polish) != self.keypoint_ik_polish
                or self.keypoint_ik_polish < 0):
            raise ConfigError(f"{self.name}: keypoint_ik_polish must be a whole number of evaluations >= 0")
        if not 0.0 <= self.keypoint_proposals < 1.0:
            raise ConfigError(f"{self.name}: keypoint_proposals must be a share of the weight in [0, 1), got "
                              f"{self.keypoint_proposals}")
        if isinstance(self.members, bool) or int(self.members) != self.members or not (self.members == 1
                                                                                         or self.members >= 3):
            raise ConfigError(f"{self.name}: members must be 1 or a whole number >= 3 (the median of two poses is "
                              f"their mean), got {self.members}")
        if isinstance(self.head_search, bool) or int(self.head_search) != self.head_search or self.head_search < 0:
            raise ConfigError(f"{self.name}: head_search must be a whole number of evaluations >= 0, got "
                              f"{self.head_search!r}")
        if not self.members_reset > 0:
            raise ConfigError(f"{self.name}: members_reset must be > 0 mm (inf: never), got {self.members_reset}")
        object.__setattr__(self, "refine_options", frozen_options(self.refine_options))
        object.__setattr__(self, "recovery", frozen_options(self.recovery))
        object.__setattr__(self, "turn_search", frozen_options(self.turn_search))
        object.__setattr__(self, "lean_search", frozen_options(self.lean_search))

    @property
    def evals_per_frame(self) -> int:
        """The search's and the refinement's evaluations, the heading's search, and the limbs' searches when every
        limb is searched on every frame (a lost limb's search, only when one is lost, is not counted, nor the keypoint
        fit's score and the head's search, only on a sequence with keypoints); with members, each member's and the
        consensus's score."""
        n = self.base.evals_per_frame + int(self.refine_budget)
        r = self.recovery
        if r and r.get("threshold", 0.05) < 0:
            limbs = min(int(r.get("in_turn") or RECOVERY_LIMBS), RECOVERY_LIMBS)
            n += limbs * (1 + int(r.get("n_samples", 100)) * int(r.get("n_rounds", 5)) + int(r.get("refine_budget", 100))
                          + (2 if r.get("guard") else 0))
        t = self.turn_search
        if t:
            n += (1 + len(t["whole"]) + len(t["pelvis"]) + int(t["n_best"]) * int(t["budget"])
                  + (2 if t.get("guard") else 0) + (2 if t.get("keypoints") else 0))
        lean = self.lean_search
        if lean:
            n += 1 + len(lean["degrees"]) + int(lean["n_best"]) * int(lean["budget"])
        return n if self.members == 1 else int(self.members) * n + 1

    def start(self, x0: Any, rng: np.random.Generator, constraint: Constraint | None = None,
              carry: Any = None) -> Optimizer:
        first = self.base.start(x0, rng, constraint=constraint, carry=carry)
        if not self.refine_budget:
            return first
        step = self.refine_step * self.sigma

        def refine(x: np.ndarray, _score: float) -> PatternSearch:
            return PatternSearch(x, step, int(self.refine_budget), lower=self.lower, upper=self.upper,
                                 constraint=constraint, fitness_options=self.refine_options)

        return Chain(first, [refine])


# --------------------------------------------------------------------------------------------------
# model helpers
# --------------------------------------------------------------------------------------------------
def _model_arrays(model: Any) -> dict[str, Any]:
    if model is None:
        raise ConfigError("a body model is required: get(name, model=..., fps=...)")
    try:
        names = tuple(str(n) for n in model.param_names)
        sigma = np.asarray(model.sigma, dtype=np.float64)
        lower = np.asarray(model.lower, dtype=np.float64)
        upper = np.asarray(model.upper, dtype=np.float64)
    except AttributeError as exc:
        raise ConfigError(
            f"model lacks {exc.name!r}; need param_names, sigma, lower, upper, group()"
        ) from None
    return {"param_names": names, "sigma": sigma, "lower": lower, "upper": upper}


def _check_fps(fps: float) -> float:
    fps = float(fps)
    if not (np.isfinite(fps) and fps > 0):
        raise ConfigError(f"fps must be > 0, got {fps}")
    return fps


def _thesis_base(model: Any, fps: float) -> dict[str, Any]:
    a = _model_arrays(model)
    a["sigma"] = a["sigma"] * (THESIS_FPS / fps)  # [FL12] sec. 5.3.2: sigma * 3 at 20 fps
    a["fps"] = fps
    return a


def _apf_base(model: Any, fps: float) -> dict[str, Any]:
    """The thesis base with the head twist x31 held fixed (``sigma = 0``), as in every thesis experiment
    ([FL12] sec. 6.1, the HumanEva APF of the comparison in sec. 6.5 included); the swarm stages leave it
    out instead. (``apf-dr05``, Deutscher & Reid's own tracker, searches it.)"""
    a = _thesis_base(model, fps)
    a["sigma"] = a["sigma"].copy()
    a["sigma"][head_twist_indices(model)] = 0.0
    return a


def _aapso_sigma(model: Any, fps: float, fps_scaling: str) -> np.ndarray:
    a = _model_arrays(model)
    sigma = np.full(len(a["param_names"]), AAPSO_SIGMA)
    try:
        pos = np.asarray(model.group("root_position"), dtype=np.int64)
    except (KeyError, ValueError, LookupError):
        raise ConfigError("aapso needs the model group 'root_position'") from None
    sigma[pos] = a["sigma"][pos] * (THESIS_FPS / AAPSO_FPS)
    if fps_scaling == "variance":
        return sigma * np.sqrt(AAPSO_FPS / fps)
    if fps_scaling == "sigma":
        return sigma * (AAPSO_FPS / fps)
    raise ConfigError(f"fps_scaling must be 'variance' or 'sigma', got {fps_scaling!r}")


# --------------------------------------------------------------------------------------------------
# factories
# --------------------------------------------------------------------------------------------------
REF_SPPSO = "Fleischmann 2012, sec. 5.3 (Algorithm 2), Table 6.1"
REF_SPPSO3 = "Fleischmann 2012, sec. 6.6, Table 6.3"
REF_GLOBAL = "Fleischmann 2012, sec. 6.6 (Fig. 6.11-6.12: 25 particles x 40 iterations)"
REF_HARD2 = "Fleischmann 2012, sec. 6.6 (Fig. 6.10: SPPSO with x1-x6 fixed in stage 2)"
REF_HPSO12 = "John, Trucco & Ivekovic 2010 (HPSO) as run in Fleischmann 2012, sec. 6.6 (Fig. 6.14), Table 4.3"
REF_APF = "Sigal, Balan & Black 2010 / Balan et al. 2005 (HumanEva APF, 200 x 5) as in Fleischmann 2012, Table 4.3, sec. 6.5; Deutscher & Reid 2005, sec. 3, eq. 13"
REF_APF_DR05 = "Deutscher & Reid 2005, sec. 3.1 (10 layers, alpha = 0.5), Fig. 9-10 (200 particles), sec. 6.1-6.2 (eq. 18-19)"
REF_APF_ADAPTIVE = ("Fleischmann 2012, sec. 4.4.4 (HumanEva's baseline as Deutscher & Reid's improved APF) and 6.5; "
                    "Deutscher & Reid 2005, sec. 6.1-6.2 (eq. 18-19)")
REF_AAPSO = "Sharifi, Harati & Vahedian 2017, sec. 3.4 (eq. 15-18), sec. 4.2"
REF_AAPSO_FIXED = "Sharifi, Harati & Vahedian 2017, sec. 3.4 (eq. 16, the initial version), sec. 4.2, 4.9"


def _pso(name: str, reference: str, schedule: Callable[[Any], tuple[Stage, ...]]) -> Callable[..., PSOConfig]:
    def factory(model: Any, fps: float) -> PSOConfig:
        return PSOConfig(name=name, reference=reference, stages=schedule(model), **_thesis_base(model, fps))

    return factory


def _apf(name: str, reference: str, **defaults: Any) -> Callable[..., APFConfig]:
    def factory(model: Any, fps: float) -> APFConfig:
        return APFConfig(name=name, reference=reference, **_apf_base(model, fps), **defaults)

    return factory


def _apf_dr05(model: Any, fps: float) -> APFConfig:
    """Deutscher & Reid's improved APF.

    * 10 layers, target survival rate 0.5 (sec. 3.1, item 1 and 3: "M = 10 with N >= 200 worked well",
      "alpha_M = ... = alpha_1 = 0.5");
    * 200 particles: the walking and box sequences (Fig. 9-10: "10 annealing layers were used with 200
      particles") -> 2000 evaluations. The thesis's Table 4.3 quotes 400 x 10 = 4000 from the Fig. 8
      comparison with Condensation; ``get("apf-dr05", ..., n_particles=400)`` gives that;
    * ``P_0``: standard deviations half the maximum expected movement per frame (sec. 3.1, item 2);
    * adaptive diffusion (sec. 6.1, eq. 18) with the kernel-bandwidth constant (DR05 gives none);
    * crossover for half of the particles (sec. 6.2, eq. 19). DR05 gives no fraction for full-body
      tracking (Fig. 16b: error falls as the fraction grows); 0.5 is our choice, the best of {0, 0.5, 1}
      on the two-arm toy with 50 particles.
    """
    base = _thesis_base(model, fps)  # searches all 31 parameters: DR05's own tracker, not a thesis experiment
    # [DR05] sec. 3.1, item 2: P_0's standard deviations are half the maximum expected movement per frame;
    # the model's sigma is that maximum ([FL12] sec. 5.3.2).
    base["sigma"] = 0.5 * base["sigma"]
    return APFConfig(
        name="apf-dr05",
        reference=REF_APF_DR05,
        n_particles=200,
        n_layers=10,
        alpha=0.5,
        diffusion="adaptive",
        crossover=0.5,
        **base,
    )


#: The heading's search of ``--variant turn=on`` (:mod:`swarmpose.track.turn`): the whole pose turned by these
#: degrees, the pelvis alone by these, the best two polished by 150 pattern-search evaluations each, a turned pose
#: kept only when the silhouette overlap term does not fall.
TURN_SEARCH: Mapping[str, Any] = frozen_options({
    "whole": (30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 135.0, -135.0, 180.0),
    "pelvis": (15.0, -15.0, 30.0, -30.0, 45.0, -45.0),
    "n_best": 2, "budget": 150, "guard": "silhouette"})

#: The tracker's search of the trunk's lean (``swarmpose.track.lean``, ``--variant lean=on``): the pelvis pitched
#: against the spine and the hips by each of these degrees, the best two polished by 100 pattern-search evaluations
#: each (207 evaluations a frame).
LEAN_SEARCH: Mapping[str, Any] = frozen_options({"degrees": (-30.0, -20.0, -10.0, 10.0, 20.0, 30.0), "n_best": 2,
                                                 "budget": 100})

#: The limbs a refined configuration's recovery searches (``swarmpose.track.recovery.LIMBS``).
RECOVERY_LIMBS = 4

REF_REFINED = ("beyond the papers: Deutscher & Reid's APF ([DR05] sec. 3, 6) with a coordinate pattern search "
               "(Kolda, Lewis & Torczon 2003) and per-limb loss detection with a wide re-search")


def _refined(model: Any, fps: float) -> RefinedConfig:
    """``apf-dr05``'s search (200 x 6), a 200-evaluation pattern search on the same fitness, and the tracker's
    recovery of lost limbs (the base of the default, ``refined-heading``)."""
    base = dataclasses.replace(_apf_dr05(model, fps), n_layers=6)
    return RefinedConfig(name="refined", reference=REF_REFINED, base=base, refine_budget=200, refine_step=0.5,
                         recovery={"threshold": 0.05, "n_samples": 100, "n_rounds": 5, "refine_budget": 100},
                         **_thesis_base(model, fps))


def _refined_limbs(model: Any, fps: float) -> RefinedConfig:
    """``refined`` with every limb searched again on every frame, scored and kept by the frame's own fitness when
    the silhouette overlap term does not fall (a limb lost inside the silhouette is seen; one the edges alone pull
    elsewhere is not taken), and the predicted root height moved by the silhouettes' rise. The same as ``refined
    --variant height=silhouettes+recovery=all+recovery_terms=fitness+recovery_guard=silhouette``."""
    cfg = _refined(model, fps)
    return dataclasses.replace(cfg, name="refined-limbs", silhouette_height=True,
                               recovery={**cfg.recovery, "threshold": -1.0, "terms": "fitness", "guard": "silhouette"})


def _refined_heading(model: Any, fps: float) -> RefinedConfig:
    """The default tracker: ``refined-limbs`` with the body's heading searched again on every frame (:data:`TURN_SEARCH`),
    the body model's coupled limits among the hard priors (the shoulders' second branch of angles left out), and,
    where the sequence carries a detector's keypoints, the keypoint term (weight :data:`FRAME_KEYPOINT_WEIGHT`, the
    detector's elbows where :data:`KEYPOINT_ELBOW` puts them, the joints weighed as :data:`KEYPOINT_JOINTS` says) in
    every search of a frame, the keypoint IK after them, and the predicted root height moved by the rise of the
    trunk's keypoints instead of the silhouettes' (``keypoint_height``), and the head searched on its own after the
    limbs (:data:`HEAD_SEARCH` evaluations). A limb searched again replaces the frame's only when it scores
    :data:`RECOVERY_JUMP` more per 100 mm that its joints move. On a sequence without keypoints it is
    ``refined-limbs --variant turn=on+coupled_limits=on+recovery_jump=0.01``, pose for pose."""
    limbs = _refined_limbs(model, fps)
    return dataclasses.replace(limbs, name="refined-heading", turn_search=TURN_SEARCH,
                               frame_options={"keypoints": FRAME_KEYPOINT_WEIGHT, "keypoint_elbow": KEYPOINT_ELBOW,
                                              "keypoint_joints": KEYPOINT_JOINTS},
                               keypoint_ik=True, keypoint_height=True, coupled_limits=True, head_search=HEAD_SEARCH,
                               recovery={**limbs.recovery, "jump": RECOVERY_JUMP})


#: The score margin per 100 mm of joint movement that a limb searched again by the default's recovery must gain to
#: replace the frame's limb (``Recovery.jump``, ``--variant recovery_jump=R``). Of the default's limb misses (a joint
#: over 100 mm off) on the synthetic clips with detected keypoints, 63 of 217 episodes began with the limb jumping
#: far in one frame while the truth's moved little, 61 of them on a frame where the recovery replaced the limb, by a
#: score gain of a few thousandths (``scripts/miss_onsets.py``). With the margin (5 runs, seed 0, 20 fps): such
#: onsets 63 -> 15, the misses 456 -> 358, D_mean 19.53 either way, clips within every limit 6 -> 7; mirrored 73 ->
#: 29, 472 -> 406, 20.16 -> 20.10, 7 either way; without keypoints (3 runs) 36.3 -> 35.0 mm (docs/results.md).
RECOVERY_JUMP = 0.01


#: Pattern-search evaluations over the head's parameters alone after the default's limb searches, on a sequence with
#: keypoints (``head_search``, ``--variant head=B``): the whole-body searches move the head's one cone only in passing,
#: and a search of it alone brings the head's top nearer the truth: synthetic clips with detected keypoints (20 fps,
#: seed 0, 5 runs), its mean error 24.6 -> 18.9 mm, D_mean 19.95 -> 19.53 mm (mirrored 24.9 -> 19.4 and 20.40 ->
#: 20.16). Without keypoints the head follows the silhouettes into a raised arm's outline (cmu_131_01 49.7 ->
#: 91.1 mm), so it is not searched there (docs/results.md).
HEAD_SEARCH = 50

#: Weight of the keypoint term in ``refined-keypoints``, chosen on the shared recording (cam04 held out, 20 fps,
#: ``track --fitness-options keypoints=W`` with ``refined``, the shoulder and hip midpoints as thorax and pelvis):
#: the held-out median joint error was 11.8 / 9.1 / 8.8 / 8.6 / 8.7 / 8.3 / 8.3 px (half resolution) at
#: W = 0 / 0.5 / 1 / 2 / 4 / 10 / 30; the gain levels off from 2.
KEYPOINT_WEIGHT = 2.0

#: Weight of the keypoint term in every search of a frame of the default tracker (``refined-heading``), half
#: :data:`KEYPOINT_WEIGHT`: where the detector fails, the images (searched harder there: the heading, every limb)
#: outweigh it. Synthetic clips with detected keypoints (20 fps, 5 runs, seed 0): MMTA >= 99 % with every worst frame
#: under 100 mm on 5 of the 8 clips against 4 with 2 (the kick's worst frame 105 -> 83 mm), D_mean 20.6 -> 20.9 mm;
#: the clips mirrored (3 runs) 21.7 -> 21.5, the right turn's MMTA 96.8 -> 98.2 %; 0.5 and 4 worse; the shared
#: recording's held-out camera level (docs/results.md).
FRAME_KEYPOINT_WEIGHT = 1.0

#: Where the default's keypoint term takes the detector's elbows to lie: ``auto`` measures it per sequence, the
#: detector's split of the arm over the model's (:func:`swarmpose.track.start.elbow_fraction`). MediaPipe Pose puts
#: the elbow 15-68 mm nearer the shoulder than the synthetic clips' skeletons (0.87-1.0 of the upper arm; 0.91 of
#: the shared recording's subject, whose arms are split at Winter's 0.565). Synthetic clips with detected
#: keypoints, 3 runs: the 8 clips' mean 22.6 -> 21.5 mm, the walk 20.8 -> 18.3 (docs/results.md).
KEYPOINT_ELBOW = "auto"

#: The joints' weights inside the default's keypoint term (``keypoint_joints``): the wrists count half. Of the
#: detector's confident detections on the synthetic renders the wrists' lie more than 40 px off the truth most often
#: (3.5 % and 1.6 %, against 0.4-1.4 % for the elbows and at most 0.4 % elsewhere), and where a track misses a wrist
#: the keypoint term prefers the missed place to the truth's (``scripts/miss_evidence.py``). Synthetic clips with
#: detected keypoints, 3 runs: the 8 clips' mean 21.7 -> 21.0 mm with 0.5 (5 runs: 21.5 -> 21.0); 0.25 level with
#: 0.5 on the six clips it was run on; 2 worse on the walk (docs/results.md).
KEYPOINT_JOINTS = "wrist:0.5"


def _refined_keypoints(model: Any, fps: float) -> RefinedConfig:
    """``refined`` with the keypoint term (weight :data:`KEYPOINT_WEIGHT`) in every search and refinement, and the
    tracker's keypoint IK: each frame's pose is then fitted to the tracked views' triangulated keypoints from
    where the search left it."""
    cfg = _refined(model, fps)
    kp = {"keypoints": KEYPOINT_WEIGHT}
    base = dataclasses.replace(cfg.base, fitness_options={**cfg.base.fitness_options, **kp})
    return dataclasses.replace(cfg, name="refined-keypoints", base=base,
                               refine_options={**cfg.refine_options, **kp}, keypoint_ik=True)


def _aapso(name: str, reference: str, adaptive: bool) -> Callable[..., AAPSOConfig]:
    def factory(model: Any, fps: float, fps_scaling: str = "variance") -> AAPSOConfig:
        a = _model_arrays(model)
        a["sigma"] = _aapso_sigma(model, fps, fps_scaling)
        return AAPSOConfig(
            name=name, reference=reference, fps=fps, stages=aapso_stages(model), adaptive=adaptive, **a
        )

    return factory


#: Pattern-search evaluations of ``aapso-refined`` after AAPSO's 4300.
AAPSO_REFINE_BUDGET = 200

REF_AAPSO_REFINED = ("beyond the papers: Sharifi et al.'s AAPSO with a coordinate pattern search (Kolda, Lewis & "
                     "Torczon 2003) on the same marker fitness")


def _aapso_refined(model: Any, fps: float, fps_scaling: str = "variance") -> RefinedConfig:
    """``aapso`` followed by a :data:`AAPSO_REFINE_BUDGET`-evaluation pattern search on the same fitness, its first
    step half AAPSO's spread (the local step of ``refined``, on markers)."""
    base = _aapso("aapso", REF_AAPSO, True)(model, fps, fps_scaling)
    a = _model_arrays(model)
    a["sigma"] = base.sigma
    a["fps"] = fps
    return RefinedConfig(name="aapso-refined", reference=REF_AAPSO_REFINED, base=base,
                         refine_budget=AAPSO_REFINE_BUDGET, refine_step=0.5, **a)


@dataclass(frozen=True)
class _Entry:
    factory: Callable[..., OptimizerConfig]
    reference: str
    evals_per_frame: int
    pre_options: tuple[str, ...] = ()  # overrides consumed by the factory itself
    summary: str = ""


_REGISTRY: dict[str, _Entry] = {}


def register(
    name: str,
    factory: Callable[..., OptimizerConfig],
    *,
    reference: str,
    evals_per_frame: int,
    factory_options: tuple[str, ...] = (),
    summary: str = "",
) -> None:
    """Add a named configuration; a name clash raises ``ConfigError``.

    Parameters
    ----------
    name : str
    factory : callable
        ``factory(model, fps, **factory_options) -> OptimizerConfig``.
    reference : str
    evals_per_frame : int
        The budget the paper states (checked against the built config by the tests).
    factory_options : tuple of str
        Override keys handled by the factory rather than by ``dataclasses.replace``.
    summary : str
        What the configuration is, in one line (``swarmpose algorithms``).
    """
    if name in _REGISTRY:
        raise ConfigError(f"optimiser name {name!r} is already registered")
    _REGISTRY[name] = _Entry(factory, reference, int(evals_per_frame), tuple(factory_options), summary)


register("sppso", _pso("sppso", REF_SPPSO, sppso_stages), reference=REF_SPPSO, evals_per_frame=1000,
         summary="SPPSO: PSO in 2 soft partitions, the torso (10 x 20), then the whole body with the root "
                 "position's spread cut to 1/10 (20 x 40)")
register("sppso3", _pso("sppso3", REF_SPPSO3, sppso3_stages), reference=REF_SPPSO3, evals_per_frame=1000,
         summary="SPPSO in 3 soft partitions: torso, then all but forearms and calves, then the whole body")
register(
    "pso-global", _pso("pso-global", REF_GLOBAL, global_stages), reference=REF_GLOBAL, evals_per_frame=1000,
    summary="baseline: one PSO over all parameters at once (25 x 40), no partitions",
)
register("hard2", _pso("hard2", REF_HARD2, hard2_stages), reference=REF_HARD2, evals_per_frame=1000,
         summary="baseline: SPPSO with hard partitions (the torso held fixed in stage 2)")
register("hpso12", _pso("hpso12", REF_HPSO12, hpso12_stages), reference=REF_HPSO12, evals_per_frame=7200,
         summary="baseline: hierarchical PSO, 12 hard partitions down the kinematic tree (10 x 60 each)")
register(
    "apf",
    _apf("apf", REF_APF, n_particles=200, n_layers=5, alpha=0.5, diffusion="fixed", crossover=0.0),
    reference=REF_APF,
    evals_per_frame=1000,
    summary="HumanEva's annealed particle filter (200 particles x 5 layers, fixed diffusion, no crossover)",
)
register(
    "apf-adaptive",
    _apf("apf-adaptive", REF_APF_ADAPTIVE, n_particles=200, n_layers=5, alpha=0.5, diffusion="adaptive",
         crossover=0.5),
    reference=REF_APF_ADAPTIVE,
    evals_per_frame=1000,
    summary="the apf baseline (200 x 5, the thesis's Sigma, x31 fixed) with Deutscher & Reid's adaptive diffusion "
            "and crossover: HumanEva's baseline as thesis sec. 4.4.4 describes it",
)
register("apf-dr05", _apf_dr05, reference=REF_APF_DR05, evals_per_frame=2000,
         summary="Deutscher & Reid's annealed particle filter with adaptive diffusion and crossover "
                 "(200 x 10); the most accurate on silhouettes here")
register("refined", _refined, reference=REF_REFINED, evals_per_frame=1400,
         summary="Deutscher & Reid's APF (200 x 6), a local pattern search (200), and lost limbs searched again "
                 "over their joint limits")
register("refined-limbs", _refined_limbs, reference=REF_REFINED, evals_per_frame=1400 + 4 * 603,
         summary="refined with every limb searched again on every frame by the frame's fitness, kept when the "
                 "silhouettes agree, and the root's height from the silhouettes")
register("refined-heading", _refined_heading, reference=REF_REFINED, evals_per_frame=1400 + 4 * 603 + 318,
         summary="the default: refined-limbs with the body's heading searched again on every frame (the pose "
                 "turned as a whole and its pelvis alone, the best two polished), and a detector's keypoints in "
                 "every search and fitted after them where the sequence carries them")
register("refined-keypoints", _refined_keypoints, reference=REF_REFINED, evals_per_frame=1400,
         summary="refined with a detector's body keypoints in the fitness (robust, confidence-weighted, left/right "
                 "swaps allowed): for imported recordings, which carry them")
register(
    "aapso",
    _aapso("aapso", REF_AAPSO, True),
    reference=REF_AAPSO,
    evals_per_frame=4300,
    factory_options=("fps_scaling",),
    summary="adaptive annealed PSO on 2D marker detections: torso, 4 limbs, head in 6 soft stages",
)
register(
    "aapso-refined",
    _aapso_refined,
    reference=REF_AAPSO_REFINED,
    evals_per_frame=4300 + AAPSO_REFINE_BUDGET,
    factory_options=("fps_scaling",),
    summary="AAPSO on 2D marker detections, then a pattern search on the same fitness (the local step of refined)",
)
register(
    "aapso-fixed",
    _aapso("aapso-fixed", REF_AAPSO_FIXED, False),
    reference=REF_AAPSO_FIXED,
    evals_per_frame=4300,
    factory_options=("fps_scaling",),
    summary="baseline: AAPSO with the non-adaptive covariance (eq. 16)",
)


# --------------------------------------------------------------------------------------------------
# public access
# --------------------------------------------------------------------------------------------------
def names() -> tuple[str, ...]:
    """All registered configuration names, in registration order."""
    return tuple(_REGISTRY)


def default_motion(name: str) -> str:
    """The motion model ``swarmpose track --motion auto`` gives an algorithm: for ``refined`` the root's
    horizontal position carried on at its last velocity (not its height: a jump turns at its top), for the
    papers' configurations the thesis's zero velocity (sec. 5.3.2)."""
    return "constant-velocity@pelvis_tx+pelvis_ty" if name.startswith("refined") else "zero-velocity"


def default_fitness(name: str) -> str:
    """The fitness ``swarmpose track --fitness auto`` gives an algorithm: the 2D-marker reprojection score for
    the AAPSO family (Sharifi et al. track markers), silhouette + edges for the others (the thesis's)."""
    return "reprojection" if name.startswith("aapso") else "silhouette_edge"


def describe() -> list[dict[str, Any]]:
    """``[{"name", "summary", "fitness", "evals_per_frame", "reference"}, ...]`` for every named configuration
    (``fitness``: what ``--fitness auto`` uses with it)."""
    return [
        {"name": n, "summary": e.summary, "fitness": default_fitness(n), "evals_per_frame": e.evals_per_frame,
         "reference": e.reference}
        for n, e in _REGISTRY.items()
    ]


def get(name: str, *, model: Any, fps: float = THESIS_FPS, **overrides: Any) -> OptimizerConfig:
    """The named configuration for ``model`` at ``fps``.

    Parameters
    ----------
    name : str
        One of :func:`names`.
    model : body model
        Duck-typed: ``param_names``, ``sigma`` (60-fps sigma), ``lower``, ``upper``, ``group(name)``.
    fps : float
        Frame rate of the tracked sequence (sigma scaling, see module docstring).
    **overrides
        Field values replacing the defaults (e.g. ``n_particles=400`` for an APF, ``crossover=0.0``);
        unknown fields raise ``ConfigError`` listing the valid ones.

    Returns
    -------
    OptimizerConfig
        Frozen; ``.name``, ``.evals_per_frame``, ``.reference``, ``.start(x0, rng, constraint, carry)``.

    Raises
    ------
    ConfigError
        Unknown name (the message lists the known names), missing model, bad values.

    Examples
    --------
    >>> from swarmpose.optim.testfunctions import hierarchical_body
    >>> _, toy = hierarchical_body([0.0] * 11)
    >>> cfg = get("sppso", model=toy, fps=20)
    >>> cfg.evals_per_frame, [st.n_particles * st.n_iterations for st in cfg.stages]
    (1000, [200, 800])
    """
    if name not in _REGISTRY:
        raise ConfigError(f"unknown optimiser {name!r}; known: {', '.join(_REGISTRY)}")
    entry = _REGISTRY[name]
    fps = _check_fps(fps)
    _model_arrays(model)  # a clear error for a missing or incomplete model
    if not callable(getattr(model, "group", None)):
        raise ConfigError("model lacks group(name); need param_names, sigma, lower, upper, group()")
    pre = {k: overrides.pop(k) for k in list(overrides) if k in entry.pre_options}
    cfg = entry.factory(model, fps, **pre)
    if overrides:
        valid = {f.name for f in dataclasses.fields(cfg)} - {"name", "param_names"}
        unknown = sorted(set(overrides) - valid)
        if unknown:
            raise ConfigError(
                f"{name}: unknown override(s) {unknown}; valid: {sorted(valid | set(entry.pre_options))}"
            )
        try:
            cfg = dataclasses.replace(cfg, **overrides)
        except (TypeError, ValueError) as exc:
            if isinstance(exc, ConfigError):
                raise
            raise ConfigError(f"{name}: bad override: {exc}") from exc
    return cfg
