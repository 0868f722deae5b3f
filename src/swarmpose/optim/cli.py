"""``swarmpose algorithms``: list every named optimiser configuration (the lead wires it into typer)."""

from __future__ import annotations

import json as _json

from .registry import describe

__all__ = ["algorithms_command"]


def algorithms_command(json: bool = False) -> None:
    """Print the named configurations with their evaluations per frame and paper reference.

    Parameters
    ----------
    json : bool
        Print one JSON object ``{"algorithms": [{"name", "summary", "fitness", "evals_per_frame", "reference"},
        ...]}`` on one
        line instead of a table (the CLI's ``--json`` contract: exactly one object).
    """
    rows = describe()
    if json:
        print(_json.dumps({"algorithms": rows}))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title="swarmpose optimisers (swarmpose track --algo NAME)", show_lines=True)
    table.add_column("name", style="bold", no_wrap=True)
    table.add_column("what it is")
    table.add_column("fitness", justify="left")
    table.add_column("evals/frame", justify="right")
    table.add_column("paper")
    fitness = {"silhouette_edge": "silhouette + edges (images)", "reprojection": "reprojection (2D markers)"}
    for r in rows:
        table.add_row(r["name"], r["summary"], fitness.get(r["fitness"], r["fitness"]), str(r["evals_per_frame"]),
                      r["reference"])
    Console().print(table)
