"""Tracking a sequence: motion model, tracker, runs.

Importing it imports :mod:`swarmpose.datasets`, which registers the ``humaneva:`` and ``leewalk:``
sources with :func:`swarmpose.io.sequence.open_sequence` (the tracker opens its sequences with it).
"""

import swarmpose.datasets  # noqa: F401
