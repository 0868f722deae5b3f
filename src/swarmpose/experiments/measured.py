"""Measured accuracy and speed of the named algorithms on the shared walk, for ``swarmpose algorithms``.

Each entry is one configuration's measurement on ``cmu_16_16_walk`` (the clip every suite tracks,
synthesised with the default settings) at the algorithm's own rate: D_mean in mm (the mean 3D error of
the 15 joints, averaged over the runs), the tracking rate, frames/s per run (two runs at a time on 2
cores; None where it was not recorded), the number of runs (seed 0) and the command that measured it.
An algorithm without an entry has no measured walk number. docs/results.md has these numbers with
their spread, and the rest.
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["CLIP", "MEASURED", "Measured"]

#: The clip of every measurement here.
CLIP = "cmu_16_16_walk"
_WALK = "../shared/data/mocap/cmu_16_16_walk.bvh"


class Measured(NamedTuple):
    d_mean_mm: float
    fps: float
    frames_per_s: float | None
    runs: int
    command: str


def _track(algo: str, fps: int, runs: int = 5) -> str:
    return f"swarmpose track {_WALK} --algo {algo} --fps {fps} --runs {runs}"


MEASURED: dict[str, Measured] = {
    "sppso": Measured(72.4, 20.0, 8.6, 5, _track("sppso", 20)),
    "sppso3": Measured(68.5, 20.0, None, 5, _track("sppso3", 20)),
    "pso-global": Measured(84.8, 20.0, None, 5, _track("pso-global", 20)),
    "hard2": Measured(87.4, 20.0, None, 5, _track("hard2", 20)),
    # thesis Fig. 6.14 runs the 12 hard partitions at 60 fps only, as the thesis-partitions suite does
    "hpso12": Measured(81.7, 60.0, 1.3, 5, _track("hpso12", 60)),
    "apf": Measured(85.4, 20.0, None, 5, _track("apf", 20)),
    "apf-adaptive": Measured(50.0, 20.0, 9.9, 5, _track("apf-adaptive", 20)),
    "apf-dr05": Measured(30.6, 20.0, 5.6, 5, _track("apf-dr05", 20)),
    # on the synthetic 2D marker detections, with the default (symmetric reprojection) fitness
    "aapso": Measured(14.8, 25.0, 5.7, 5, _track("aapso", 25)),
    "aapso-fixed": Measured(15.2, 25.0, None, 5, "swarmpose compare markers-reprojection"),
    # aapso's frames/s and both rows at git 7b0355c, in one session
    "aapso-refined": Measured(12.1, 25.0, 6.1, 5, _track("aapso-refined", 25)),
    # 2 runs (git d556adc); `swarmpose compare ablation --runs 5` gives it 25.7 (23.8-28.9) on the walk; the frames/s
    # of these rows and of sppso, apf-adaptive and apf-dr05 measured again at git 4cbe663, in one session
    "refined": Measured(24.8, 20.0, 6.9, 2, _track("refined", 20, runs=2)),
    "refined-limbs": Measured(20.9, 20.0, 4.3, 3, _track("refined-limbs", 20, runs=3)),
    # the default; `swarmpose demo` tracks the same runs (git 1c7843b: the shoulders' second branch left out)
    "refined-heading": Measured(22.4, 20.0, 3.8, 3, _track("refined-heading", 20, runs=3)),
}
