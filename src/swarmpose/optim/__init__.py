"""Stochastic optimisers with an ask/tell interface: staged constricted PSO (SPPSO and variants),
the annealed particle filter and the adaptive annealed PSO, plus a registry of named configurations.

>>> import numpy as np
>>> from swarmpose import optim
>>> "sppso" in optim.names()
True

The package imports nothing else from swarmpose except :mod:`swarmpose.errors`.
"""

from .aapso import AdaptiveAnnealedPSO, StagedAAPSO
from .apf import AnnealedParticleFilter, ParticleSet
from .base import Candidate, ConfigError, Constraint, Fitness, Optimizer, OptimResult, optimize
from .pso import ConstrictedPSO, StagedPSO
from .registry import AAPSOConfig, APFConfig, OptimizerConfig, PSOConfig, describe, get, names, register
from .staged import Stage, StagedSearch

__all__ = [
    "AAPSOConfig",
    "APFConfig",
    "AdaptiveAnnealedPSO",
    "AnnealedParticleFilter",
    "Candidate",
    "ConfigError",
    "ConstrictedPSO",
    "Constraint",
    "Fitness",
    "OptimResult",
    "Optimizer",
    "OptimizerConfig",
    "PSOConfig",
    "ParticleSet",
    "Stage",
    "StagedAAPSO",
    "StagedPSO",
    "StagedSearch",
    "describe",
    "get",
    "names",
    "optimize",
    "register",
]
