"""``swarmpose synth`` (render a clip into a sequence folder) and ``swarmpose show`` (contact sheet)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from swarmpose.cli.app import app
from swarmpose.cli.common import (
    console,
    err_console,
    escape,
    fail_on_user_error,
    note_upsampling,
    print_json,
)
from swarmpose.errors import ConfigError


def parse_albedo(text: str) -> dict[str, float]:
    """``"shirt=0.6,trousers=0.15"`` over :class:`~swarmpose.synth.BodySettings`'s default albedos."""
    from swarmpose.errors import option_items
    from swarmpose.synth import BodySettings
    from swarmpose.synth.body import MATERIALS

    form = f"material=value with a material of {', '.join(MATERIALS)}"
    out = dict(BodySettings().albedo)
    for key, value in option_items(text, "--albedo:", form):
        if key not in MATERIALS:
            raise ConfigError(f"--albedo: {f'{key}={value}'!r} is not {form}")
        try:
            out[key] = float(value)
        except ValueError:
            raise ConfigError(f"--albedo: {key}={value!r} is not a number") from None
    return out


#: The settings' field names as the user typed them on the command line.
_SYNTH_FLAGS = {
    "MarkerSettings.markers": "--markers",
    "MarkerSettings.dropout": "--dropout",
    "MarkerSettings.false_per_view": "--false-per-view",
    "MarkerSettings.noise_px": "--marker-noise-px",
    "BodySettings.clothing_mm": "--clothing-mm",
    "BodySettings.albedo": "--albedo",
    "SceneSettings.noise_sigma": "--noise-sigma",
}


def option_names(message: str) -> str:
    """A settings error as the command line says it: ``MarkerSettings.dropout`` -> ``--dropout``."""
    message = re.sub(r"BodySettings\.albedo\['(\w+)'\]", r"--albedo \1", message)
    for field_name, flag in _SYNTH_FLAGS.items():
        message = message.replace(field_name, flag)
    return message


@app.command()
@fail_on_user_error
def synth(
    clip: Annotated[Path, typer.Argument(help="A BVH motion-capture file (CMU skeleton).")],
    out: Annotated[Path, typer.Option("--out", help="Sequence folder to write.")],
    fps: Annotated[float, typer.Option(help="Frame rate of the sequence (the clip is resampled).")] = 60.0,
    seed: Annotated[int, typer.Option(min=0, help="Seed (>= 0) of background texture, sensor noise and markers.")] = 0,
    markers: Annotated[str, typer.Option(help="Marker set: joints15, extended (+toe and hand tips) or none.")] = "joints15",
    dropout: Annotated[float, typer.Option(help="Probability that a visible marker is not detected.")] = 0.05,
    false_per_view: Annotated[float, typer.Option(help="Mean false detections per frame and view (Poisson).")] = 0.5,
    marker_noise: Annotated[float, typer.Option("--marker-noise-px", help="Gaussian pixel noise of detections (sd).")] = 1.0,
    no_occlusion: Annotated[bool, typer.Option("--no-occlusion", help="Detect every marker, also those the body hides (default: a "
                                                                 "marker hidden behind the body is not detected).")] = False,
    clothing: Annotated[float, typer.Option("--clothing-mm", help="Clothing bulk added to clothed parts, mm.")] = 10.0,
    albedo: Annotated[str, typer.Option(help="Grey reflectance per material over the defaults, material=value[,...] "
                                             "with materials shirt (0.34), trousers (0.29), skin (0.28), hair "
                                             "(0.20), shoes (0.21); e.g. shirt=0.15,skin=0.40 for forearms "
                                             "that stand out against the shirt. Albedos between about 0.5 "
                                             "and 0.85 are as light as the room (grey levels ~116-153): the "
                                             "silhouettes lose those parts (synth warns).")] = "",
    noise: Annotated[float, typer.Option("--noise-sigma", help="Sensor noise, grey levels (sd).")] = 2.5,
    max_frames: Annotated[int | None, typer.Option(help="Only the first N frames.")] = None,
    fs_stride: Annotated[int, typer.Option(help="Evaluate the tracker model's f_s every N-th frame (0: never).")] = 5,
    no_measure: Annotated[bool, typer.Option("--no-measure", help="Skip silhouette IoU and f_s measurements.")] = False,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing sequence folder.")] = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object (progress goes to stderr).")] = False,
    progress: Annotated[bool, typer.Option("--progress/--no-progress", help="Progress bar on stderr.")] = True,
) -> None:
    """Render a motion-capture clip into a HumanEva-like 4-camera sequence folder.

    A detailed observation body (not the tracker's cone model) is driven by the clip, rendered with
    a z-buffer over a textured room with sensor noise, with 2D marker detections; the product's own
    feature code then measures the silhouettes (IoU against the exact masks) and the tracker model's
    silhouette fitness at its inverse-kinematics pose.
    """
    from swarmpose.synth import BodySettings, MarkerSettings, SceneSettings, synthesize

    try:
        msettings = MarkerSettings(markers=markers, dropout=dropout, false_per_view=false_per_view,
                                   noise_px=marker_noise, occlusion=not no_occlusion)
        body = BodySettings(clothing_mm=clothing, albedo=parse_albedo(albedo))
        scene = SceneSettings(noise_sigma=noise)
    except ConfigError as exc:
        raise ConfigError(option_names(str(exc))) from None
    if not (np.isfinite(fps) and fps > 0):
        raise ConfigError(f"--fps must be a positive frame rate, got {fps!r}")
    note_upsampling(clip, fps)
    report = synthesize(clip, out, fps=fps, seed=seed, markers=msettings, body=body, scene=scene,
                        max_frames=max_frames, fs_stride=fs_stride, measure=not no_measure, overwrite=force,
                        progress=progress)
    data = report.to_dict()
    data["warnings"] = silhouette_warnings(Path(data["path"]), data["silhouette_iou"], body, scene)
    for w in data["warnings"]:
        err_console.print(f"[bold yellow]warning:[/bold yellow] {escape(w)}", highlight=False)
    if json_out:
        print_json(data)
        return
    iou = data["silhouette_iou"]
    fs = data["model_fs_at_gt"]
    console.print(f"[bold]{escape(str(data['path']))}[/bold]: {data['frames']} frames x {data['views']} views in "
                  f"{data['seconds']:.1f} s ({data['disk_mb']:.0f} MB)")
    if iou.get("n"):
        console.print(f"  silhouette IoU (image-derived vs exact): min {iou['min']:.3f}, p05 {iou['p05']:.3f}, "
                      f"median {iou['p50']:.3f}, mean {iou['mean']:.3f} over {iou['n']} frame-views")
    if fs.get("mean") is not None:
        console.print(f"  balan31 f_s at its IK pose: mean {fs['mean']:.3f} (min {fs['min']:.3f}, max {fs['max']:.3f}) "
                      f"over {fs['n_frames']} frame{'' if fs['n_frames'] == 1 else 's'}; IK floor {fs['ik_floor_mm']:.1f} mm")
    sm = data.get("subject_measurements")
    if sm:
        console.print("  subject measurements (mm, for the tracker's cones): "
                      + ", ".join(f"{k} {v:.1f}" for k, v in sm.items() if k != "source"))
    m = data["markers"]
    if m:
        console.print(f"  markers: {m['visible_fraction']:.1%} visible, drop-out {m['dropout_rate']:.3f}, "
                      f"{m['false_per_view']:.2f} false per view")


