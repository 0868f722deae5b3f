"""Limb lengths of the shared clips' subjects against a subject from stature alone (Winter 2009 proportions).

For each clip of ../shared/data/mocap: the subject measured from the clip's skeleton (what `track` uses)
and the subject `swarmpose subject --height H` builds, with H the skeleton's own stature (ankle to head top
along the standing chain, over 1 - 0.039: the ankle's height above the floor). Prints one row per subject
with each length and the relative error of the proportions.

Run:  .venv/bin/python scripts/subject_proportions.py [--json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from swarmpose.body.anthropometry import HEIGHT_FRACTIONS, limb_lengths, subject_from_height
from swarmpose.body.spec import load_spec
from swarmpose.io.mocap import load_clip, subject_from_clip

MOCAP = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mocap"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    spec = load_spec("balan31")
    rows, seen = [], set()
    for clip in sorted(MOCAP.glob("*.bvh")):
        measured = subject_from_clip(spec, load_clip(clip))
        key = json.dumps(measured.offsets, sort_keys=True)
        if key in seen:  # one row per subject
            continue
        seen.add(key)
        o = measured.offsets
        span = (abs(o["l_pelvis_to_hip"][2]) + abs(o["l_thigh"][2]) + abs(o["l_shank"][2]) + o["spine_to_thorax"][2]
                + o["neck_to_head_top"][2])
        height = span / (1.0 - HEIGHT_FRACTIONS["ankle"])
        a, b = limb_lengths(measured), limb_lengths(subject_from_height(spec, height))
        rows.append({"clip": clip.stem, "height_mm": height, "measured_mm": a, "from_height_mm": b,
                     "error_pct": {k: 100.0 * (b[k] - a[k]) / a[k] for k in a}})
    if args.json:
        print(json.dumps({"subjects": rows}))
        return
    names = list(rows[0]["measured_mm"])
    print("| subject (first clip) | stature mm | " + " | ".join(names) + " |")
    print("|---|---:|" + "---:|" * len(names))
    for r in rows:
        cells = [f"{r['measured_mm'][k]:.0f} / {r['from_height_mm'][k]:.0f} ({r['error_pct'][k]:+.0f} %)" for k in names]
        print(f"| {r['clip']} | {r['height_mm']:.0f} | " + " | ".join(cells) + " |")
    worst = np.abs([list(r["error_pct"].values()) for r in rows])
    print(f"\nlargest error {worst.max():.0f} %, mean |error| {worst.mean():.1f} %")


if __name__ == "__main__":
    main()
