"""Our constricted PSO (thesis Algorithm 2) next to pyswarms' GlobalBestPSO at equal evaluation budgets.

Usage (pyswarms writes ``report.log`` into the working directory when it is imported, so the script moves
into a temporary directory for that import; running it from one is safer still)::

    cd "$(mktemp -d)" && /work/main/.venv/bin/python /work/main/benchmarks/pso_vs_pyswarms.py --seeds 20

Set-up, identical for both optimisers where they allow it:

* functions: Sphere and Rastrigin on [-5.12, 5.12]^D, Rosenbrock on [-5, 10]^D (optimum 0 at 0, 0, 1);
  D = 10 and 30;
* budget: ``particles x iterations`` evaluations, 25 x 40 = 1000 (the thesis's per-frame budget) and
  50 x 200 = 10,000; pyswarms evaluates ``n_particles`` per iteration for ``iters`` iterations, so the
  budgets are equal;
* start swarm: the same uniform draw over the box for both (pyswarms ``init_pos``);
* velocity limit ``vmax = 2 sigma`` with ``sigma = (upper - lower) / 4`` (a quarter of the box): ours via
  ``|v| <= 2 sigma`` (Algorithm 2), pyswarms via ``velocity_clamp=(-vmax, vmax)``;
* coefficients: ours c1 = c2 rising 2.05 -> 2.15 with the constriction factor recomputed each iteration;
  pyswarms the equivalent constant Clerc-Kennedy setting w = 0.7298, c1 = c2 = 1.4962 (phi = 4.1);
* bounds: ours re-draws a move that leaves the box up to 10 times, then clips; pyswarms clips
  (``bh_strategy="nearest"``);
* 20 seeds; reported: median (and inter-quartile range) of the final best cost f, and how many seeds ours
  was at least as good.

pyswarms draws from NumPy's global random state (it has no Generator argument), so it is seeded with
``np.random.seed`` here; ours gets ``np.random.default_rng(seed)``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from collections.abc import Callable

import numpy as np

from swarmpose.optim import ConstrictedPSO, optimize
from swarmpose.optim.testfunctions import rastrigin, rosenbrock, sphere

FUNCTIONS: dict[str, tuple[Callable[[np.ndarray], np.ndarray], float, float]] = {
    "sphere": (sphere, -5.12, 5.12),
    "rosenbrock": (rosenbrock, -5.0, 10.0),
    "rastrigin": (rastrigin, -5.12, 5.12),
}
BUDGETS = ((25, 40), (50, 200))
DIMS = (10, 30)


def _import_pyswarms():
    """Import pyswarms from inside a temporary directory (its import writes report.log into the cwd)."""
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        try:
            import pyswarms
        finally:
            os.chdir(cwd)
    return pyswarms


def run_ours(f, lo, hi, d, n, iters, init, seed, c_end=2.15) -> float:
    sigma = np.full(d, (hi - lo) / 4.0)
    opt = ConstrictedPSO(
        np.full(d, (lo + hi) / 2.0),
        sigma,
        n,
        iters,
        np.random.default_rng(seed),
        lower=np.full(d, lo),
        upper=np.full(d, hi),
        init_positions=init,
        c_end=c_end,
    )
    res = optimize(opt, f)
    assert res.evaluations == n * iters
    return -res.score  # cost


def run_pyswarms(ps, f, lo, hi, d, n, iters, init, seed) -> float:
    np.random.seed(seed)  # noqa: NPY002 - pyswarms only uses the global RandomState
    vmax = 2.0 * (hi - lo) / 4.0
    opt = ps.single.GlobalBestPSO(
        n_particles=n,
        dimensions=d,
        options={"c1": 1.4962, "c2": 1.4962, "w": 0.7298},
        bounds=(np.full(d, lo), np.full(d, hi)),
        bh_strategy="nearest",
        velocity_clamp=(-vmax, vmax),
        init_pos=init.copy(),
    )
    calls = 0

    def cost(x):
        nonlocal calls
        calls += x.shape[0]
        return -f(x)

    best_cost, _ = opt.optimize(cost, iters=iters, verbose=False)
    assert calls == n * iters
    return float(best_cost)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--out", default=None, help="also write the markdown table here")
    args = ap.parse_args(argv)
    out = os.path.abspath(args.out) if args.out else None
    ps = _import_pyswarms()
    with tempfile.TemporaryDirectory() as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)  # pyswarms' reporter opens report.log in the working directory
        try:
            table = _table(ps, args.seeds)
        finally:
            os.chdir(cwd)
    if out:
        with open(out, "w") as fh:
            fh.write(table + "\n")
    return 0


def _table(ps, seeds: int) -> str:
    rows = [
        "| function | D | budget (particles x iterations) | ours: median [IQR] | pyswarms: median [IQR] "
        "| ours <= pyswarms (seeds) | ours at least as good in median | ours with c fixed at 2.05: median |",
        "|---|---|---|---|---|---|---|---|",
    ]
    t0 = time.time()
    for name, (f, lo, hi) in FUNCTIONS.items():
        for d in DIMS:
            for n, iters in BUDGETS:
                ours, theirs, const = [], [], []
                for seed in range(seeds):
                    init = np.random.default_rng([seed, d, n]).uniform(lo, hi, (n, d))
                    ours.append(run_ours(f, lo, hi, d, n, iters, init, seed))
                    const.append(run_ours(f, lo, hi, d, n, iters, init, seed, c_end=2.05))
                    with contextlib.redirect_stderr(open(os.devnull, "w")):  # noqa: SIM115
                        theirs.append(run_pyswarms(ps, f, lo, hi, d, n, iters, init, seed))
                ours_a, theirs_a = np.array(ours), np.array(theirs)

                def fmt(a):
                    q1, m, q3 = np.percentile(a, [25, 50, 75])
                    return f"{m:.3g} [{q1:.3g}, {q3:.3g}]"

                wins = int(np.sum(ours_a <= theirs_a))
                ok = "yes" if np.median(ours_a) <= np.median(theirs_a) else "**no**"
                rows.append(
                    f"| {name} | {d} | {n} x {iters} = {n * iters} | {fmt(ours_a)} | {fmt(theirs_a)} "
                    f"| {wins}/{seeds} | {ok} | {np.median(const):.3g} |"
                )
                print(rows[-1], flush=True)
    table = "\n".join(rows)
    print(
        f"\n{table}\n\n{seeds} seeds, {time.time() - t0:.0f} s, pyswarms {ps.__version__}, numpy {np.__version__}"
    )
    return table


if __name__ == "__main__":
    sys.exit(main())
