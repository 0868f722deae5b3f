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
        from swarmpose.track.provenance import source_revision

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

    A bad option value (``--runs 0``, ``--seed -1``, ``--fps abc``) is one line on stderr naming the option,
    ``error: --runs 0: must be at least 1``, with exit code 2, as the commands' own errors are
    (:func:`swarmpose.cli.common.fail_on_user_error`); other usage errors (a missing argument, an unknown
    option) show typer's usage box. With ``--json`` every usage error also prints the ``{"error", "exit_code"}``
    object on stdout.
    """
    import sys

    try:
        from typer._click.exceptions import BadParameter, ClickException, MissingParameter  # newer typer
    except ImportError:  # pragma: no cover - typer on the installed click
        from click.exceptions import BadParameter, ClickException, MissingParameter

    from swarmpose.cli.common import err_console, escape, print_json
    from swarmpose.track.heap import fix_mmap_threshold

    fix_mmap_threshold()  # large buffers off the C heap: a long run's heap grows less (swarmpose.track.heap)
    args = sys.argv[1:]
    try:
        rv = command()(standalone_mode=False)
    except ClickException as exc:
        if isinstance(exc, BadParameter) and not isinstance(exc, MissingParameter):
            message = bad_value_message(exc, args)
            err_console.print(f"[bold red]error:[/bold red] {escape(message)}", highlight=False)
        else:
            message = exc.format_message()
            try:
                from typer import rich_utils

                rich_utils.rich_format_error(exc)  # the usual usage box on stderr
            except (ImportError, AttributeError):  # pragma: no cover - older or newer typer
                exc.show()
        if "--json" in args:
            print_json({"error": message, "exit_code": exc.exit_code})
        sys.exit(exc.exit_code)
    except typer.Abort:
        err_console.print("Aborted.", highlight=False)
        sys.exit(1)
    sys.exit(rv if isinstance(rv, int) else 0)


_RANGE_WORDS = (("greater than or equal to", "at least"), ("less than or equal to", "at most"),
                ("greater than", "above"), ("less than", "below"))


def bad_value_message(exc, args: list[str]) -> str:
    """``--runs 0: must be at least 1``: the option, the value given (when it is on the command line) and
    what is wrong with it, from typer's ``Invalid value for '--runs': Input should be greater than or equal
    to 1``."""
    import re

    param = getattr(exc, "param", None)
    opts = [*getattr(param, "opts", ()), *getattr(param, "secondary_opts", ())]
    if getattr(param, "param_type_name", "") == "option" and opts:
        name = next((o for o in opts if o.startswith("--")), opts[0])
        given = None
        for i, arg in enumerate(args):  # the last occurrence is the one that counts
            for opt in opts:
                if arg == opt and i + 1 < len(args):
                    given = args[i + 1]
                elif arg.startswith(opt + "="):
                    given = arg[len(opt) + 1:]
        where = name if given is None else f"{name} {given}"
    else:  # an argument: its name as the usage line shows it
        where = str(getattr(param, "human_readable_name", "") or "").upper()
    text = str(getattr(exc, "message", "") or exc.format_message()).strip()
    for words, plain in _RANGE_WORDS:
        m = re.fullmatch(rf"Input should be {words} (\S+)", text)
        if m:
            text = f"must be {plain} {m.group(1)}"
            break
    else:
        m = re.fullmatch(r"Input should be a valid (\w+)\b.*", text)  # "a valid number, unable to parse ..."
        text = f"not a valid {m.group(1)}" if m else re.sub(r"^Input should be ", "should be ", text)
    return f"{where}: {text}" if where else text


# Command modules: importing one adds its commands to ``app``.
from swarmpose.cli import (  # noqa: E402
    bench,
    clip_commands,
    compare_commands,
    dataset_commands,
    demo,
    recording_commands,
    report_commands,
    synth_commands,
    track_commands,
)

__all__ = ["app", "main", "command", "bench", "clip_commands", "compare_commands", "dataset_commands", "demo",
           "recording_commands", "report_commands", "synth_commands", "track_commands"]


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


def _help_folds_long_words() -> None:
    """Make typer's help panels wrap a word too long for its cell onto the next line instead of cutting it with
    "…": on an 80-column terminal the description column of `track --help` is about 25 characters wide, and
    `results/<sequence>-<algo>-<fps>fps`, `terms=silhouette|edge` or `constant-velocity[:D][@GROUP+...]` came
    out cut, the syntax a user needs lost. Rich cells cut by default; these fold."""
    try:
        from typer import rich_utils
    except ImportError:  # pragma: no cover - typer without rich
        return
    from rich.text import Text

    table, columns = getattr(rich_utils, "Table", None), getattr(rich_utils, "Columns", None)
    if not isinstance(table, type) or columns is None or getattr(table, "folds", False):
        return  # another typer (the help test says so), or done already

    class FoldingTable(table):  # the options and commands panels
        folds = True

        def add_row(self, *renderables, **kwargs):
            super().add_row(*renderables, **kwargs)
            last = len(self.columns) - 2  # an options panel: required mark, option names, then type and help
            for i, column in enumerate(self.columns):
                column.overflow = "fold"
                column.no_wrap = column.no_wrap or i < last  # an option's name is never broken

    def folding_columns(renderables=None, *args, **kwargs):  # an option's help, default and "required"
        items = list(renderables or [])
        for item in items:
            if isinstance(item, Text):
                item.overflow = "fold"
        return columns(items, *args, **kwargs)

    rich_utils.Table = FoldingTable
    rich_utils.Columns = folding_columns


_tidy_help(app)
_help_folds_long_words()