#: Below this median IoU against the exact masks the image-derived silhouettes are poor (the default
#: synthesis of the shared clips gives 0.93-0.96)
POOR_SILHOUETTE_IOU = 0.85


def silhouette_warnings(seq_dir: Path, iou: dict | None, body, scene) -> list[str]:
    """Say when the silhouettes found in the images are poor, and which materials blend into the room.

    A material's grey is ``255 * albedo * light`` with ``light`` between ``ambient`` and ``ambient +
    sky + key`` (:func:`swarmpose.synth.scene.shade_vertices`); it blends in where that range overlaps
    the backgrounds' 5th-95th percentile.
    """
    from swarmpose.io.files import load_npz

    if not iou or not iou.get("n") or iou["p50"] >= POOR_SILHOUETTE_IOU:
        return []
    backgrounds = load_npz(seq_dir / "backgrounds.npz", ("backgrounds",))["backgrounds"]
    lo, hi = np.percentile(backgrounds, [5, 95])
    dark, bright = scene.ambient, scene.ambient + scene.sky + scene.key
    blend = [f"{name} ({a:g}: grey {255 * a * dark:.0f}-{255 * a * bright:.0f})"
             for name, a in body.albedo.items() if 255 * a * dark <= hi and 255 * a * bright >= lo]
    why = (f"; these materials are as light as the room (grey {lo:.0f}-{hi:.0f}): {', '.join(blend)}; "
           "choose darker --albedo values" if blend else "")
    return [f"the silhouettes found in the images match the exact masks poorly (median IoU {iou['p50']:.3f}, "
            f"below {POOR_SILHOUETTE_IOU}){why}"]


