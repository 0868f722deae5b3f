"""``swarmpose demo``: the main job on the shared walking clip (what ``make demo`` runs)."""

from __future__ import annotations

from pathlib import Path

import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import console, fail_on_user_error

DEFAULT_CLIP = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "mocap" / "cmu_16_16_walk.bvh"


@app.command()
@fail_on_user_error
def demo(
    clip: Path = typer.Option(DEFAULT_CLIP, help="BVH clip to run on (default: the shared walking clip)."),
    out: Path = typer.Option(Path("results/demo"), help="Output folder."),
) -> None:
    """Run the demo: load the walking clip, fit the body model (IK floor) and write the results.

    Until the tracker lands this runs the richest pipeline that exists: BVH loading, the 15-joint
    ground truth, subject measurement and inverse kinematics of ``balan31``.
    """
    from swarmpose.cli.clip_commands import ik, info

    if not Path(clip).is_file():
        raise FileNotFoundError(f"demo clip {clip} not found: the shared data folder must sit beside the repo")
    info(clip=clip, unit=None, json_out=False)
    out.mkdir(parents=True, exist_ok=True)
    ik(clip=clip, model="balan31", fps=60.0, out=out / "ik_balan31.npz", unit=None, json_out=False)
    console.print(f"[green]demo finished[/green]: results in {out}/")
