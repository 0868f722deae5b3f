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


# Command modules (each adds its commands to ``app``). Keep one import per line.
from swarmpose.cli import clip_commands  # noqa: E402,F401
from swarmpose.cli import synth_commands  # noqa: E402,F401
from swarmpose.cli import demo  # noqa: E402,F401
