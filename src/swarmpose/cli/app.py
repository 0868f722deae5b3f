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


def _version(value: bool) -> None:
    if value:
        from swarmpose import __version__
        from swarmpose.track.tracker import source_revision

        rev = source_revision()
        typer.echo(f"swarmpose {__version__}" + (f" (git {rev})" if rev else ""))
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="Print the version (and the git revision of a checkout) and exit."),
) -> None:
    """Recover 3D human motion from several calibrated cameras by stochastic search (SPPSO, annealed particle
    filter, adaptive annealed PSO)."""


def main() -> None:
    """Entry point of the ``swarmpose`` script.

    With ``--json`` a command-line usage error (a bad option value, a missing argument) also prints
    the ``{"error", "exit_code"}`` object on stdout, as the command's own errors do
    (:func:`swarmpose.cli.common.fail_on_user_error`).
    """
    import sys

    if "--json" not in sys.argv[1:]:
        command()()
        return
    try:
        from typer._click.exceptions import ClickException  # newer typer carries its own click
    except ImportError:  # pragma: no cover - typer on the installed click
        from click.exceptions import ClickException

    from swarmpose.cli.common import print_json

    try:
        rv = command()(standalone_mode=False)
    except ClickException as exc:
        try:
            from typer import rich_utils

            rich_utils.rich_format_error(exc)  # the usual error box on stderr
        except (ImportError, AttributeError):  # pragma: no cover - older or newer typer
            exc.show()
        print_json({"error": exc.format_message(), "exit_code": exc.exit_code})
        sys.exit(exc.exit_code)
    except typer.Abort:
        sys.exit(1)
    sys.exit(rv if isinstance(rv, int) else 0)


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

__all__ = ["app", "main", "command", "bench", "clip_commands", "compare_commands", "dataset_commands", "demo",
           "report_commands", "synth_commands", "track_commands"]


def _tidy_help(typer_app: typer.Typer) -> None:
    """Docstring paragraphs joined into one line each, for every command (sub-apps included): typer keeps a
    paragraph's line breaks, so an 80-column terminal showed every docstring line broken again mid-sentence."""
    import inspect

    for info in typer_app.registered_commands:
        text = info.help if info.help is not None else inspect.getdoc(info.callback)
        if text:
            info.help = "\n\n".join(" ".join(p.split()) for p in inspect.cleandoc(text).split("\n\n"))
    for group in typer_app.registered_groups:
        if group.typer_instance is not None:
            _tidy_help(group.typer_instance)


def _without_flag_placeholders(command) -> None:
    """On/off flags (``--json``, ``--video``, ``--help``) show no ``<bool>`` value placeholder in the help:
    they take no value (``--json true`` is an error)."""
    for param in getattr(command, "params", ()):
        if getattr(param, "is_flag", False) and param.metavar is None:
            param.metavar = ""
    make_help = command.get_help_option  # --help is made when the help is shown, not kept in params

    def help_option(ctx):
        opt = make_help(ctx)
        if opt is not None and opt.metavar is None:
            opt.metavar = ""
        return opt

    command.get_help_option = help_option
    for sub in getattr(command, "commands", {}).values():
        _without_flag_placeholders(sub)


def command():
    """The click command that ``swarmpose`` runs: :data:`app` with tidy help texts."""
    cmd = typer.main.get_command(app)
    _without_flag_placeholders(cmd)
    return cmd


_tidy_help(app)
