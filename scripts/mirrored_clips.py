"""Motion-capture clips mirrored left for right: motions the tracker was never tuned on, from the shared clips.

Each BVH clip is reflected in its skeleton's sagittal plane (the world plane x = 0 of the CMU skeletons, whose
left joints lie at +x in the rest pose): the root's x position changes sign, and every joint takes the rotation of
its other side (``Left*`` for ``Right*``, ``L*`` for ``R*``, ``l*`` for ``r*``; middle joints their own) reflected, ``M R M`` with
``M = diag(-1, 1, 1)``, which for the files' Z-Y-X Euler channels negates the Z and Y angles and keeps X. Each
side keeps its own bone offsets (a subject's two sides differ by up to a few mm per bone), so the mirrored motion
is the reflection to within that asymmetry; the script checks it with the clips' own forward kinematics and
prints how far each mirrored joint lies from the reflection of its other side's (median and largest, mm).

The header is kept as written; only the motion rows change (written with four decimals, as the files are).

Run:  .venv/bin/python scripts/mirrored_clips.py [--clips CLIP ...] [--out results/mirrored-clips] [--json]
Then e.g.  .venv/bin/python scripts/detected_keypoints.py --mocap results/mirrored-clips --clips
      cmu_16_16_walk_mirrored ...   (the default tracker on their renders, with the detector's keypoints)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from swarmpose.io.bvh import read_bvh
from swarmpose.io.mocap import infer_unit_scale

MOCAP = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mocap"
CLIPS = ["cmu_16_16_walk", "cmu_135_04_kick", "cmu_131_01_walk", "cmu_131_03_hop", "cmu_16_02_jump",
         "cmu_16_18_turn", "cmu_16_35_jog", "cmu_49_17_dance"]
#: A channel's sign under the reflection x -> -x (the rotations' about z and y change sign, about x not).
SIGN = {"Xposition": -1.0, "Yposition": 1.0, "Zposition": 1.0, "Xrotation": 1.0, "Yrotation": -1.0,
        "Zrotation": -1.0}


def other_side(name: str, names: set[str]) -> str:
    """The joint of the other side (``LeftArm`` <-> ``RightArm``, ``LHipJoint`` <-> ``RHipJoint``, ``lhand`` <->
    ``rhand``) where the skeleton has it, else ``name`` (a middle joint)."""
    for a, b in (("Left", "Right"), ("Right", "Left"), ("L", "R"), ("R", "L"), ("l", "r"), ("r", "l")):
        if name.startswith(a) and b + name[len(a):] in names:
            return b + name[len(a):]
    return name


def mirrored_motion(clip) -> np.ndarray:
    """The clip's motion ``(F, C)`` mirrored left for right."""
    by_name = {j.name: j for j in clip.joints}
    out = np.empty_like(clip.motion)
    for j in clip.joints:
        src = by_name[other_side(j.name, set(by_name))]
        if src.channels != j.channels:
            raise SystemExit(f"{clip.path}: {j.name} and {src.name} have different channels")
        for k, ch in enumerate(j.channels):
            out[:, j.channel_start + k] = SIGN[ch] * clip.motion[:, src.channel_start + k]
    return out


def reflection_offsets(src: Path, dst: Path) -> tuple[list[str], np.ndarray]:
    """The joint names and how far ``(F, J)`` mm each joint of clip ``dst`` lies from the reflection of its other
    side's in clip ``src`` (both read with their own forward kinematics)."""
    clip, mirrored = read_bvh(src), read_bvh(dst)
    names = clip.joint_names
    before, after = clip.global_positions(), mirrored.global_positions()
    if mirrored.joint_names != names or after.shape != before.shape:
        raise SystemExit(f"{dst}: its hierarchy differs from {src}'s")
    twin = [names.index(other_side(n, set(names))) for n in names]
    reflected = before[:, twin] * np.array([-1.0, 1.0, 1.0])
    return names, np.linalg.norm(after - reflected, axis=-1) * infer_unit_scale(clip)[0]


def write_mirrored(src: Path, dst: Path) -> None:
    clip = read_bvh(src)
    text = src.read_text()
    head = text[: text.index("Frame Time:")]
    head += text[text.index("Frame Time:"):].split("\n", 1)[0] + "\n"
    rows = "\n".join(" ".join(f"{v:.4f}" for v in row) for row in mirrored_motion(clip))
    tmp = dst.with_name(dst.name + ".tmp")
    tmp.write_text(head + rows + "\n")
    tmp.rename(dst)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="*", default=CLIPS)
    ap.add_argument("--out", type=Path, default=Path("results/mirrored-clips"))
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.clips:
        src, dst = MOCAP / f"{name}.bvh", args.out / f"{name}_mirrored.bvh"
        write_mirrored(src, dst)
        _, off = reflection_offsets(src, dst)
        rows.append({"clip": name, "out": str(dst), "frames": int(off.shape[0]),
                     "median_mm": float(np.median(off)), "max_mm": float(off.max())})
        if not args.json:
            print(f"{dst}: {off.shape[0]} frames; joints from the reflection: median {rows[-1]['median_mm']:.1f} "
                  f"mm, largest {rows[-1]['max_mm']:.1f} mm")
    if args.json:
        print(json.dumps({"clips": rows}))


if __name__ == "__main__":
    main()
