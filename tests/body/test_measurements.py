"""Subject measurements: HumanEva's ComputeLimbParameters rules, round trip, named errors, cones."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarmpose.body.measurements import LIMB_ROWS, SubjectMeasurements, limb_table, measured_cones
from swarmpose.body.model import load_model
from swarmpose.errors import FormatError

VALUES = {  # a plausible adult (mm), names as in a Vicon .mp file / marker pairs
    "LSHO-RSHO": 380.0, "STRN-T10": 230.0, "LKneeWidth": 104.0, "RKneeWidth": 106.0, "LAnkleWidth": 72.0,
    "RAnkleWidth": 74.0, "LElbowWidth": 70.0, "RElbowWidth": 72.0, "LWristWidth": 52.0, "RWristWidth": 54.0,
    "LShoulderOffset": 45.0, "RShoulderOffset": 47.0,
}


def _m(**extra) -> SubjectMeasurements:
    return SubjectMeasurements.from_dict({**VALUES, **extra, "source": "test"})


def test_limb_table_follows_compute_limb_parameters():
    P = limb_table(_m())
    r_t = 380.0 / 2 - 7.0  # half the shoulder marker distance less half a marker
    np.testing.assert_allclose(P[0, :4], [r_t, r_t, 230.0 / (2 * r_t), 1.0])
    np.testing.assert_allclose(P[1, :2], [(r_t + 7.0) / 2, 52.0])  # thigh: hip from the torso, knee width
    np.testing.assert_allclose(P[3, :2], [(r_t + 7.0) / 2, 53.0])
    np.testing.assert_allclose(P[2, :2], [52.0, 36.0])  # calf: knee -> ankle widths
    np.testing.assert_allclose(P[5, :2], [45.0, 35.0])  # upper arm: shoulder offset -> elbow width
    np.testing.assert_allclose(P[8, :2], [36.0, 27.0])  # right forearm: elbow -> wrist
    assert np.isnan(P[9]).all()  # no head band measured


def test_head_band_sizes_the_head():
    P = limb_table(_m(**{"LBHD-RFHD": 200.0, "LFHD-RFHD": 140.0, "HeadOffset": 10.0}))
    np.testing.assert_allclose(P[9], [100.0, 100.0, 1.0, 0.7, math.radians(10.0)])


def test_measured_cones_cover_the_model_and_keep_the_head():
    ref = load_model("balan31").spec.default_subject.cones
    cones, kept = measured_cones(_m(), ref)
    assert set(cones) == set(ref) and kept == ["head"]
    assert cones["head"] == tuple(float(x) for x in ref["head"])
    P = limb_table(_m())
    for name, row in LIMB_ROWS.items():
        if name != "head":
            np.testing.assert_allclose(cones[name], P[row, :4])


@settings(max_examples=40, deadline=None)
@given(st.dictionaries(st.sampled_from(sorted(VALUES)), st.floats(20.0, 600.0), max_size=len(VALUES)))
def test_round_trip(changes):
    m = _m(**changes)
    back = SubjectMeasurements.from_dict(m.to_dict())
    assert back == m


@pytest.mark.parametrize(("changes", "field"), [
    ({"LKneeWidth": -3.0}, "LKneeWidth"),
    ({"STRN-T10": float("nan")}, "STRN-T10"),
    ({"RWristWidth": True}, "RWristWidth"),
    ({"LSHO-RSHO": 12.0}, "LSHO-RSHO"),
    ({"HeadOffset": 400.0}, "HeadOffset"),
])
def test_bad_value_is_named(changes, field):
    with pytest.raises(FormatError, match=f"seq.json.*{field}"):
        SubjectMeasurements.from_dict({**VALUES, **changes}, path="seq.json")


def test_missing_and_unknown_fields_are_named():
    data = dict(VALUES)
    del data["LElbowWidth"]
    with pytest.raises(FormatError, match="LElbowWidth"):
        SubjectMeasurements.from_dict(data, path="seq.json")
    with pytest.raises(FormatError, match="KneeWdth"):
        SubjectMeasurements.from_dict({**VALUES, "KneeWdth": 100.0}, path="seq.json")


def test_subject_cones_scale_with_the_subjects_legs(mocap_dir):
    """(subject.py:121 `ratio = leg / ref_leg` -> 1.0): the shared clips' legs are all within 3 % of the
    reference, so nothing noticed. The same skeleton read with a 20 % smaller unit gets 20 % thinner cones."""
    from swarmpose.body.spec import load_spec
    from swarmpose.io.mocap import UNIT_SCALES, load_clip, subject_from_clip

    spec = load_spec("balan31")
    full = subject_from_clip(spec, load_clip(mocap_dir / "cmu_16_16_walk.bvh"))
    small = subject_from_clip(spec, load_clip(mocap_dir / "cmu_16_16_walk.bvh", unit_scale=0.8 * UNIT_SCALES["cmu"]))
    for name, (r0, r1, sx, sy) in full.cones.items():
        np.testing.assert_allclose(small.cones[name], (0.8 * r0, 0.8 * r1, sx, sy), rtol=1e-9)
