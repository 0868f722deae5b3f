"""``swarmpose datasets ...``: commands for the real datasets (HumanEva-I/II, the Lee walk release)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import console, count, print_json

datasets_app = typer.Typer(
    help="Real datasets: check a HumanEva-I/II release, subject folder or Lee walk folder (see docs/datasets.md).",
    no_args_is_help=True,
)
app.add_typer(datasets_app, name="datasets")


@datasets_app.command("check")
def check(
    path: Annotated[Path, typer.Argument(help="A HumanEva release root, one subject folder (S1/), or a Lee walk "
                                              "folder.")],
    json_out: Annotated[bool, typer.Option("--json", help='Print one JSON object: {"ok", "kind", "path", "cameras", '
                                                          '"problems", "notes", "sequences"}.')] = False,
) -> None:
    """Validate a dataset folder and report exactly what is missing or malformed.

    Every problem is printed as "<file>: <what is wrong>" and makes the exit code 1. Notes do not fail the check.
    """
    from rich.markup import escape

    from swarmpose.datasets.check import check_dataset

    report = check_dataset(path)
    if json_out:
        print_json(report.to_dict())
    else:
        kinds = {"humaneva-release": "HumanEva release", "humaneva-subject": "HumanEva subject folder",
                 "leewalk": "Lee walk folder", "unknown": "unrecognised folder"}
        console.print(f"[bold]{kinds.get(report.kind, report.kind)}[/bold] {escape(report.path)}: "
                      f"{count(len(report.cameras), 'camera')}{''.join(' ' + c for c in report.cameras)}; "
                      f"{count(len(report.sequences), 'sequence')}", highlight=False)
        for p in report.problems:
            console.print(f"  [red]problem[/red] {escape(p)}", highlight=False)
        for n in report.notes:
            console.print(f"  [yellow]note[/yellow] {escape(n)}", highlight=False)
        if report.ok:
            console.print("[green]ok[/green]: no problems found")
        else:
            console.print(f"[red]{count(len(report.problems), 'problem')}[/red]")
    if not report.ok:
        raise typer.Exit(code=1)
