"""Synthetic multi-view observations from real motion capture (``shared/design.md`` §4).

A detailed *observation body* (:mod:`~swarmpose.synth.body`, deliberately not the tracker's cone
model) is driven by a BVH clip, rendered with a z-buffer (:mod:`~swarmpose.synth.raster`) into a
HumanEva-like rig (:mod:`~swarmpose.synth.rig`) over a textured room with sensor noise
(:mod:`~swarmpose.synth.scene`), with 2D marker detections (:mod:`~swarmpose.synth.markers`), and
written as a :class:`~swarmpose.io.sequence.MultiViewSequence` folder
(:mod:`~swarmpose.synth.synthesize`).
"""

from __future__ import annotations

from swarmpose.synth.body import BodySettings, ObservationBody
from swarmpose.synth.markers import MarkerSettings
from swarmpose.synth.rig import RigSettings, default_rig
from swarmpose.synth.scene import SceneSettings
from swarmpose.synth.synthesize import SynthReport, cached_sequence, synthesize

__all__ = [
    "BodySettings",
    "MarkerSettings",
    "ObservationBody",
    "RigSettings",
    "SceneSettings",
    "SynthReport",
    "cached_sequence",
    "default_rig",
    "synthesize",
]
