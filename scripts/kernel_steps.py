"""What one view of one pose costs in the fitness kernel, step by step, on one core.

The full kernel (swarmpose.fitness._numba) measures a (pose, view) item in steps: the cone outlines
(render._kernels.cone_outline), their row spans into the rows' buckets (bucket_outlines), the merge that counts the
covered and the observed pixels (silhouette_counts, buckets included), and the edge lines. Each step is timed alone
in a compiled loop over the same item (the demo scene's pose, its first view, 644x484), then the whole item through
the backend (serial, the full kernel); the edge lines are the whole less the silhouette counts and the outlines.

Run:  .venv/bin/python scripts/kernel_steps.py [--repeats 20000] [--json]
"""

from __future__ import annotations

import argparse
import json
import time

import numba as nb
import numpy as np

from swarmpose.body.kinematics import fk_pose_into
from swarmpose.body.model import load_model
from swarmpose.fitness._numba import _scratch
from swarmpose.fitness.backends import NumbaBackend, Request
from swarmpose.fitness.scene import demo_cameras, demo_frame
from swarmpose.render._kernels import bucket_outlines, cone_outline, silhouette_counts


@nb.njit(cache=True)
def _outlines(T, joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near, poly, sides, axis, info,
              bbox, orient, nvs, valid, repeats):
    for _ in range(repeats):
        for k in range(joint.shape[0]):
            nvs[k] = cone_outline(T, joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near, k, poly,
                                  sides, axis, info, bbox, orient)
            valid[k] = nvs[k] > 0


@nb.njit(cache=True)
def _buckets(poly, nvs, valid, H, W, cnt, bl, br, repeats):
    s = 0
    for _ in range(repeats):
        a, b = bucket_outlines(poly, nvs, valid, nvs.shape[0], H, W, cnt, bl, br)
        s += a + b
    return s


@nb.njit(cache=True)
def _counts(poly, nvs, valid, H, W, prefix, cnt, bl, br, repeats):
    s = 0
    for _ in range(repeats):
        y, p = silhouette_counts(poly, nvs, valid, nvs.shape[0], H, W, prefix, 0, cnt, bl, br)
        s += y + p
    return s


def _per_call(fn, repeats: int) -> float:
    fn(1)
    t0 = time.perf_counter()
    fn(repeats)
    return (time.perf_counter() - t0) / repeats * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=20000, help="Loops per timed step (default 20000).")
    ap.add_argument("--json", action="store_true", help="Print one JSON object.")
    args = ap.parse_args()

    model = load_model("balan31")
    pose = model.zero_pose()
    pose[5] = 1000.0
    frame = demo_frame(model, pose, demo_cameras(4), rng=np.random.default_rng(11))
    backend = NumbaBackend(model, threads="serial", moving=False)
    prep = backend.prepare(frame)
    K = len(backend.cones.names)
    H, W = prep.silhouettes.shape[1:]
    T = np.empty((model.kin.n_joints, 3, 4))
    fk_pose_into(pose, *model.kin.as_tuple(), T)
    poly, sides, axis, info, bbox, orient, _, nvs, valid, cnt, bl, br, *_ = _scratch(K, H, 2 * backend.n_rim + 4)
    view = (prep.R[0], prep.t[0], prep.cam[0], backend._ctab, backend._stab, backend.near)
    outlines = _per_call(lambda r: _outlines(T, *backend.cones.as_tuple(), *view, poly, sides, axis, info, bbox,
                                             orient, nvs, valid, r), args.repeats)
    drawn = valid & (nvs >= 3)
    rows = int(sum(max(0, min(int(np.floor(poly[k, :nvs[k], 1].max())), H - 1)
                       - max(int(np.ceil(poly[k, :nvs[k], 1].min())), 0) + 1) for k in np.flatnonzero(drawn)))
    buckets = _per_call(lambda r: _buckets(poly, nvs, valid, H, W, cnt, bl, br, r), args.repeats)
    counts = _per_call(lambda r: _counts(poly, nvs, valid, H, W, prep.prefix, cnt, bl, br, r), args.repeats)
    request = Request(edge_mask=np.ones(K, bool), top_cone=0)
    one = np.repeat(pose[None], 50, axis=0)
    backend.measure(prep, one, request)
    n = max(1, args.repeats // 500)
    t0 = time.perf_counter()
    for _ in range(n):
        backend.measure(prep, one, request)
    item = (time.perf_counter() - t0) / n / (50 * prep.n_views) * 1e6
    res = {"outlines_us": outlines, "row_spans": rows, "buckets_us": buckets, "ns_per_span": 1e3 * buckets / rows,
           "merge_and_count_us": counts - buckets, "silhouette_counts_us": counts, "whole_item_us": item,
           "edges_and_rest_us": item - counts - outlines, "cones": K, "image": [int(W), int(H)]}
    if args.json:
        print(json.dumps(res))
        return
    print(f"one view of the demo scene's pose ({W}x{H}, {K} cones), one core, µs:")
    print(f"  outlines                 {outlines:6.2f}")
    print(f"  row spans into buckets   {buckets:6.2f}  ({rows} spans, {1e3 * buckets / rows:.1f} ns each)")
    print(f"  merge and count          {counts - buckets:6.2f}")
    print(f"  edge lines and the rest  {item - counts - outlines:6.2f}")
    print(f"  the whole item           {item:6.2f}  (the backend, serial, the full kernel; kinematics included)")


if __name__ == "__main__":
    main()
