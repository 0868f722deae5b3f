"""``swarmpose info`` and ``swarmpose ik``: look at a motion-capture clip and its IK floor."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import (
    console,
    count,
    err_console,
    escape,
    fail_on_user_error,
    names_a_folder,
    note_upsampling,
    print_json,
)


@app.command()
@fail_on_user_error
def info(
    clip: Path = typer.Argument(..., help="A BVH motion-capture file.", exists=False),
    unit: str = typer.Option(None, help="Source unit (mm, cm, m, inch, cmu = 56.444 mm: the CMU files' 1/0.45 inch) or mm per "
                                   "unit; inferred from the skeleton's height if omitted."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object instead of a table."),
) -> None:
    """Show a clip's frames, frame rate, duration, skeleton and unit scale.

    Reads CMU-style skeletons (the shared clips) and files written by `swarmpose export`.
    """
    from swarmpose.errors import FormatError
    from swarmpose.io.bvh import read_bvh
    from swarmpose.io.mocap import clip_from_bvh, map_skeleton
    from swarmpose.joints import JOINTS15

    bvh = read_bvh(clip)  # a malformed file fails here, with its line
    try:
        map_skeleton(bvh, "auto")
    except FormatError as exc:  # a skeleton swarmpose cannot map to 15 joints: the file's own facts still
        _header_only(clip, bvh, exc, json_out)
        return
    c = clip_from_bvh(bvh, unit_scale=_unit(unit), style="auto")  # no frames, no unit: errors, as before
    j15 = c.joints
    height_mm, warnings = _height_check(c)
    data = {
        "clip": str(clip),
        "frames": int(bvh.frames),
        "frame_rate": float(bvh.frame_rate),
        "duration_s": float(bvh.duration_s),
        "joints": len(bvh.joints),
        "channels": int(bvh.motion.shape[1]),
        "unit": c.unit_name,
        "mm_per_unit": float(c.mm_per_unit),
        "skeleton": c.skeleton_map.style,
        "joints15": {
            name: {"bvh_joint": bvh.joints[c.skeleton_map.joint_index[i]].name
                   + (" (end site)" if c.skeleton_map.from_end_site[i] else ""),
                   "start_mm": [round(float(v), 1) for v in j15[0, i]]}
            for i, name in enumerate(JOINTS15)
        },
        "pelvis_path_m": float(np.sum(np.linalg.norm(np.diff(j15[:, 1, :2], axis=0), axis=1)) / 1000.0),
        "pelvis_height_mm": {"min": float(j15[:, 1, 2].min()), "max": float(j15[:, 1, 2].max())},
        "rest_height_mm": height_mm,
        "warnings": warnings,
    }
    if json_out:
        print_json(data)
        return
    from rich.table import Table

    for w in warnings:
        err_console.print(f"[bold yellow]warning:[/bold yellow] {escape(w)}", highlight=False)

    console.print(f"[bold]{escape(str(clip))}[/bold]")
    console.print(f"  {count(data['frames'], 'frame')} at {data['frame_rate']:g} fps = {data['duration_s']:.3f} s, "
                  f"{data['joints']} joints / {data['channels']} channels, unit {data['unit']} "
                  f"({data['mm_per_unit']:.3f} mm per unit; the rest pose stands {height_mm:.0f} mm tall)")
    console.print(f"  pelvis travels {data['pelvis_path_m']:.2f} m; height "
                  f"{data['pelvis_height_mm']['min']:.0f}-{data['pelvis_height_mm']['max']:.0f} mm")
    table = Table("joint", "BVH joint", "frame 0 (mm, z up)")
    for name, d in data["joints15"].items():
        table.add_row(name, d["bvh_joint"], " ".join(f"{v:8.1f}" for v in d["start_mm"]))
    console.print(table)


def _height_check(c) -> tuple[float, list[str]]:
    """The rest pose's height in mm, and a warning when it is not a person's (a wrong --unit)."""
    from swarmpose.io.mocap import rest_height

    height_mm = rest_height(c.bvh) * float(c.mm_per_unit)
    warnings = []
    # The rest pose's joints and end sites stand ~10 % below the person's height (1.37-1.47 m for the
    # shared clips); 0.9-2.4 m covers children to tall adults, and a CMU clip read as inches (0.65 m) fails.
    if not 900.0 <= height_mm <= 2400.0:
        warnings.append(f"the skeleton stands {height_mm / 1000.0:.2f} m tall in unit {c.unit_name!r}: "
                        "not a person's height (0.9-2.4 m expected); is --unit right?")
    return height_mm, warnings


def _header_only(clip: Path, bvh, why: Exception, json_out: bool) -> None:
    """`info` on a BVH whose skeleton has no 15-joint mapping: frames, rate, duration, joints, and why."""
    reason = str(why)
    data = {"clip": str(clip), "frames": int(bvh.frames), "frame_rate": float(bvh.frame_rate),
            "duration_s": float(bvh.duration_s), "joints": len(bvh.joints), "channels": int(bvh.motion.shape[1]),
            "skeleton": None, "joints15": None,
            "warnings": [f"no HumanEva 15-joint mapping for this skeleton, so it cannot be tracked or fitted: "
                         f"{reason}"]}
    if json_out:
        print_json(data)
        return
    console.print(f"[bold]{escape(str(clip))}[/bold]")
    console.print(f"  {count(data['frames'], 'frame')} at {data['frame_rate']:g} fps = {data['duration_s']:.3f} s, "
                  f"{count(data['joints'], 'joint')} / {data['channels']} channels; root "
                  f"{escape(bvh.joints[0].name)}")
    err_console.print(f"[bold yellow]warning:[/bold yellow] {escape(data['warnings'][0])} (swarmpose reads CMU-style "
                      "skeletons and files written by `swarmpose export`)", highlight=False)


@app.command()
@fail_on_user_error
def ik(
    clip: Path = typer.Argument(..., help="A BVH motion-capture file."),
    model: str = typer.Option("balan31", help="Body model: a shipped name (balan31, full45) or a spec file."),
    fps: float = typer.Option(60.0, help="Frame rate to resample the clip to before fitting."),
    out: str = typer.Option(None, help="Write the fitted parameters, joints and errors here (.npz)."),
    unit: str = typer.Option(None, help="Source unit (mm, cm, m, inch, cmu = 56.444 mm) or mm per unit; inferred if omitted."),
    force: bool = typer.Option(False, "--force", help="Overwrite the --out file (and its .subject.json) when it exists."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object instead of a summary."),
) -> None:
    """Fit the body model to the clip's 15 ground-truth joints frame by frame: the IK floor.

    The IK floor is the mean 3D error (mm, HumanEva 15 joints) of the best fit of the model to the
    ground truth: the error no tracker using this model can beat (thesis sec. 6.4).
    """
    from tqdm import tqdm

    from swarmpose.body.ik import fit_ik
    from swarmpose.body.model import BodyModel
    from swarmpose.body.priors import HardPriors
    from swarmpose.body.spec import load_spec
    from swarmpose.errors import ConfigError
    from swarmpose.io.mocap import load_clip, subject_from_clip
    from swarmpose.joints import JOINTS15

    if out is not None and names_a_folder(out):  # before the fit, which takes a while
        raise ConfigError(f"--out {out} is a folder; give the .npz file to write, "
                          f"e.g. {Path(out) / (Path(clip).stem + '_ik.npz')}")
    if out is not None:
        out = Path(out)
        if out.suffix != ".npz":
            out = out.with_name(out.name + ".npz")  # what numpy would write anyway; say so
        existing = [p for p in (out, out.with_suffix(".subject.json")) if p.exists()]
        if existing and not force:  # a mistyped --out must not clobber a results file
            raise ConfigError(f"--out: {' and '.join(map(str, existing))} exist{'s' if len(existing) == 1 else ''}; "
                              "add --force to overwrite")
    note_upsampling(clip, fps)
    c = load_clip(clip, fps=fps, unit_scale=_unit(unit), style="auto")
    _, warnings = _height_check(c)
    for w in warnings:  # before the fit: a fit to a 25-m skeleton would give a floor that means nothing
        err_console.print(f"[bold yellow]warning:[/bold yellow] {escape(w)}", highlight=False)
    spec = load_spec(model)
    body = BodyModel(spec, subject_from_clip(spec, c), "thesis" if "thesis" in spec.variants else None)
    with tqdm(total=c.frames, desc=f"IK {c.name}", unit="frame", file=sys.stderr, disable=json_out) as bar:
        res = fit_ik(body, c.joints, progress=lambda _k: bar.update(1))
    valid = HardPriors(body, coupled_limits=True).valid(res.floor_params)  # as the default tracker has them
    per_joint = res.joint_error_mm.mean(axis=0)
    data = {
        "clip": str(clip),
        "model": body.name,
        "fps": float(c.frame_rate),
        "frames": int(c.frames),
        "ik_floor_mm": {"mean": res.floor_mean_mm, "max": res.floor_max_mm,
                        "median": float(np.median(res.frame_error_mm))},
        "per_joint_mm": {n: float(v) for n, v in zip(JOINTS15, per_joint, strict=True)},
        "valid_under_hard_priors": float(valid.mean()),
        "warnings": warnings,
    }
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        np.savez(out, params=res.floor_params, joints=body.joints15(res.floor_params), gt_joints=c.joints,
                 joint_error_mm=res.joint_error_mm, smooth_params=res.params, frame_times=c.frame_times,
                 param_names=np.array(body.param_names), world_from_source=c.world_from_source)
        body.subject.save(out.with_suffix(".subject.json"))
        data["out"] = str(out)
    if json_out:
        print_json(data)
        return
    console.print(f"[bold]{escape(c.name)}[/bold]: {c.frames} frames at {c.frame_rate:g} fps, model {body.name}")
    console.print(f"  IK floor: mean {res.floor_mean_mm:.2f} mm, max {res.floor_max_mm:.2f} mm; "
                  f"{100 * valid.mean():.1f} % of fitted poses satisfy the hard priors (with the coupled limits)")
    worst = sorted(data["per_joint_mm"].items(), key=lambda kv: -kv[1])[:4]
    console.print("  largest per-joint errors: " + ", ".join(f"{n} {v:.1f} mm" for n, v in worst))
    if out is not None:
        console.print(f"  wrote {out} and {out.with_suffix('.subject.json')}", markup=False, highlight=False)


def _unit(unit: str | None):
    if unit is None:
        return None
    try:
        return float(unit)
    except ValueError:
        return unit



@app.command()
@fail_on_user_error
def subject(
    height: float = typer.Option(..., "--height", help="The person's stature in millimetres (e.g. 1750)."),
    out: Path = typer.Option(..., help="Subject file to write (.json), for `track --subject`."),
    model: str = typer.Option("balan31", help="Body model: a shipped name (balan31, full45) or a spec file."),
    name: str = typer.Option(None, help="Name recorded in the file (default: stature-<height>mm)."),
    force: bool = typer.Option(False, "--force", help="Overwrite --out when it exists."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object instead of a summary."),
) -> None:
    """Write a subject (limb lengths and cone sizes) for a person of the given height, from published
    proportions (Winter 2009, Fig. 4.1): for recordings without motion capture of the person."""
    from swarmpose.body.anthropometry import subject_from_height
    from swarmpose.body.spec import load_spec
    from swarmpose.errors import ConfigError

    if out.exists() and not force:
        raise ConfigError(f"{out} exists; pass --force to overwrite it")
    if out.suffix != ".json":
        raise ConfigError(f"--out {out}: a subject file is JSON; give a name ending in .json")
    spec = load_spec(model)
    subj = subject_from_height(spec, height, name=name)
    out.parent.mkdir(parents=True, exist_ok=True)
    subj.save(out)
    o = subj.offsets
    lengths = {k: abs(o[v][2]) for k, v in (("thigh_mm", "l_thigh"), ("shank_mm", "l_shank"),
                                             ("upper_arm_mm", "l_upper_arm"), ("forearm_mm", "l_forearm"))}
    if json_out:
        print_json({"out": str(out), "height_mm": height, "model": model, "name": subj.name, **lengths,
                    "source": subj.source})
        return
    console.print(f"wrote {out}: {subj.name} ({model}); " + ", ".join(
        f"{k[:-3].replace('_', ' ')} {v:.0f} mm" for k, v in lengths.items()), markup=False, highlight=False)
