"""Export of tracked motion for other tools: :func:`export_bvh` (Biovision hierarchy)."""

from __future__ import annotations

from swarmpose.export.bvh_export import (
    REST_FACINGS,
    ROTATION_ORDERS,
    bvh_axes,
    euler_from_matrices,
    export_bvh,
    rest_rotation,
    uniform_clock,
)

__all__ = ["REST_FACINGS", "ROTATION_ORDERS", "bvh_axes", "euler_from_matrices", "export_bvh", "rest_rotation",
           "uniform_clock"]
