"""Subject measurements and the cone sizes HumanEva computes from them (``ComputeLimbParameters``).

A motion-capture lab measures each subject once: the Vicon subject file (``<S>.mp``) holds knee,
ankle, elbow and wrist widths and the shoulder offsets, and the static trial's markers give the
shoulder width (``|LSHO - RSHO|``) and the chest depth (``|STRN - T10|``). HumanEva's support code
sizes the body model's truncated cones from these numbers (``shared/reference/humaneva-facts.md``
§5.2), which is also how the thesis's model was fitted to its subject (thesis sec. 5.1.2). This
module holds those numbers (:class:`SubjectMeasurements`) and the rules (:func:`limb_table`,
:func:`measured_cones`). The synthesiser measures its observation body the same way
(:meth:`swarmpose.synth.body.ObservationBody.measurements`) and the HumanEva loader reads them from
the dataset's files, so the tracker's cones come from measurements in both cases.

The head cone needs head-band markers (``LFHD``, ``RFHD``, ``LBHD``); they are optional here, and
without them :func:`measured_cones` keeps the reference head (it is never in the edge fitness).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from swarmpose.errors import FormatError

__all__ = ["HALF_MARKER_MM", "LIMB_ROWS", "SubjectMeasurements", "limb_table", "measured_cones"]

#: Half the diameter of a Vicon marker (14 mm), as ``ComputeLimbParameters`` subtracts it.
HALF_MARKER_MM = 7.0

# field name -> key in files (the Vicon names; marker distances as "A-B")
_KEYS: dict[str, str] = {
    "shoulder_markers": "LSHO-RSHO",
    "sternum_t10": "STRN-T10",
    "l_knee_width": "LKneeWidth",
    "r_knee_width": "RKneeWidth",
    "l_ankle_width": "LAnkleWidth",
    "r_ankle_width": "RAnkleWidth",
    "l_elbow_width": "LElbowWidth",
    "r_elbow_width": "RElbowWidth",
    "l_wrist_width": "LWristWidth",
    "r_wrist_width": "RWristWidth",
    "l_shoulder_offset": "LShoulderOffset",
    "r_shoulder_offset": "RShoulderOffset",
    "head_diagonal": "LBHD-RFHD",
    "head_front": "LFHD-RFHD",
    "head_offset_deg": "HeadOffset",
}
_OPTIONAL = ("head_diagonal", "head_front", "head_offset_deg")


@dataclass(frozen=True)
class SubjectMeasurements:
    """One subject's measurements (mm; ``head_offset_deg`` in degrees).

    Attributes
    ----------
    shoulder_markers : float
        Mean distance between the shoulder (acromion) marker centres, ``|LSHO - RSHO|``.
    sternum_t10 : float
        Mean distance between the sternum (xiphoid) and 10th-thoracic-vertebra marker centres.
    l_knee_width, r_knee_width, l_ankle_width, r_ankle_width, l_elbow_width, r_elbow_width,
    l_wrist_width, r_wrist_width : float
        Caliper widths across the joint (the ``.mp`` values).
    l_shoulder_offset, r_shoulder_offset : float
        Vertical distance from the shoulder marker's base to the shoulder joint centre (``.mp``).
    head_diagonal, head_front : float or None
        ``|LBHD - RFHD|`` and ``|LFHD - RFHD|`` of a head band; None when not measured.
    head_offset_deg : float or None
        ``HeadOffset`` of the ``.mp`` (degrees); None when absent.
    source : str
        Where the numbers come from (file, or "synthetic observation body").
    """

    shoulder_markers: float
    sternum_t10: float
    l_knee_width: float
    r_knee_width: float
    l_ankle_width: float
    r_ankle_width: float
    l_elbow_width: float
    r_elbow_width: float
    l_wrist_width: float
    r_wrist_width: float
    l_shoulder_offset: float
    r_shoulder_offset: float
    head_diagonal: float | None = None
    head_front: float | None = None
    head_offset_deg: float | None = None
    source: str = ""

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name != "source":
                _check(f.name, getattr(self, f.name), None, _KEYS[f.name])

    # ------------------------------------------------------------------ (de)serialisation
    def to_dict(self) -> dict[str, Any]:
        """Vicon-named values (``"LKneeWidth"``, ``"LSHO-RSHO"``, ...), JSON-safe; absent optionals omitted."""
        out: dict[str, Any] = {}
        for name, key in _KEYS.items():
            v = getattr(self, name)
            if v is not None:
                out[key] = float(v)
        out["source"] = self.source
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, path: object = None) -> SubjectMeasurements:
        """Inverse of :meth:`to_dict`; a missing or bad value is named with ``path``."""
        if not isinstance(data, Mapping):
            raise FormatError("subject measurements must be an object", path=path, field="subject_measurements")
        unknown = sorted(set(data) - set(_KEYS.values()) - {"source"})
        if unknown:
            raise FormatError(f"unknown subject measurement(s) {unknown}; known: {sorted(_KEYS.values())}",
                              path=path, field="subject_measurements")
        kw: dict[str, Any] = {}
        for name, key in _KEYS.items():
            if key not in data:
                if name in _OPTIONAL:
                    continue
                raise FormatError(f"missing subject measurement {key!r}", path=path,
                                  field=f"subject_measurements.{key}")
            _check(name, data[key], path, f"subject_measurements.{key}")
            kw[name] = float(data[key])
        return cls(**kw, source=str(data.get("source", "")))


def _check(name: str, v: Any, path: object, field: str) -> None:
    """Raise :class:`FormatError` naming ``path``/``field`` unless ``v`` is a plausible value for ``name``."""
    if v is None and name in _OPTIONAL:
        return
    number = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    if name == "head_offset_deg":
        ok, expect = number and abs(v) <= 90.0, "a finite angle in [-90, 90] degrees"
    else:
        ok, expect = number and 1.0 <= v <= 2000.0, "a finite length in [1, 2000] mm"
    if ok and name == "shoulder_markers" and v / 2.0 - HALF_MARKER_MM <= 0:
        ok, expect = False, f"more than {2 * HALF_MARKER_MM:g} mm (it leaves no torso radius)"
    if not ok:
        raise FormatError(f"subject measurement {_KEYS[name]!r} must be {expect}, got {v!r}", path=path,
                          field=field)


def limb_table(m: SubjectMeasurements) -> np.ndarray:
    """The 10 x 5 cone parameters of HumanEva's ``ComputeLimbParameters`` (facts §5.2).

    Rows: torso, L thigh, L calf, R thigh, R calf, L upper arm, L lower arm, R upper arm, R lower
    arm, head; columns: proximal radius, distal radius, x-scale (depth), y-scale (width), head offset
    (rad, head row only). The head row is NaN without head-band measurements.
    """
    r_t = m.shoulder_markers / 2.0 - HALF_MARKER_MM
    thigh_top = (r_t + HALF_MARKER_MM) / 2.0
    P = np.zeros((10, 5))
    P[0] = (r_t, r_t, m.sternum_t10 / (2.0 * r_t), 1.0, 0.0)
    P[1] = (thigh_top, m.l_knee_width / 2.0, 1.0, 1.0, 0.0)
    P[2] = (m.l_knee_width / 2.0, m.l_ankle_width / 2.0, 1.0, 1.0, 0.0)
    P[3] = (thigh_top, m.r_knee_width / 2.0, 1.0, 1.0, 0.0)
    P[4] = (m.r_knee_width / 2.0, m.r_ankle_width / 2.0, 1.0, 1.0, 0.0)
    P[5] = (m.l_shoulder_offset, m.l_elbow_width / 2.0, 1.0, 1.0, 0.0)
    P[6] = (m.l_elbow_width / 2.0, m.l_wrist_width / 2.0, 1.0, 1.0, 0.0)
    P[7] = (m.r_shoulder_offset, m.r_elbow_width / 2.0, 1.0, 1.0, 0.0)
    P[8] = (m.r_elbow_width / 2.0, m.r_wrist_width / 2.0, 1.0, 1.0, 0.0)
    if m.head_diagonal is not None and m.head_front is not None:
        r_h = m.head_diagonal / 2.0
        P[9] = (r_h, r_h, 1.0, m.head_front / (2.0 * r_h),
                math.radians(m.head_offset_deg) if m.head_offset_deg is not None else 0.0)
    else:
        P[9] = np.nan
    return P


#: Row of :func:`limb_table` for each cone name of the body-model specs.
LIMB_ROWS: dict[str, int] = {
    "torso": 0, "l_thigh": 1, "l_calf": 2, "r_thigh": 3, "r_calf": 4,
    "l_upper_arm": 5, "l_lower_arm": 6, "r_upper_arm": 7, "r_lower_arm": 8, "head": 9,
}


def measured_cones(m: SubjectMeasurements, reference: Mapping[str, tuple[float, float, float, float]]
                   ) -> tuple[dict[str, tuple[float, float, float, float]], list[str]]:
    """Cone sizes ``name -> (r_start, r_end, scale_x, scale_y)`` from measurements.

    Every cone of ``reference`` that :data:`LIMB_ROWS` names gets :func:`limb_table`'s row (our
    ``scale_x`` is the depth axis, as HumanEva's x-scale); cones without a measurement (the head
    without head-band markers, or cones a spec adds) keep the reference size.

    Returns
    -------
    cones : dict
    kept : list of str
        Names of the cones that kept the reference size.
    """
    P = limb_table(m)
    cones: dict[str, tuple[float, float, float, float]] = {}
    kept: list[str] = []
    for name, ref in reference.items():
        row = LIMB_ROWS.get(name)
        if row is None or not np.all(np.isfinite(P[row, :4])):
            cones[name] = tuple(float(x) for x in ref)  # type: ignore[assignment]
            kept.append(name)
        else:
            cones[name] = tuple(float(x) for x in P[row, :4])  # type: ignore[assignment]
    return cones, kept
