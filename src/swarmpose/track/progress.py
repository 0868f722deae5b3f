"""A run's progress on disk, written as it goes at a cost per frame that does not grow with the recording.

Two files in the run's folder:

* ``progress_frames.npy`` -- one row per frame of the run (a structured NumPy array: parameters, score,
  evaluations, seconds, recovered limbs): frame ``i`` writes its row in place (a positioned write, in the
  system's file cache when ``save`` returns, so a crash of the process loses nothing; the file is not mapped,
  so a long recording's rows do not stay in the process's memory);
* ``progress.npz`` -- the small state the next frame needs (frames done, last estimate, the generator's
  state, the carried particle set, and an ensemble's members' state, ``extra_*``), replaced atomically after
  the row is on disk.

A crash between the two leaves a row that ``progress.npz`` does not count yet: the resume tracks that frame
again and overwrites it, so a resumed run gives exactly the uninterrupted result. ``progress.npz`` files of
the earlier layout (every frame's arrays inside it) are still read.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import FormatError
from swarmpose.io.files import load_npz

__all__ = ["ProgressState", "RunProgress"]

STATE_FILE = "progress.npz"
FRAMES_FILE = "progress_frames.npy"
#: The prefix of the extra state's arrays in ``progress.npz``.
EXTRA = "extra_"


@dataclass
class ProgressState:
    """What a resume starts from: ``done`` frames with their rows, and the state after the last of them."""

    done: int
    params: np.ndarray
    scores: np.ndarray
    evaluations: np.ndarray
    seconds: np.ndarray
    recovered: np.ndarray
    x_prev: np.ndarray
    rng_state: dict[str, Any]
    carry: tuple[np.ndarray, np.ndarray] | None
    extra: dict[str, np.ndarray] = field(default_factory=dict)


def _dtype(n_params: int, n_limbs: int) -> np.dtype:
    return np.dtype([("params", np.float64, (n_params,)), ("score", np.float64), ("evaluations", np.int64),
                     ("seconds", np.float64), ("recovered", np.bool_, (n_limbs,))])


class RunProgress:
    """The progress files of run ``run`` (``T`` frames, ``D`` parameters, ``L`` limbs)."""

    def __init__(self, run_dir: Path, n_frames: int, n_params: int, n_limbs: int, *, run: int = 0) -> None:
        self.run_dir = Path(run_dir)
        self.run = int(run)
        self.state_file = self.run_dir / STATE_FILE
        self.frames_file = self.run_dir / FRAMES_FILE
        self.dtype = _dtype(n_params, n_limbs)
        self.shape = (int(n_frames),)
        self._fd: int | None = None  # the frames file, open for writing rows
        self._offset = 0  # where its rows start (after the .npy header)

    def exists(self) -> bool:
        return self.state_file.is_file()

    def load(self) -> ProgressState:
        """Read the saved progress.

        Raises
        ------
        FormatError
            A file is damaged or belongs to another run shape (the message names it and says how to go on).
        """
        try:
            z = load_npz(self.state_file, ("done", "x_prev", "rng_state"))
        except FormatError as exc:
            raise FormatError(f"{exc}; delete it to track run {self.run} afresh") from None
        try:
            done = int(z["done"])
            if not 0 <= done <= self.shape[0]:
                raise ValueError(f"{done} frames done of {self.shape[0]}")
            carry = (z["carry_x"].copy(), z["carry_w"].copy()) if "carry_x" in z else None
            rng_state = json.loads(str(z["rng_state"]))
            x_prev = z["x_prev"].copy()
            extra = {k[len(EXTRA):]: v.copy() for k, v in z.items() if k.startswith(EXTRA)}
            if "params" in z:  # the earlier layout: every frame's arrays in progress.npz
                rows = np.zeros(self.shape, self.dtype)
                if z["params"].shape != (self.shape[0], self.dtype["params"].shape[0]):
                    raise ValueError(f"params {z['params'].shape}")
                rows["params"], rows["score"] = z["params"], z["scores"]
                rows["evaluations"], rows["seconds"] = z["evaluations"], z["seconds"]
                if "recovered" in z:
                    rows["recovered"] = z["recovered"]
            else:
                rows = self._checked()  # mapped for reading; the rows done are copied below
        except (ValueError, TypeError, KeyError, json.JSONDecodeError) as exc:
            raise FormatError(f"does not fit this run ({exc}); delete it to track run {self.run} afresh",
                              path=self.state_file) from None
        r = np.array(rows[:done])
        return ProgressState(done=done, params=r["params"], scores=r["score"], evaluations=r["evaluations"],
                             seconds=r["seconds"], recovered=r["recovered"], x_prev=x_prev, rng_state=rng_state,
                             carry=carry, extra=extra)

    def _checked(self) -> np.memmap:
        """The frames file, mapped for reading, after checking its row type and length."""
        try:
            frames = np.lib.format.open_memmap(self.frames_file, mode="r")
        except (OSError, ValueError) as exc:
            raise ValueError(f"{self.frames_file.name} cannot be read: {exc}") from None
        if frames.dtype != self.dtype or frames.shape != self.shape:
            raise ValueError(f"{self.frames_file.name} holds {frames.shape} {frames.dtype}, expected {self.shape}")
        return frames

    def start(self, state: ProgressState | None) -> None:
        """Open the frames file for writing: a new one, or the loaded run's (rows of the earlier layout copied)."""
        if state is None or not self.frames_file.is_file():
            frames = np.lib.format.open_memmap(self.frames_file, mode="w+", dtype=self.dtype, shape=self.shape)
        else:
            frames = self._checked()
        self._offset = int(frames.offset)
        del frames
        self._fd = os.open(self.frames_file, os.O_RDWR)
        if state is not None and state.done:
            rows = np.zeros(state.done, self.dtype)
            rows["params"], rows["score"] = state.params, state.scores
            rows["evaluations"], rows["seconds"] = state.evaluations, state.seconds
            rows["recovered"] = state.recovered
            self._write(0, rows)

    def _write(self, i: int, rows: np.ndarray) -> None:
        data = rows.tobytes()
        if os.pwrite(self._fd, data, self._offset + i * self.dtype.itemsize) != len(data):
            raise OSError(f"{self.frames_file}: row {i} not written whole (disk full?)")

    def save(self, i: int, *, params: np.ndarray, score: float, evaluations: int, seconds: float,
             recovered: np.ndarray, x_prev: np.ndarray, rng_state: dict[str, Any],
             carry: tuple[np.ndarray, np.ndarray] | None, extra: Mapping[str, np.ndarray] | None = None) -> None:
        """Frame ``i`` done: its row, then the state that counts it (``extra``: more arrays of that state, read
        back as :attr:`ProgressState.extra`)."""
        if self._fd is None:
            raise RuntimeError("RunProgress.start() first")
        self._write(i, np.array([(params, score, evaluations, seconds, recovered)], self.dtype))
        arrays = {} if carry is None else {"carry_x": carry[0], "carry_w": carry[1]}
        arrays.update({EXTRA + k: np.asarray(v) for k, v in (extra or {}).items()})
        tmp = self.state_file.with_name(self.state_file.name + ".tmp.npz")
        np.savez(tmp, done=i + 1, x_prev=x_prev, rng_state=np.array(json.dumps(rng_state)), **arrays)
        os.replace(tmp, self.state_file)

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
