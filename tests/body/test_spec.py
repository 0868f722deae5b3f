"""Body-model spec files: validation with clear errors, subject round trip, groups."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from swarmpose.body.model import BodyModel, load_model
from swarmpose.body.spec import BodySpec, Subject, builtin_specs, load_spec
from swarmpose.errors import ConfigError, DataError, FormatError


@pytest.fixture(scope="module")
def balan_dict():
    from importlib import resources

    return json.loads((resources.files("swarmpose.models") / "balan31.json").read_text())


def test_shipped_models():
    assert {"balan31", "full45"} <= set(builtin_specs())
    spec = load_spec("balan31")
    assert len(spec.parameters) == 31 and len(spec.cones) == 10


def test_balan31_layout_follows_thesis_table_5_1():
    m = load_model("balan31")
    # x1-x3 orientation, x4-x6 position, x7-x9 left hip, x10 left knee, ..., x29-x31 head
    expected = {"root_orientation": [0, 1, 2], "root_position": [3, 4, 5], "left_leg": [6, 7, 8, 9],
                "right_leg": [10, 11, 12, 13], "left_arm": list(range(14, 20)),
                "right_arm": list(range(20, 26)), "spine": [26, 27], "head": [28, 29, 30], "head_twist": [30]}
    for g, idx in expected.items():
        assert list(m.group(g)) == idx
    assert np.all(m.sigma > 0)
    # sigma derived from walking mocap: same order of magnitude as thesis l.861 (13.7 mm, 0.093 rad)
    assert 3.0 < m.sigma[3] < 40.0
    assert 0.03 < m.sigma[9] < 0.3


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (lambda d: d.pop("joints15"), "joints15"),
        (lambda d: d["parameters"][3].pop("sigma"), "parameters[3].sigma"),
        (lambda d: d["joints"][2].update(parent="nowhere"), "joints[2]"),
        (lambda d: d["joints"][1]["rotation"][0].__setitem__(0, "w"), "joints[1]"),
        (lambda d: d["parameters"][6].update(lower=50, upper=10), "parameters[6]"),
        (lambda d: d["cones"][0].update(axis="no_such_measurement"), "cones"),
        (lambda d: d.update(version=99), "version"),
    ],
)
def test_malformed_specs_name_the_field(balan_dict, mutate, field):
    d = copy.deepcopy(balan_dict)
    mutate(d)
    with pytest.raises(FormatError) as err:
        BodySpec.from_dict(d, path="bad.json")
    assert "bad.json" in str(err.value)
    assert field in str(err.value)


def test_unused_parameter_is_rejected(balan_dict):
    d = copy.deepcopy(balan_dict)
    d["joints"][1]["rotation"] = d["joints"][1]["rotation"][:2]  # l_hip_rot drives nothing
    with pytest.raises(FormatError, match="l_hip_rot"):
        BodySpec.from_dict(d)


def test_subject_round_trip(tmp_path):
    m = load_model("balan31")
    m.subject.save(tmp_path / "s.json")
    s = Subject.load(tmp_path / "s.json")
    assert s == m.subject
    assert BodyModel(m.spec, s, m.variant).kin.offsets.tolist() == m.kin.offsets.tolist()


def test_partial_subject_falls_back_but_unknown_names_are_refused():
    spec = load_spec("balan31")
    base = spec.default_subject
    cone = next(iter(base.cones))
    partial = Subject(name="p", offsets={}, cones={cone: (50.0, 40.0, 1.0, 1.0)})
    m = BodyModel(spec, partial)
    assert m.subject.cones[cone] == (50.0, 40.0, 1.0, 1.0)
    assert m.subject.offsets == base.offsets  # what the file leaves out is the spec's default
    with pytest.raises(ConfigError, match="cones that body model 'balan31' does not have: lower_arm_l"):
        BodyModel(spec, Subject(name="typo", offsets={}, cones={"lower_arm_l": (40.0, 30.0, 1.0, 1.0)}))
    with pytest.raises(ConfigError, match="offsets .* not have: knee"):
        BodyModel(spec, Subject(name="typo", offsets={"knee": (0.0, 0.0, -400.0)}, cones={}))


def test_unknown_model_and_variant():
    with pytest.raises(ConfigError, match="balan31"):
        load_spec("no_such_model")
    with pytest.raises(ConfigError, match="thesis"):
        BodyModel(load_spec("balan31"), variant="nope")


@pytest.mark.parametrize("text,error,match", [
    (None, DataError, "subject file not found"),
    ("{not json", FormatError, "not valid JSON"),
    ("[1, 2]", FormatError, "expected a JSON object"),
    ('{"cones": {}}', FormatError, "missing field 'offsets'"),
    ('{"offsets": [], "cones": {}}', FormatError, "offsets"),
    ('{"offsets": {"l_thigh": [0, 0]}, "cones": {}}', FormatError, "offsets.l_thigh"),
    ('{"offsets": {}, "cones": {"torso": [100, 90, 1, -1]}}', FormatError, "cones.torso"),
])
def test_bad_subject_files_name_the_file_and_field(tmp_path, text, error, match):
    path = tmp_path / "s.json"
    if text is not None:
        path.write_text(text)
    with pytest.raises(error, match=match) as err:
        Subject.load(path)
    assert "s.json" in str(err.value)


def test_binary_subject_and_spec_files_are_named_not_a_traceback(tmp_path):
    path = tmp_path / "s.json"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    with pytest.raises(FormatError, match="not a UTF-8 text file") as err:
        Subject.load(path)
    assert "s.json" in str(err.value)
    with pytest.raises(FormatError, match="not a UTF-8 text file") as err:
        load_spec(path)
    assert "s.json" in str(err.value)