def contact_sheet(path: Path, frame: int) -> np.ndarray:
    """BGR contact sheet of one frame: per view a row of (image + markers, silhouette, edge map).

    Parameters
    ----------
    path : Path
        Sequence folder.
    frame : int

    Returns
    -------
    numpy.ndarray, shape (rows * H', 3 * W', 3), uint8
    """
    import cv2

    from swarmpose.features import compute_features
    from swarmpose.io.sequence import open_sequence

    with open_sequence(path) as seq:
        if not 0 <= frame < seq.n_frames:
            raise ConfigError(f"--frame {frame} outside [0, {seq.n_frames}) of {path}")
        images = seq.images(frame)
        if images is None:
            raise ConfigError(f"{path}: the sequence stores no images")
        bgs = seq.backgrounds()
        masks = seq.masks(frame)
        dets = seq.markers(frame)
        ids = seq.marker_ids(frame)
        feats = compute_features(images, bgs, seq.cameras) if bgs is not None else None
        W, H = seq.image_size
        rows = []
        font = cv2.FONT_HERSHEY_SIMPLEX
        for c, name in enumerate(seq.view_names):
            img = cv2.cvtColor(images[c], cv2.COLOR_GRAY2BGR)
            if dets is not None:
                for (u, v), i in zip(dets[c], ids[c], strict=True):
                    p = (int(round(u)), int(round(v)))
                    if i >= 0:
                        cv2.circle(img, p, 4, (60, 220, 60), 1, cv2.LINE_AA)
                    else:
                        cv2.drawMarker(img, p, (40, 40, 255), cv2.MARKER_TILTED_CROSS, 9, 1, cv2.LINE_AA)
            cv2.putText(img, f"{name} frame {frame}", (8, 22), font, 0.6, (0, 255, 255), 1, cv2.LINE_AA)
            if feats is not None:
                sil = feats.silhouettes[c].astype(bool)
                tile2 = np.zeros((H, W, 3), np.uint8)
                tile2[sil] = (255, 255, 255)
                label = "silhouette (from image)"
                if masks is not None:
                    m = masks[c].astype(bool)
                    tile2[sil & ~m] = (60, 60, 255)  # extra: red
                    tile2[m & ~sil] = (255, 120, 40)  # missed: blue
                    union = (sil | m).sum()
                    label += f"  IoU {((sil & m).sum() / union if union else float('nan')):.3f}"
                cv2.putText(tile2, label, (8, 22), font, 0.6, (0, 255, 255), 1, cv2.LINE_AA)
                e = (np.clip(feats.edges[c], 0, 1) * 255).astype(np.uint8)
                tile3 = cv2.applyColorMap(e, cv2.COLORMAP_INFERNO)
                cv2.putText(tile3, "edge map", (8, 22), font, 0.6, (0, 255, 255), 1, cv2.LINE_AA)
            else:
                tile2 = np.zeros((H, W, 3), np.uint8)
                tile3 = np.zeros((H, W, 3), np.uint8)
                cv2.putText(tile2, "no background stored", (8, 22), font, 0.6, (0, 255, 255), 1, cv2.LINE_AA)
            row = np.hstack([img, tile2, tile3])
            row[:, W - 1:W + 1] = 90
            row[:, 2 * W - 1:2 * W + 1] = 90
            rows.append(row)
            rows.append(np.full((2, row.shape[1], 3), 90, np.uint8))
        sheet = np.vstack(rows[:-1])
        legend = np.zeros((28, sheet.shape[1], 3), np.uint8)
        cv2.putText(legend, "markers: green o = detection of a marker, red x = false detection;  silhouette: "
                    "white = agrees with exact mask, red = extra, blue = missed", (8, 19), font, 0.55,
                    (230, 230, 230), 1, cv2.LINE_AA)
        return np.vstack([sheet, legend])


@app.command()
@fail_on_user_error
def show(
    seq_dir: Annotated[Path, typer.Argument(help="A sequence folder (from swarmpose synth).")],
    frame: Annotated[int, typer.Option("--frame", help="Frame index.")] = 0,
    out: Annotated[Path | None, typer.Option("--out", help="PNG to write (default: <DIR>/contact_NNNNNN.png, "
                                                           "the frame index in 6 digits).")] = None,
    scale: Annotated[float, typer.Option(help="Resize the sheet by this factor (0.05 to 8).")] = 1.0,
    force: Annotated[bool, typer.Option("--force", help="Overwrite an existing --out file (the default "
                                                        "contact_NNNNNN.png is always rewritten).")] = False,
    json_out: Annotated[bool, typer.Option("--json", help='Print one JSON object {"path", "frame", "width", '
                                                          '"height"} (the sheet written and its size in pixels).')] = False,
) -> None:
    """Write a PNG contact sheet of one frame: every view with its markers, silhouette and edge map."""
    import cv2

    from swarmpose.errors import DataError

    if out is not None and out.suffix.lower() not in (".png", ".jpg", ".jpeg"):
        raise ConfigError(f"--out {out}: the contact sheet is written as .png (or .jpg), not {out.suffix or 'a file without suffix'}")
    if not (np.isfinite(scale) and 0.05 <= scale <= 8.0):
        raise ConfigError(f"--scale must lie in [0.05, 8] (a factor on the sheet's size), got {scale!r}")
    if out is not None and out.exists() and not force:  # a mistyped --out must not clobber another picture
        raise ConfigError(f"--out {out} exists; add --force to overwrite it")
    sheet = contact_sheet(seq_dir, frame)
    if scale != 1.0:
        sheet = cv2.resize(sheet, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    out = out if out is not None else seq_dir / f"contact_{frame:06d}.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(out), sheet):
        raise DataError(f"{out}: cannot write the PNG")
    if json_out:
        print_json({"path": str(out), "frame": int(frame), "width": int(sheet.shape[1]), "height": int(sheet.shape[0])})
        return
    console.print(str(out), markup=False, highlight=False)
