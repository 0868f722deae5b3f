"""Motion models: where each frame's search is centred, from the estimates of the frames before it.

The thesis predicts with a zero-velocity model (sec. 5.3.2): the swarm of frame ``t`` starts at
``N(x̂_{t-1}, Σ)``, with ``Σ`` scaled by 60/fps (the optimiser registry does the scaling). That is
the default, and every compare suite uses it. ``constant-velocity[:d]`` is an extension none of the
three papers uses: the centre moves on by ``d`` times the last step,

    x̃_t = x̂_{t-1} + d (x̂_{t-1} - x̂_{t-2}),    d = 1 unless given,

and the spread ``Σ`` stays the same. ``constant-velocity[:d]@root_position`` (groups joined by
``+``, as :meth:`swarmpose.body.model.BodyModel.groups` names them: ``root``, ``left_leg``, ..., or single
parameters by name: ``pelvis_tx``) moves only those parameters on and keeps the others at ``x̂_{t-1}``; a group written
``GROUP*F`` carries its own fraction ``F`` of the last step instead of ``d`` (``@pelvis_tx+pelvis_ty+pelvis_rz*0.5``:
the heading half as far as the position). It needs two tracked estimates, so the
first two frames use zero velocity. A prediction that breaks the body model's hard priors (joint limits, collisions) is
not used: that frame falls back to zero velocity. A carried particle set (the APF's, Deutscher & Reid
eq. 9) moves by the same step, particle by particle where the moved particle stays valid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.optim.base import Constraint

__all__ = ["MotionModel", "parse_motion", "MOTION_MODELS"]

MOTION_MODELS = ("zero-velocity", "constant-velocity")


@dataclass(frozen=True)
class MotionModel:
    """A named motion model; ``fraction`` is ``d`` of the constant-velocity model (0 for zero velocity)."""

    name: str = "zero-velocity"
    fraction: float = 0.0
    groups: tuple[str, ...] = ()  # parameter groups that move on; () = all
    group_fractions: tuple[float | None, ...] = ()  # a group's own fraction (None: ``fraction``); () = none

    def __post_init__(self) -> None:
        if self.name not in MOTION_MODELS:
            raise ConfigError(f"unknown motion model {self.name!r}; known: {', '.join(MOTION_MODELS)}")
        if self.group_fractions and len(self.group_fractions) != len(self.groups):
            raise ConfigError(f"motion model {self.name!r}: one fraction per group, got {len(self.group_fractions)} "
                              f"for {len(self.groups)}")

    def _group_fraction(self, k: int) -> float:
        f = self.group_fractions[k] if self.group_fractions else None
        return self.fraction if f is None else float(f)

    def mask(self, model: Any) -> np.ndarray | None:
        """``(D,)`` float: the fraction of its last step each parameter of ``model`` carries on (0: it stays; None:
        every parameter carries ``fraction``)."""
        if not self.groups:
            return None
        mask = np.zeros(model.n_params, dtype=np.float64)
        for k, g in enumerate(self.groups):
            if g in model.param_names:  # a single parameter, e.g. pelvis_tx
                mask[model.param_index(g)] = self._group_fraction(k)
                continue
            try:
                mask[model.group(g)] = self._group_fraction(k)
            except KeyError as e:
                raise ConfigError(f"motion model {str(self)!r}: {e.args[0]} (or a parameter's name)") from None
        return mask

    def predict(self, history: np.ndarray, constraint: Constraint | None = None,
                mask: np.ndarray | None = None) -> np.ndarray:
        """The centre of the next frame's search from ``history`` ``(k, D)``, oldest first (``k >= 1``);
        ``mask`` (from :meth:`mask`) gives each parameter's fraction of the last step (0: it stays)."""
        history = np.asarray(history, dtype=np.float64)
        if history.ndim != 2 or len(history) == 0:
            raise ValueError(f"history must be (k >= 1, D), got shape {history.shape}")
        last = history[-1]
        if self.name == "zero-velocity" or len(history) < 2:
            return last.copy()
        if mask is None:
            step = self.fraction * (last - history[-2])
        else:
            step = np.where(np.asarray(mask, dtype=np.float64) != 0.0, np.asarray(mask, dtype=np.float64)
                            * (last - history[-2]), 0.0)
        if not np.any(step):
            return last.copy()
        predicted = last + step
        if constraint is not None and not bool(np.asarray(constraint(predicted[None]))[0]):
            return last.copy()
        return predicted

    @staticmethod
    def move_particles(particles: np.ndarray, step: np.ndarray, constraint: Constraint | None = None) -> np.ndarray:
        """Move a carried particle set ``(N, D)`` by ``step``; particles the step would make invalid stay
        where they were (the set then splits between old and new places; its weights are kept)."""
        if not np.any(step):
            return particles
        moved = particles + step[None, :]
        if constraint is not None:
            ok = np.asarray(constraint(moved), dtype=bool)
            moved[~ok] = particles[~ok]
        return moved

    def __str__(self) -> str:
        """The canonical text ``parse_motion`` reads back to an equal model."""
        text = self.name
        if self.name == "constant-velocity" and self.fraction != 1.0:
            text += f":{self.fraction!r}"
        groups = [g if not self.group_fractions or self.group_fractions[k] is None else f"{g}*{self.group_fractions[k]!r}"
                  for k, g in enumerate(self.groups)]
        return text + ("@" + "+".join(groups) if groups else "")


def parse_motion(text: str) -> MotionModel:
    """``"zero-velocity"`` or ``"constant-velocity[:D][@GROUP[*F]+GROUP[*F]...]"`` with ``0 <= D, F <= 1``.

    Group names are checked against a body model by :meth:`MotionModel.mask`.
    """
    head, at, group_text = (text or "zero-velocity").strip().partition("@")
    groups_f = [g.strip().partition("*") for g in group_text.split("+") if g.strip()]
    groups = tuple(g.strip() for g, _, _ in groups_f)
    own: list[float | None] = []
    for g, star, f in groups_f:
        if not star:
            own.append(None)
            continue
        try:
            value = float(f)
        except ValueError:
            value = float("nan")
        if not 0.0 <= value <= 1.0:
            raise ConfigError(f"motion model {text!r}: {g.strip()}*F needs F, the fraction of the group's last step "
                              f"carried on, in [0, 1]; got {f.strip()!r}")
        own.append(value)
    group_fractions = tuple(own) if any(f is not None for f in own) else ()
    if at and not groups:
        raise ConfigError(f"motion model {text!r}: name at least one parameter group after '@' "
                          "(e.g. constant-velocity@root_position)")
    name, sep, arg = head.strip().partition(":")
    if name not in MOTION_MODELS:
        raise ConfigError(f"unknown motion model {text!r}; known: zero-velocity, constant-velocity[:D] "
                          "(D, the fraction of the last step carried on, in [0, 1])")
    if name == "zero-velocity":
        if sep or at:
            raise ConfigError(f"motion model {text!r}: zero-velocity takes no ':D' and no '@GROUPS'")
        return MotionModel()
    try:
        fraction = float(arg) if sep else 1.0
    except ValueError:
        raise ConfigError(f"motion model {text!r}: expected constant-velocity:D with D a number in [0, 1]") from None
    if not 0.0 <= fraction <= 1.0:
        raise ConfigError(f"motion model {text!r}: D must lie in [0, 1], got {fraction!r}")
    return MotionModel(name, fraction, groups, group_fractions)
