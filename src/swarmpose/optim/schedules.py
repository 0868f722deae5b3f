"""Ready-made stage schedules, built from a body model's named parameter groups.

The model is duck-typed: only ``model.param_names`` (D names) and ``model.group(name) -> indices`` are used
here. Group names (``balan31`` indices, 0-based): ``root_orientation`` x1-x3, ``root_position`` x4-x6,
``left_leg`` x7-x10, ``right_leg`` x11-x14, ``left_arm`` x15-x20, ``right_arm`` x21-x26, ``spine`` x27-x28,
``head`` x29-x31 and ``head_twist`` x31. Optional groups (``spine``, ``head``, ``head_twist``,
``lower_limbs``) may be missing (``KeyError``) and are then empty.

Fitness options vocabulary (read by the tracker's fitness through ``Optimizer.fitness_options``):

``edge_cones``
    Which cones are sampled for the edge fitness: ``"torso"``, ``"torso+upper_limbs"`` (torso, upper arms,
    thighs) or ``"all"``. The head cone is never in the edge fitness ([FL12] sec. 5.2.1).
``edge_top``
    Also sample the torso's upper edge ([FL12] sec. 5.2.1 and 6.10; used in every stage).

The silhouette fitness always covers the full body ([FL12] Table 6.1, 6.3).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import ConfigError
from .staged import Stage

__all__ = [
    "EDGE_ALL",
    "EDGE_TORSO",
    "EDGE_TORSO_UPPER",
    "aapso_stages",
    "global_stages",
    "hard2_stages",
    "head_twist_indices",
    "hpso12_stages",
    "lower_limb_indices",
    "sppso3_stages",
    "sppso_stages",
]

EDGE_TORSO = {"edge_cones": "torso", "edge_top": True}
EDGE_TORSO_UPPER = {"edge_cones": "torso+upper_limbs", "edge_top": True}
EDGE_ALL = {"edge_cones": "all", "edge_top": True}

_LIMBS = ("left_leg", "right_leg", "left_arm", "right_arm")


def _group(model: Any, name: str, *, required: bool = True) -> np.ndarray:
    try:
        idx = np.asarray(model.group(name), dtype=np.int64).ravel()
    except (KeyError, ValueError, LookupError):
        if required:
            raise ConfigError(
                f"the body model has no parameter group {name!r}, which this schedule needs"
            ) from None
        return np.empty(0, dtype=np.int64)
    d = len(model.param_names)
    if idx.size and (idx.min() < 0 or idx.max() >= d):
        raise ConfigError(f"group {name!r} has indices outside 0..{d - 1}")
    return idx


def _dim(model: Any) -> int:
    return len(model.param_names)


def _root(model: Any) -> tuple[np.ndarray, np.ndarray]:
    return _group(model, "root_orientation"), _group(model, "root_position")


def head_twist_indices(model: Any) -> np.ndarray:
    """The head twist x31, held fixed in every thesis experiment ([FL12] 6.1); empty if the model has none."""
    return _group(model, "head_twist", required=False)


def _all_but_twist(model: Any) -> np.ndarray:
    """All parameters except the head twist (x31 is held fixed in every thesis experiment, [FL12] 6.1)."""
    keep = np.ones(_dim(model), dtype=bool)
    keep[head_twist_indices(model)] = False
    return np.flatnonzero(keep)


def lower_limb_indices(model: Any) -> np.ndarray:
    """Parameters that only move the lower limbs (forearms, calves).

    ``model.group("lower_limbs")`` when the model defines it; otherwise the last two parameters of each limb
    group (the twist about the upper segment's axis and the elbow/knee hinge). For ``balan31`` this is the
    thesis's list x9, x10, x13, x14, x19, x20, x25, x26 ([FL12] sec. 6.6).
    """
    own = _group(model, "lower_limbs", required=False)
    if own.size:
        return own
    parts = []
    for limb in _LIMBS:
        g = _group(model, limb)
        if g.size < 3:
            raise ConfigError(f"group {limb!r} has {g.size} parameters; cannot split upper/lower limb")
        parts.append(g[-2:])
    return np.concatenate(parts)


def sppso_stages(model: Any) -> tuple[Stage, ...]:
    """SPPSO base configuration ([FL12] Table 6.1, sec. 5.3.3): 10 x 20 + 20 x 40 = 1000 evaluations.

    Stage 1: x1-x6 (root orientation and position), standard sigma, edge fitness on the torso only.
    Stage 2: all parameters (head twist fixed), sigma of x4-x6 divided by 10, edge fitness on all cones.
    """
    d = _dim(model)
    rot, pos = _root(model)
    return (
        Stage.from_groups("root", d, [(rot, 1.0), (pos, 1.0)], 10, 20, EDGE_TORSO),
        Stage.from_groups("all", d, [(_all_but_twist(model), 1.0), (pos, 0.1)], 20, 40, EDGE_ALL),
    )


def hard2_stages(model: Any) -> tuple[Stage, ...]:
    """SPPSO with hard partitions: identical, but x1-x6 held fixed in stage 2 ([FL12] sec. 6.6, Fig. 6.10)."""
    d = _dim(model)
    rot, pos = _root(model)
    return (
        Stage.from_groups("root", d, [(rot, 1.0), (pos, 1.0)], 10, 20, EDGE_TORSO),
        Stage.from_groups(
            "joints", d, [(_all_but_twist(model), 1.0), (rot, 0.0), (pos, 0.0)], 20, 40, EDGE_ALL
        ),
    )


def global_stages(model: Any) -> tuple[Stage, ...]:
    """One global stage of 25 particles x 40 iterations ([FL12] sec. 6.6, Fig. 6.11-6.12)."""
    return (Stage.from_groups("all", _dim(model), [(_all_but_twist(model), 1.0)], 25, 40, EDGE_ALL),)


def sppso3_stages(model: Any) -> tuple[Stage, ...]:
    """SPPSO with three partitions ([FL12] sec. 6.6, Table 6.3): 10 x 20 + 10 x 40 + 10 x 40 = 1000.

    1. x1-x6, standard sigma; edge fitness: torso.
    2. all parameters except those that only move the lower limbs (x9, x10, x13, x14, x19, x20, x25, x26)
       and the head twist; sigma of x4-x6 / 10; edge fitness: torso + upper limbs.
    3. all parameters (head twist fixed): sigma of x1-x6 / 10, parameters optimised in stage 2 (other than
       x1-x6) / 2, the remaining ones (lower limbs) * sqrt(2); edge fitness: all.
    """
    d = _dim(model)
    rot, pos = _root(model)
    root = np.concatenate([rot, pos])
    everything = _all_but_twist(model)
    lower = lower_limb_indices(model)
    stage2 = np.setdiff1d(everything, lower)
    return (
        Stage.from_groups("root", d, [(root, 1.0)], 10, 20, EDGE_TORSO),
        Stage.from_groups("upper", d, [(stage2, 1.0), (pos, 0.1)], 10, 40, EDGE_TORSO_UPPER),
        Stage.from_groups(
            "all",
            d,
            [(everything, np.sqrt(2.0)), (stage2, 0.5), (root, 0.1)],
            10,
            40,
            EDGE_ALL,
        ),
    )


def hpso12_stages(model: Any) -> tuple[Stage, ...]:
    """Twelve hard partitions as in John, Trucco & Ivekovic 2010 (HPSO), 10 x 60 each = 7200 evaluations.

    The thesis ([FL12] sec. 6.6, Fig. 6.14; Table 4.3) gives the number of partitions (12), their size
    (10 particles, 60 iterations) and that they follow the kinematic hierarchy; it does not list them. We use
    the hierarchy root -> torso -> limbs (proximal, then distal) -> head:
    1 root position, 2 root orientation, 3 spine, 4/5 left upper/lower arm, 6/7 right upper/lower arm,
    8/9 left upper/lower leg, 10/11 right upper/lower leg, 12 head (twist fixed). "Lower" is
    :func:`lower_limb_indices` (the distal twist + hinge), "upper" the rest of the limb group. Every stage is
    a hard partition (all other parameters held); the fitness covers all cones.
    """
    d = _dim(model)
    rot, pos = _root(model)
    lower = set(lower_limb_indices(model).tolist())
    twist = set(_group(model, "head_twist", required=False).tolist())
    parts: list[tuple[str, np.ndarray]] = [("root_position", pos), ("root_orientation", rot)]
    parts.append(("spine", _group(model, "spine", required=False)))
    for limb in ("left_arm", "right_arm", "left_leg", "right_leg"):
        g = _group(model, limb)
        parts.append((f"{limb}_upper", np.array([i for i in g if i not in lower], dtype=np.int64)))
        parts.append((f"{limb}_lower", np.array([i for i in g if i in lower], dtype=np.int64)))
    head = _group(model, "head", required=False)
    parts.append(("head", np.array([i for i in head if i not in twist], dtype=np.int64)))
    empty = [name for name, idx in parts if idx.size == 0]
    if empty:
        raise ConfigError(f"hpso12 needs 12 non-empty partitions; empty for this model: {empty}")
    return tuple(Stage.from_groups(name, d, [(idx, 1.0)], 10, 60, EDGE_ALL) for name, idx in parts)


def aapso_stages(model: Any) -> tuple[Stage, ...]:
    """Six soft stages of the adaptive annealed PSO ([SH17] sec. 3.4, 4.2): 5 x 80 x 10 + 30 x 10 = 4300.

    1. torso (root orientation + root position + spine when the model has one), standard sigma;
    2-5. left arm, right arm, left leg, right leg; 6. head -- each with its own group at standard sigma and
    the torso at sigma / 10 ("a trivial search about the result of stage one"); all other parameters held.
    80 particles x 10 iterations in stages 1-5, 30 x 10 in stage 6. The paper's fitness (markers) has no
    per-stage options.

    Deviation: the paper's stage 1 has "six parameters related to global position and orientation of
    torso" and none of its six stages names a spine. A model with spine joints (balan31 x27-x28, full45's
    trunk) puts them in stage 1 with the root (the spine carries the shoulders and head, whose markers
    stage 1 scores) and holds them to sigma / 10 with the root afterwards; without it they would never
    be searched.
    """
    d = _dim(model)
    rot, pos = _root(model)
    torso = np.concatenate([rot, pos, _group(model, "spine", required=False)])
    stages = [Stage.from_groups("torso", d, [(torso, 1.0)], 80, 10)]
    for name in ("left_arm", "right_arm", "left_leg", "right_leg", "head"):
        n = 30 if name == "head" else 80
        stages.append(Stage.from_groups(name, d, [(torso, 0.1), (_group(model, name), 1.0)], n, 10))
    return tuple(stages)
