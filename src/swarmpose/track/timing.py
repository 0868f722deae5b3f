"""Where a run's time goes: exclusive wall time per part of the frame loop (``swarmpose bench track``)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["PARTS", "PartTimer", "TimedFitness"]

#: The parts of a frame, in loop order.
PARTS = ("features", "motion", "optimiser", "fitness", "priors", "recovery", "keypoint_ik", "consensus", "writing")


class PartTimer:
    """Exclusive wall time per named part: a part's time excludes the parts timed inside it
    (the optimiser's time is its own bookkeeping, without the fitness and the hard priors it calls)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = dict.fromkeys(PARTS, 0.0)
        self._children: list[float] = []

    @contextmanager
    def part(self, name: str) -> Iterator[None]:
        t0 = time.perf_counter()
        self._children.append(0.0)
        try:
            yield
        finally:
            inner = self._children.pop()
            dt = time.perf_counter() - t0
            self.seconds[name] = self.seconds.get(name, 0.0) + dt - inner
            if self._children:
                self._children[-1] += dt

    def wrap(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn`` with every call timed as ``name``."""

        def timed(*args: Any, **kwargs: Any) -> Any:
            with self.part(name):
                return fn(*args, **kwargs)

        return timed


class TimedFitness:
    """A fitness whose evaluations are timed as ``"fitness"`` (binding as ``"features"``)."""

    def __init__(self, fitness: Any, timer: PartTimer) -> None:
        self._fitness = fitness
        self._timer = timer

    def bind(self, frame: Any) -> TimedFitness:
        with self._timer.part("features"):
            self._fitness.bind(frame)
        return self

    def evaluate(self, poses: Any, options: Any = None) -> Any:
        with self._timer.part("fitness"):
            return self._fitness.evaluate(poses, options)

    def __call__(self, poses: Any) -> Any:
        return self.evaluate(poses)

    @property
    def features(self) -> Any:
        """The bound frame's features (an image fitness's), else None."""
        prepared = getattr(self._fitness, "prepared", None)
        return None if prepared is None else prepared.features

    def part_agreement(self, poses: Any) -> Any:
        with self._timer.part("fitness"):
            return self._fitness.part_agreement(poses)
