"""Fake body models for the optimiser tests (duck-typed like ``swarmpose.body``; no import of it)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest


@dataclass(frozen=True, eq=False)
class FakeModel:
    """``param_names``, ``sigma`` (60 fps), ``lower``, ``upper``, ``group(name)``; unknown groups -> KeyError."""

    param_names: tuple[str, ...]
    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    groups: dict[str, np.ndarray] = field(default_factory=dict)

    def group(self, name: str) -> np.ndarray:
        try:
            return self.groups[name]
        except KeyError:
            raise KeyError(f"no group {name!r}") from None


def make_balan31() -> FakeModel:
    """31 parameters in the thesis's layout (Table 5.1), 0-based groups as in the design contract."""
    d = 31
    sigma = np.full(d, 0.09)
    sigma[3:6] = 13.7  # mm per frame at 60 fps (thesis sec. 5.3.2: sigma_4 = 13.7 mm)
    sigma[9] = 0.093  # left knee (thesis sec. 5.3.2)
    lower = np.full(d, -np.pi)
    upper = np.full(d, np.pi)
    lower[3:6], upper[3:6] = -np.inf, np.inf
    groups = {
        "root_orientation": np.arange(0, 3),
        "root_position": np.arange(3, 6),
        "left_leg": np.arange(6, 10),
        "right_leg": np.arange(10, 14),
        "left_arm": np.arange(14, 20),
        "right_arm": np.arange(20, 26),
        "spine": np.arange(26, 28),
        "head": np.arange(28, 31),
        "head_twist": np.array([30]),
    }
    return FakeModel(tuple(f"x{i + 1}" for i in range(d)), sigma, lower, upper, groups)


def make_marker45() -> FakeModel:
    """A 45-parameter model with the same group names and other sizes (no head twist, longer limbs)."""
    sizes = [
        ("root_orientation", 3),
        ("root_position", 3),
        ("left_leg", 6),
        ("right_leg", 6),
        ("left_arm", 7),
        ("right_arm", 7),
        ("spine", 6),
        ("head", 7),
    ]
    groups, start = {}, 0
    for name, n in sizes:
        groups[name] = np.arange(start, start + n)
        start += n
    d = start
    sigma = np.full(d, 0.08)
    sigma[groups["root_position"]] = 20.0
    return FakeModel(tuple(f"p{i}" for i in range(d)), sigma, np.full(d, -np.inf), np.full(d, np.inf), groups)


@pytest.fixture
def balan31() -> FakeModel:
    return make_balan31()


@pytest.fixture
def marker45() -> FakeModel:
    return make_marker45()
