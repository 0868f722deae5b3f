"""Real datasets: HumanEva-I/II as distributed and the Lee walk release (see ``docs/datasets.md``).

A dataset source is a string with a prefix:

* ``humaneva:<root>/<S>/<Action>_<Trial>[?cams=C1,C2,C3&split=auto&frames=6-590]``
  (:func:`swarmpose.datasets.humaneva.humaneva_sequence`),
* ``leewalk:<folder>[?frames=1-450]`` (:func:`swarmpose.datasets.leewalk.leewalk_sequence`).

:func:`open_dataset_sequence` opens either, or a plain sequence folder, as a lazily read
:class:`~swarmpose.io.sequence.MultiViewSequence`; :func:`check_dataset` validates a folder. Importing
this package registers both prefixes with :func:`swarmpose.io.sequence.open_sequence`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from swarmpose.datasets.check import CheckReport, check_dataset
from swarmpose.datasets.humaneva import humaneva_sequence, open_humaneva, parse_humaneva_spec
from swarmpose.datasets.leewalk import LeeWalkLayout, leewalk_sequence, open_leewalk
from swarmpose.errors import DataError, FormatError, ShapeError
from swarmpose.io.sequence import MultiViewSequence, register_source_scheme

__all__ = [
    "DATASET_PREFIXES",
    "is_dataset_spec",
    "dataset_sequence_name",
    "open_dataset_sequence",
    "humaneva_sequence",
    "open_humaneva",
    "leewalk_sequence",
    "open_leewalk",
    "LeeWalkLayout",
    "check_dataset",
    "CheckReport",
]

DATASET_PREFIXES: tuple[str, ...] = ("humaneva:", "leewalk:")


def is_dataset_spec(source: Any) -> bool:
    """True for a ``humaneva:`` or ``leewalk:`` source (str or path-like)."""
    try:
        s = os.fspath(source)
    except TypeError:
        return False
    return isinstance(s, str) and s.startswith(DATASET_PREFIXES)


def dataset_sequence_name(source: str | os.PathLike[str]) -> str:
    """A short name for result folders: ``S1_Walking_1`` for HumanEva, ``leewalk`` for the Lee walk."""
    s = os.fspath(source)
    if s.startswith("humaneva:"):
        return parse_humaneva_spec(s).name
    if s.startswith("leewalk:"):
        return "leewalk"
    return os.path.basename(os.path.normpath(s))


def open_dataset_sequence(source: str | os.PathLike[str], **options: Any) -> MultiViewSequence:
    """Open a ``humaneva:``/``leewalk:`` source, or a sequence folder, as a :class:`MultiViewSequence`.

    Parameters
    ----------
    source : str or path-like
        A dataset source (see the module docstring) or a folder written by
        :func:`swarmpose.io.sequence.write_sequence`. A :class:`pathlib.Path` built from a
        ``humaneva:`` string works too (only repeated slashes are collapsed).
    **options
        Passed to :func:`humaneva_sequence` (e.g. ``cache_dir``) for ``humaneva:`` sources.

    Returns
    -------
    MultiViewSequence
        Read lazily; close it (or use ``with``) to release the videos or archives.
    """
    s = os.fspath(source)
    if not s.startswith(DATASET_PREFIXES):
        from swarmpose.io.sequence import open_sequence

        return open_sequence(s)
    try:
        return humaneva_sequence(s, **options) if s.startswith("humaneva:") else leewalk_sequence(s)
    except (DataError, FormatError, ShapeError) as error:
        # the reader stops at the first problem; the check lists all of them (a missing camera 2 and a
        # corrupt cam1.cal, say, in one report)
        folder = parse_humaneva_spec(s).subject_dir if s.startswith("humaneva:") else Path(s[8:].partition("?")[0])
        if folder.is_dir() and error.args and isinstance(error.args[0], str):
            error.args = (f"{error.args[0]} (`swarmpose datasets check {folder}` lists every problem of the "
                          "folder)", *error.args[1:])
        raise


for _prefix in DATASET_PREFIXES:
    register_source_scheme(_prefix, open_dataset_sequence)
