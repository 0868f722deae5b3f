"""Derive the motion-model sigma of the shipped body models from motion capture (thesis l.861).

sigma_d = the largest inter-frame change |x_d(t+1) - x_d(t)| at 60 fps over the walking clips, of
the IK fit of the model to the clips' ground truth (as Balan et al. and the thesis did with HumanEva
walking data; [FL12] l.861: sigma_4 = 13.7 mm, sigma_10 = 0.093 rad). One deviation: "largest" is the
99th percentile, not the maximum, because IK of a coarse model has a few jumps between near-equivalent
solutions (e.g. a hip twist with a straight knee) that are not motion; the plain maximum is printed
beside it. A floor of 1 degree / 1 mm keeps parameters that do not move in walking searchable. It also prints the range each parameter takes
over ALL shared clips next to the anatomical limits, to check the limits against real motion.

Run:  .venv/bin/python scripts/derive_priors.py [--write]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from swarmpose.body.ik import fit_ik
from swarmpose.body.model import BodyModel
from swarmpose.body.spec import load_spec
from swarmpose.io.mocap import load_clip, subject_from_clip

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "data" / "mocap"
# cmu_131_01_walk is left out: its pelvis jitters vertically by ~20 mm per 60-fps frame (1.3 m/s), which
# is capture noise, not walking motion (measured: p99 of |dz| = 20.3 mm vs 3.9 mm in the subject-16 walks).
WALKING = ["cmu_16_16_walk", "cmu_16_18_turn"]
FLOOR_DEG, FLOOR_MM = 1.0, 1.0


def main(write: bool) -> None:
    for name in ("balan31", "full45"):
        spec = load_spec(name)
        D = len(spec.parameters)
        steps = []
        lo_obs, hi_obs = np.full(D, np.inf), np.full(D, -np.inf)
        for path in sorted(MOCAP.glob("*.bvh")):
            clip = load_clip(path, fps=60)
            model = BodyModel(spec, subject_from_clip(spec, clip))
            x = fit_ik(model, clip.joints, polish=False).params  # the smooth fit
            lo_obs, hi_obs = np.minimum(lo_obs, x.min(0)), np.maximum(hi_obs, x.max(0))
            if path.stem in WALKING:
                steps.append(np.abs(np.diff(x, axis=0)))
        steps = np.concatenate(steps)
        max_step, p99 = steps.max(0), np.percentile(steps, 99, axis=0)
        rot = np.array([p.kind == "rotation" for p in spec.parameters])
        sigma = np.maximum(p99, np.where(rot, np.radians(FLOOR_DEG), FLOOR_MM))
        print(f"\n{name}: sigma at 60 fps (max inter-frame change over {', '.join(WALKING)})")
        print(f"{'parameter':20s} {'sigma':>9s} {'(max)':>9s} {'observed min..max (all clips)':>32s} {'limits':>20s}")
        for i, p in enumerate(spec.parameters):
            f = np.degrees if rot[i] else (lambda v: v)
            lim = f"{f(p.lower):7.1f}..{f(p.upper):7.1f}"
            print(f"{p.name:20s} {f(sigma[i]):9.3f} {f(max_step[i]):9.3f} {f(lo_obs[i]):15.1f}..{f(hi_obs[i]):<15.1f} {lim:>20s}"
                  f"{'  AT LIMIT' if (np.isclose(lo_obs[i], p.lower, atol=1e-3) or np.isclose(hi_obs[i], p.upper, atol=1e-3)) else ''}")
        if write:
            path = ROOT / "src" / "swarmpose" / "models" / f"{name}.json"
            data = json.loads(path.read_text())
            for i, p in enumerate(data["parameters"]):
                p["sigma"] = round(float(np.degrees(sigma[i]) if rot[i] else sigma[i]), 4)
                p["sigma_source"] = "99th percentile of |dx| at 60 fps over " + ", ".join(WALKING) + " (scripts/derive_priors.py)"
            path.write_text(json.dumps(data, indent=1) + "\n")
            print(f"wrote {path}")


if __name__ == "__main__":
    main("--write" in sys.argv)
