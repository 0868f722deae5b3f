"""The ``swarmpose`` command. Command modules register themselves on :data:`app` when imported.

Heavy imports (numba kernels, matplotlib) happen inside the commands, so ``--help`` is fast.
"""

from __future__ import annotations

import typer

app = typer.Typer(
    name="swarmpose",
    help=("Recover 3D human motion from several calibrated cameras by stochastic search "
          "(SPPSO, annealed particle filter, adaptive annealed PSO)."),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def main() -> None:
    """Entry point of the ``swarmpose`` script."""
    app()


# Command modules: importing one adds its commands to ``app``.
from swarmpose.cli import (  # noqa: E402
    bench,
    clip_commands,
    compare_commands,
    dataset_commands,
    demo,
    report_commands,
    synth_commands,
    track_commands,
)

__all__ = ["app", "main", "bench", "clip_commands", "compare_commands", "dataset_commands", "demo",
           "report_commands", "synth_commands", "track_commands"]
