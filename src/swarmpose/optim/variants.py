"""Variants of a named optimiser configuration (``--variant``), each stating its budget."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from .base import ConfigError

__all__ = ["apply_variant"]


def _number(variant: str, off: float | None = None) -> float:
    """The number after ``=`` in ``variant`` (``off`` where it says ``off`` and ``off`` is given); NaN when it is none."""
    value = variant.partition("=")[2].strip()
    if off is not None and value == "off":
        return off
    try:
        return float(value)
    except ValueError:
        return float("nan")


def apply_variant(config: Any, variant: str) -> Any:
    """Modify a named optimiser configuration; every variant states its budget.

    * ``budget=B`` (SPPSO family): every stage's iterations × B/1000 (thesis 6.4 gives only the
      totals 1000/2000/4000; scaling iterations keeps the swarm sizes of Table 6.1).
    * ``stage2=PxI``: the last stage runs P particles × I iterations (thesis 6.8, Table 6.4).
    * ``global=PxI`` (AAPSO): one stage over all parameters (Sharifi et al. Table 4: 400 × 10).
    * ``hard``: each stage after the first holds the earlier stages' parameters fixed (σ scale 0)
      instead of searching them at σ/10 (Sharifi et al. Table 5; thesis 6.6 hard partitioning).
    * ``apf=PxL`` (annealed particle filters): P particles × L layers (Sharifi et al. sec. 4.10 ran
      Deutscher & Reid's APF with 700 × 5).
    * ``spread=K``: the search's per-parameter sigma times K.
    * ``refine=B`` (refined configurations): B pattern-search evaluations (0: none); ``recovery=off``: no
      loss detection; ``recovery=T``: a limb counts as lost above a disagreement of T (default 0.05; the
      search per lost limb unchanged); ``recovery=all``: every limb searched again on every frame;
      ``recovery_terms=fitness``: the limbs searched again and kept by the frame's own fitness (``distance``:
      the silhouette distance term, the default; ``silhouette``: the silhouette overlap term alone); ``recovery_margin=M``: a searched-again limb kept only when
      it scores more than M above the one it replaces; ``recovery_jump=R``: and R more per 100 mm that its joints move
      (``off``: 0); ``recovery_guard=silhouette``: a searched-again limb kept
      only when the silhouette overlap term does not fall either; ``recovery_in_turn=K``: only K limbs looked at per frame,
      in turn (with ``recovery=all`` each limb is searched every 4/K frames); ``recovery_search=SxR``: each searched limb's
      box search asks S poses in each of R rounds (default 100 x 5), ``recovery_refine=B``: then B pattern-search
      evaluations (default 100); ``height=silhouettes``: the predicted root height moves by the rise of
      the silhouettes' triangulated centre since the frame before, ``height=keypoints``: by the rise of the trunk's
      triangulated keypoints where the sequence has them, else as ``silhouettes`` (``height=off``: not); ``turn=on``: the body's
      heading searched again on every frame (the pose and its pelvis alone turned, the best polished:
      ``swarmpose.track.turn``, 318 evaluations); ``turn_margin=M``: a turned pose kept only when it scores
      more than M above the frame's pose; ``lean=on``: the trunk's lean searched again on every frame, the pelvis
      pitched against the spine and the hips (``swarmpose.track.lean``, 207 evaluations); ``turn_keypoints=on``:
      also the turn that lays the model's hips onto the frame's triangulated keypoints (sequences with keypoints);
      ``heading_speed=D``: the part of the heading's last step beyond D degrees carried on into the prediction; ``keypoint_ik=on``: each frame's pose fitted to the triangulated
      keypoints from where the searches left it, kept when it scores higher (sequences with keypoints);
      ``keypoint_ik_polish=B``: where that fit scores no higher than the frame's pose, B pattern-search evaluations
      from it, kept when they score higher (``off``: 0; needs ``keypoint_ik``);
      ``keypoint_proposals=F``: before each frame's search, the pose fitted to the frame's triangulated keypoints
      from the prediction takes share F of the carried particle set's weight (``off``: 0; sequences with keypoints);
      ``members=K``: K searches of every frame side by side, the frame's pose their consensus (K >= 3; 1: one
      search; K times the evaluations); ``members_reset=M``: a member with a joint more than M mm from the consensus
      goes on from it (default 80; ``off``: never);
      ``head=B``: on a sequence with a detector's keypoints, B pattern-search evaluations over the head's parameters
      after the limbs' searches, kept when they score higher (``off``: 0);
      ``coupled_limits=on``: the hard priors also reject the body model's coupled limits (the shoulders' second
      branch of angles; on in the default tracker, ``off`` turns them off); several variants are joined by ``+``
      (``apf=200x5+refine=0``).
    """
    if not variant:
        return config
    if "+" in variant:
        for part in variant.split("+"):
            config = apply_variant(config, part)
        return config
    head = variant.partition("=")[0].strip()
    if head == "height":
        value = variant.partition("=")[2].strip()
        if not hasattr(config, "silhouette_height") or value not in ("silhouettes", "keypoints", "off"):
            raise ConfigError(f"variant {variant!r}: expected height=silhouettes, height=keypoints or height=off on a "
                              f"refined configuration ({config.name!r})")
        return dataclasses.replace(config, silhouette_height=value != "off", keypoint_height=value == "keypoints")
    if head in ("turn", "lean", "keypoint_ik", "coupled_limits"):
        field, on = {"turn": ("turn_search", "on"),
                     "lean": ("lean_search", "on"), "keypoint_ik": ("keypoint_ik", "on"),
                     "coupled_limits": ("coupled_limits", "on")}[head]
        value = variant.partition("=")[2].strip()
        if not hasattr(config, field) or value not in (on, "off"):
            raise ConfigError(f"variant {variant!r}: expected {head}={on} or {head}=off on a refined "
                              f"configuration ({config.name!r})")
        if head == "turn":
            from .registry import TURN_SEARCH

            return dataclasses.replace(config, turn_search=TURN_SEARCH if value == on else {})
        if head == "lean":
            from .registry import LEAN_SEARCH

            return dataclasses.replace(config, lean_search=LEAN_SEARCH if value == on else {})
        return dataclasses.replace(config, **{field: value == on})
    if head == "heading_speed":
        value = variant.partition("=")[2].strip()
        try:
            d = None if value == "off" else float(value)
        except ValueError:
            d = float("nan")
        if not hasattr(config, "heading_speed") or not (d is None or (math.isfinite(d) and d >= 0)):
            raise ConfigError(f"variant {variant!r}: expected heading_speed=D (degrees per frame, >= 0) or "
                              f"heading_speed=off on a refined configuration ({config.name!r})")
        return dataclasses.replace(config, heading_speed=d)
    if head == "keypoint_ik_polish":
        value = variant.partition("=")[2].strip()
        if not getattr(config, "keypoint_ik", False) or not (value == "off" or value.isdigit()):
            raise ConfigError(f"variant {variant!r}: expected keypoint_ik_polish=B (pattern-search evaluations, a "
                              f"whole number >= 0) or keypoint_ik_polish=off on a configuration with the keypoint fit "
                              f"({config.name!r}: add keypoint_ik=on first)")
        return dataclasses.replace(config, keypoint_ik_polish=0 if value == "off" else int(value))
    if head == "head":
        value = variant.partition("=")[2].strip()
        if not hasattr(config, "head_search") or not (value == "off" or value.isdigit()):
            raise ConfigError(f"variant {variant!r}: expected head=B (pattern-search evaluations over the head, a whole "
                              f"number >= 0) or head=off on a refined configuration ({config.name!r})")
        return dataclasses.replace(config, head_search=0 if value == "off" else int(value))
    if head == "keypoint_proposals":
        f = _number(variant, off=0.0)
        if not hasattr(config, "keypoint_proposals") or not 0.0 <= f < 1.0:
            raise ConfigError(f"variant {variant!r}: expected keypoint_proposals=F (a share of the carried particle "
                              f"set's weight, 0 <= F < 1) or keypoint_proposals=off on a refined configuration "
                              f"({config.name!r})")
        return dataclasses.replace(config, keypoint_proposals=f)
    if head in ("members", "members_reset"):
        value = variant.partition("=")[2].strip()
        if head == "members":
            ok = value.isdigit() and (int(value) == 1 or int(value) >= 3)
            form = "members=K (searches side by side: 1, or a whole number >= 3)"
        else:
            try:
                mm = math.inf if value == "off" else float(value)
            except ValueError:
                mm = float("nan")
            ok = mm > 0
            form = "members_reset=M (mm, > 0) or members_reset=off"
        if not hasattr(config, "members") or not ok:
            raise ConfigError(f"variant {variant!r}: expected {form} on a refined configuration ({config.name!r})")
        return dataclasses.replace(config, **({"members": int(value)} if head == "members" else {"members_reset": mm}))
    if head == "turn_keypoints":
        value = variant.partition("=")[2].strip()
        if not getattr(config, "turn_search", None) or value not in ("on", "off"):
            raise ConfigError(f"variant {variant!r}: expected turn_keypoints=on or turn_keypoints=off on a "
                              f"configuration with the turn search ({config.name!r}: add turn=on first)")
        return dataclasses.replace(config, turn_search={**dict(config.turn_search), "keypoints": value == "on"})
    if head == "turn_margin":
        m = _number(variant)
        if not getattr(config, "turn_search", None) or not (math.isfinite(m) and m >= 0):
            raise ConfigError(f"variant {variant!r}: expected turn_margin=M, a score margin >= 0, on a configuration "
                              f"with the turn search ({config.name!r}: add turn=on first)")
        return dataclasses.replace(config, turn_search={**dict(config.turn_search), "margin": m})
    if head == "recovery_margin":
        m = _number(variant)
        if not getattr(config, "recovery", None) or not (math.isfinite(m) and m >= 0):
            raise ConfigError(f"variant {variant!r}: expected recovery_margin=M, a score margin >= 0, on a "
                              f"configuration with limb recovery ({config.name!r})")
        return dataclasses.replace(config, recovery={**dict(config.recovery), "margin": m})
    if head == "recovery_jump":
        m = _number(variant, off=0.0)
        if not getattr(config, "recovery", None) or not (math.isfinite(m) and m >= 0):
            raise ConfigError(f"variant {variant!r}: expected recovery_jump=R, a score margin >= 0 per 100 mm that the "
                              f"searched limb's joints move, or off, on a configuration with limb recovery "
                              f"({config.name!r})")
        return dataclasses.replace(config, recovery={**dict(config.recovery), "jump": m})
    if head == "recovery_guard":
        value = variant.partition("=")[2].strip()
        if not getattr(config, "recovery", None) or value not in ("silhouette", "off"):
            raise ConfigError(f"variant {variant!r}: expected recovery_guard=silhouette or recovery_guard=off on a "
                              f"configuration with limb recovery ({config.name!r})")
        return dataclasses.replace(config, recovery={**dict(config.recovery), "guard": "" if value == "off" else value})
    if head == "recovery_in_turn":
        value = variant.partition("=")[2].strip()
        if not getattr(config, "recovery", None) or not value.isdigit() or int(value) < 1:
            raise ConfigError(f"variant {variant!r}: expected recovery_in_turn=K, a whole number of limbs >= 1 per "
                              f"frame, on a configuration with limb recovery ({config.name!r})")
        return dataclasses.replace(config, recovery={**dict(config.recovery), "in_turn": int(value)})
    if head == "recovery_search":
        parts = variant.partition("=")[2].lower().split("x")
        if (not getattr(config, "recovery", None) or len(parts) != 2
                or not all(p.strip().isdigit() and int(p) >= 1 for p in parts)):
            raise ConfigError(f"variant {variant!r}: expected recovery_search=SxR (S poses in each of R rounds of a "
                              f"limb's box search, two whole numbers >= 1, e.g. recovery_search=50x3) on a "
                              f"configuration with limb recovery ({config.name!r})")
        return dataclasses.replace(config, recovery={**dict(config.recovery), "n_samples": int(parts[0]),
                                                     "n_rounds": int(parts[1])})
    if head == "recovery_refine":
        value = variant.partition("=")[2].strip()
        if not getattr(config, "recovery", None) or not value.isdigit():
            raise ConfigError(f"variant {variant!r}: expected recovery_refine=B, a whole number of pattern-search "
                              f"evaluations per searched limb, on a configuration with limb recovery ({config.name!r})")
        return dataclasses.replace(config, recovery={**dict(config.recovery), "refine_budget": int(value)})
    if head == "recovery_terms":
        value = variant.partition("=")[2].strip()
        if not getattr(config, "recovery", None) or value not in ("distance", "fitness", "silhouette"):
            raise ConfigError(f"variant {variant!r}: expected recovery_terms=distance, fitness or silhouette on a "
                              f"configuration with limb recovery ({config.name!r})")
        return dataclasses.replace(config, recovery={**dict(config.recovery), "terms": value})
    if head in ("refine", "recovery"):
        if not hasattr(config, "refine_budget"):
            raise ConfigError(f"variant {variant!r} needs a refined configuration, {config.name!r} is not one")
        value = variant.partition("=")[2].strip()
        if head == "refine":
            if not value.isdigit():
                raise ConfigError(f"variant {variant!r}: expected refine=B, a whole number of evaluations")
            return dataclasses.replace(config, refine_budget=int(value))
        if value == "off":
            return dataclasses.replace(config, recovery={})
        if value == "all" and config.recovery:
            return dataclasses.replace(config, recovery={**dict(config.recovery), "threshold": -1.0})
        try:
            threshold = float(value)
        except ValueError:
            threshold = float("nan")
        if not 0.0 < threshold < 1.0 or not config.recovery:
            raise ConfigError(f"variant {variant!r}: expected recovery=off or recovery=T with 0 < T < 1 (the "
                              f"disagreement above which a limb is lost; {config.name!r} "
                              f"{'has' if config.recovery else 'has no'} limb recovery)")
        return dataclasses.replace(config, recovery={**dict(config.recovery), "threshold": threshold})
    if hasattr(config, "base") and hasattr(config, "refine_budget"):
        return dataclasses.replace(config, base=apply_variant(config.base, variant))
    if head == "spread":
        try:
            k = float(variant.partition("=")[2])
        except ValueError:
            k = float("nan")
        if not k > 0:
            raise ConfigError(f"variant {variant!r}: expected spread=K with K > 0 (the search's sigma times K)")
        return dataclasses.replace(config, sigma=config.sigma * k)
    from .staged import Stage

    key, sep, value = (t.strip() for t in variant.partition("="))
    forms = {"budget": "budget=B, e.g. budget=2000", "stage2": "stage2=PxI, e.g. stage2=40x20",
             "global": "global=PxI, e.g. global=400x10", "apf": "apf=PxL, e.g. apf=700x5", "hard": "hard"}
    if key not in forms:
        raise ConfigError(f"unknown variant {variant!r} (budget=B, stage2=PxI, global=PxI, hard, apf=PxL)")
    if (key == "hard") == bool(sep):
        raise ConfigError(f"variant {variant!r}: expected {forms[key]}")

    def sizes() -> tuple[int, int]:
        parts = value.lower().split("x")
        if len(parts) != 2 or not all(p.strip().isdigit() and int(p) >= 1 for p in parts):
            raise ConfigError(f"variant {variant!r}: expected {forms[key]} (two whole numbers >= 1)")
        return int(parts[0]), int(parts[1])

    if key == "apf":
        if not hasattr(config, "n_layers"):
            raise ConfigError(f"variant {variant!r} needs an annealed particle filter, {config.name!r} is not one")
        p, layers = sizes()
        return dataclasses.replace(config, n_particles=p, n_layers=layers)
    stages = getattr(config, "stages", None)
    if stages is None:
        raise ConfigError(f"variant {variant!r} needs a staged configuration, {config.name!r} has no stages")
    if key == "budget":
        if not value.isdigit() or int(value) < 1000 or int(value) % 1000:
            raise ConfigError(f"variant {variant!r}: B must be 1000, 2000, 3000... (every stage's iterations x B/1000: "
                              f"B evaluations per frame for the thesis's 1000-evaluation configurations)")
        factor = int(value) / 1000.0
        new = tuple(dataclasses.replace(s, n_iterations=int(round(s.n_iterations * factor))) for s in stages)
    elif key == "stage2":
        p, i = sizes()
        new = (*stages[:-1], dataclasses.replace(stages[-1], n_particles=p, n_iterations=i))
    elif key == "global":
        import numpy as np

        p, i = sizes()
        active = np.logical_or.reduce([s.active for s in stages])
        # the whole body at once: the last stage's fitness (SPPSO's first stage scores only the torso's edges)
        new = (Stage("global", active, np.ones(active.shape[0]), p, i, dict(stages[-1].fitness_options)),)
    else:  # hard
        first = stages[0].active
        new = (stages[0],) + tuple(
            dataclasses.replace(s, active=s.active & ~first, sigma_scale=s.sigma_scale) for s in stages[1:])
    return dataclasses.replace(config, stages=new)
