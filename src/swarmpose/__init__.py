"""swarmpose: multi-view 3D human motion tracking by stochastic search.

Data flow (``design.md`` §1): ``body`` (models, kinematics) → ``camera`` → ``io`` (BVH, sequences) →
``synth`` (observations from mocap) → ``features`` → ``render`` (cone projection) → ``fitness`` →
``optim`` (ask/tell) → ``track`` → ``metrics`` → ``experiments`` → ``report`` → ``cli``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("swarmpose")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0+unknown"

__all__ = ["__version__"]
