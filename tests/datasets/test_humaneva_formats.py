"""HumanEva file parsers: .cal, .ofs, .mp, mocap .mat/.c3d; the sync rule; errors that name file and line/field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io
from he_fixtures import labels, mocap_array, parameter_group, rig, write_cal, write_mocap_mat, write_ofs

from swarmpose.datasets.humaneva import (
    StreamOffset,
    matlab_round,
    mp_value,
    parse_calibration,
    read_c3d,
    read_calibration,
    read_mocap,
    read_mocap_mat,
    read_mp,
    read_offsets,
    synchronize,
)
from swarmpose.errors import DataError, FormatError


# ---------------------------------------------------------------------- .cal
@pytest.mark.parametrize("fmt", ["%f", "%.17g"])
def test_calibration_round_trip(tmp_path: Path, fmt: str):
    cam = rig(["C1"], (640, 480), f=1000.0)["C1"]
    write_cal(tmp_path / "C1.cal", cam, fmt)
    back = read_calibration(tmp_path / "C1.cal", width=640, height=480)
    assert back.name == "C1" and back.size == (640, 480)
    tol = 1e-5 if fmt == "%f" else 1e-12
    for a in ("fx", "fy", "cx", "cy", "skew"):
        assert getattr(back, a) == pytest.approx(getattr(cam, a), abs=tol)
    np.testing.assert_allclose(back.dist, cam.dist, atol=tol)
    np.testing.assert_allclose(back.R, cam.R, atol=tol)
    np.testing.assert_allclose(back.t, cam.t, atol=1e-5)
    # 6-decimal rotations are orthonormalised (Camera demands 1e-6)
    np.testing.assert_allclose(back.R @ back.R.T, np.eye(3), atol=1e-12)
    pts = np.array([[0.0, 0.0, 900.0], [300.0, -200.0, 1500.0]])
    np.testing.assert_allclose(back.project(pts), cam.project(pts), atol=0.01)


def test_calibration_field_order_and_units(tmp_path: Path):
    """Numbers 1-22 are fc, cc, alpha_c, kc, R row-major, T (mm); projection is Bouguet's."""
    vals = [1000, 990, 320, 240, 0.001, -0.2, 0.1, 0.001, -0.002, 0.01, 1, 0, 0, 0, 0, -1, 0, 1, 0, 10, 20, 4000]
    (tmp_path / "BW2.cal").write_text("\n".join(str(v) for v in vals))
    v = parse_calibration(tmp_path / "BW2.cal")
    assert v.fc == (1000, 990) and v.cc == (320, 240) and v.alpha_c == 0.001
    assert v.kc == (-0.2, 0.1, 0.001, -0.002, 0.01)
    np.testing.assert_array_equal(v.R, [[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    np.testing.assert_array_equal(v.T, [10, 20, 4000])
    cam = v.camera("BW2", 644, 484)
    X = np.array([100.0, 50.0, 300.0])  # camera coordinates R X + T = (110, -280, 4050)
    a, b = 110 / 4050, -280 / 4050
    r2 = a * a + b * b
    rad = 1 - 0.2 * r2 + 0.1 * r2**2 + 0.01 * r2**3
    xd = a * rad + 2 * 0.001 * a * b + -0.002 * (r2 + 2 * a * a)
    yd = b * rad + 0.001 * (r2 + 2 * b * b) + 2 * -0.002 * a * b
    np.testing.assert_allclose(cam.project(X), [1000 * (xd + 0.001 * yd) + 320, 990 * yd + 240], rtol=1e-12)


def _cal_text(n: int = 22) -> list[str]:
    cam = rig(["C1"], (640, 480), f=1000.0)["C1"]
    vals = [cam.fx, cam.fy, cam.cx, cam.cy, cam.skew, *cam.dist, *cam.R.ravel(), *cam.t]
    return [f"{v:.12g}" for v in vals][:n]


def test_calibration_non_numeric_names_line_and_field(tmp_path: Path):
    lines = _cal_text()
    lines[6] = "0.1x"
    f = tmp_path / "C3.cal"
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError) as e:
        parse_calibration(f)
    msg = str(e.value)
    assert str(f) in msg and "line 7" in msg and "'kc[1]'" in msg and "0.1x" in msg
    assert e.value.line == 7 and e.value.field == "kc[1]"


def test_calibration_truncated(tmp_path: Path):
    f = tmp_path / "C1.cal"
    f.write_text("\n".join(_cal_text(20)) + "\n")
    with pytest.raises(FormatError, match=r"truncated: 20 of 22 numbers; T\[1\]") as e:
        parse_calibration(f)
    assert e.value.field == "T[1]" and str(f) in str(e.value)


def test_calibration_extra_values_and_bodytrack_variant(tmp_path: Path):
    f = tmp_path / "C1.cal"
    f.write_text("\n".join(_cal_text() + ["0.1", "0.2", "0.3"]) + "\n")
    with pytest.raises(FormatError, match="bodytrack") as e:
        parse_calibration(f)
    assert e.value.line == 23


@pytest.mark.parametrize(("index", "value", "match"), [
    (0, "nan", "not a number"), (3, "1e999", "out of range"), (1, "-5", "focal length"), (12, "0.5", "not a rotation"),
])
def test_calibration_bad_values(tmp_path: Path, index: int, value: str, match: str):
    lines = _cal_text()
    lines[index] = value
    f = tmp_path / "C1.cal"
    f.write_text("\n".join(lines))
    with pytest.raises(FormatError, match=match):
        parse_calibration(f)


def test_calibration_reflection_rejected(tmp_path: Path):
    vals = [1000, 1000, 320, 240, 0, 0, 0, 0, 0, 0, -1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 4000]
    (tmp_path / "C1.cal").write_text(" ".join(map(str, vals)))
    with pytest.raises(FormatError, match="reflection"):
        parse_calibration(tmp_path / "C1.cal")


def test_calibration_missing_and_binary(tmp_path: Path):
    with pytest.raises(DataError, match="missing calibration"):
        parse_calibration(tmp_path / "nope.cal")
    (tmp_path / "bin.cal").write_bytes(bytes(range(256)))
    with pytest.raises(FormatError, match="not a number"):
        parse_calibration(tmp_path / "bin.cal")
    (tmp_path / "empty.cal").write_text("")
    with pytest.raises(FormatError, match="truncated: 0 of 22"):
        parse_calibration(tmp_path / "empty.cal")


# ---------------------------------------------------------------------- .ofs and sync
def test_offsets_round_trip_and_errors(tmp_path: Path):
    write_ofs(tmp_path / "a.ofs", 7, 3, 2.0017)
    o = read_offsets(tmp_path / "a.ofs")
    assert (o.im_st, o.mc_st, o.mc_sc) == (7, 3, 2.0017)
    (tmp_path / "b.ofs").write_text("7\n3\n")
    with pytest.raises(FormatError, match="truncated") as e:
        read_offsets(tmp_path / "b.ofs")
    assert e.value.field == "mc_sc"
    (tmp_path / "c.ofs").write_text("7\nabc\n2\n")
    with pytest.raises(FormatError) as e:
        read_offsets(tmp_path / "c.ofs")
    assert e.value.line == 2 and e.value.field == "mc_st"
    (tmp_path / "d.ofs").write_text("7 3 0")
    with pytest.raises(FormatError, match="mc_sc"):
        read_offsets(tmp_path / "d.ofs")
    with pytest.raises(DataError, match="missing sync file"):
        read_offsets(tmp_path / "none.ofs")


def test_matlab_round():
    assert [matlab_round(x) for x in (2.5, 3.5, -2.5, 2.4999, 7.5)] == [3, 4, -3, 2, 8]


def test_synchronize_worked_example():
    """The sync_stream rule on the fixture's offsets, worked by hand (facts section 2)."""
    offs = {"C1": StreamOffset(7, 3, 2), "C2": StreamOffset(5, 1, 2), "C3": StreamOffset(9, 5, 2)}
    s = synchronize(offs)
    # starts relative to C1: C1 7, C2 5 + (3 - 1)/2 = 6, C3 9 + (3 - 5)/2 = 8; T0 = 3 - 2 * (6 - 1) = -7 < 1
    # -> starts shifted by (1 - T0)/s = 4: C1 6, C2 5, C3 7 and T0 = 1
    assert s.mocap_start == 1.0 and s.mocap_scale == 2.0
    assert s.video_start == {"C1": 6, "C2": 5, "C3": 7}
    # each camera's own .ofs mapping holds at every synchronized frame
    for cam, o in offs.items():
        for F in (1, 6, 40):
            v = s.video_frame(cam, F)
            assert o.mc_st + (v - o.im_st) * o.mc_sc == pytest.approx(s.mocap_position(F))
    assert s.mocap_frames(60) == 29


def test_synchronize_fractional_mean_scale_and_missing_cameras():
    offs = {"C1": None, "C2": StreamOffset(100, 250, 2.0), "C3": StreamOffset(90, 229, 2.02)}
    s = synchronize(offs, ["C1", "C2", "C3"])
    assert "C1" not in s.video_start
    assert s.mocap_scale == pytest.approx(2.01)
    # C2 is the reference: start3 = 90 + (250 - 229)/2.02 = 100.396; min = 100 -> T0 = 250 - 2.01 * 99 = 51.01
    assert s.mocap_start == pytest.approx(250 - 2.01 * 99)
    assert s.video_start == {"C2": 1, "C3": matlab_round(100.396 - 99)}
    with pytest.raises(DataError, match="no sync offsets"):
        synchronize({"C1": None})


def test_synchronize_he2_exact():
    s = synchronize(dict.fromkeys(["C1", "C2", "C3", "C4"], StreamOffset(1, 1, 2)))
    assert s.mocap_start == 1 and s.mocap_scale == 2 and set(s.video_start.values()) == {1}


# ---------------------------------------------------------------------- .mp
def test_mp_parse_and_lookup(tmp_path: Path):
    f = tmp_path / "S1.mp"
    f.write_text("$Bodymass = 70\n\n$LKneeWidth = 105.5\n$RKneeWidth=101\r\n")
    mp = read_mp(f)
    assert mp == {"Bodymass": 70.0, "LKneeWidth": 105.5, "RKneeWidth": 101.0}
    assert mp_value(mp, "KneeWidth") == 105.5  # substring, first match (MATLAB readmp)
    with pytest.raises(FormatError, match="LShoulderOffset"):
        mp_value(mp, "LShoulderOffset", f)
    f.write_text("$Bodymass = 70\n$LKneeWidth = wide\n")
    with pytest.raises(FormatError) as e:
        read_mp(f)
    assert e.value.line == 2 and e.value.field == "LKneeWidth"
    f.write_text("$Bodymass 70\n")
    with pytest.raises(FormatError, match="line 1"):
        read_mp(f)


# ---------------------------------------------------------------------- mocap
def test_mocap_mat_round_trip(tmp_path: Path):
    markers = mocap_array(12)
    write_mocap_mat(tmp_path / "Walking_1.mat", labels(), markers)
    (tmp_path / "Walking_1.c3d").write_bytes(b"not read: the .mat cache beside it wins")
    m = read_mocap(tmp_path / "Walking_1.c3d")
    assert m.labels == tuple(labels()) and m.frame_rate == 120.0
    np.testing.assert_array_equal(m.markers, markers)
    assert m.find("LFEP") == labels().index("LFEP") and m.find("nothing") is None
    assert m.missing_labels() == []


def test_mocap_mat_transposed(tmp_path: Path):
    markers = mocap_array(5)
    pg = parameter_group(labels()[:3])
    scipy.io.savemat(str(tmp_path / "t.mat"), {"Markers": markers[:, :3].transpose(1, 0, 2), "ParameterGroup": pg})
    m = read_mocap_mat(tmp_path / "t.mat")
    assert m.markers.shape == (5, 3, 3)
    np.testing.assert_array_equal(m.markers, markers[:, :3])


@pytest.mark.parametrize(("markers", "match"), [
    (None, "missing variable 'Markers'"),
    (np.zeros((4, 3, 2)), "shape"),
    (np.full((2, 3, 3), np.nan), "non-finite"),
    (np.array(["a", "b"]), "numeric"),
])
def test_mocap_mat_malformed(tmp_path: Path, markers, match):
    data = {"ParameterGroup": parameter_group(["A", "B", "C"])}
    if markers is not None:
        data["Markers"] = markers
    scipy.io.savemat(str(tmp_path / "m.mat"), data)
    with pytest.raises(FormatError, match=match) as e:
        read_mocap_mat(tmp_path / "m.mat")
    assert str(tmp_path / "m.mat") in str(e.value)


def test_mocap_mat_without_point_labels(tmp_path: Path):
    scipy.io.savemat(str(tmp_path / "m.mat"), {"Markers": np.ones((2, 3, 3)), "ParameterGroup": np.zeros((1, 1))})
    with pytest.raises(FormatError, match="POINT"):
        read_mocap_mat(tmp_path / "m.mat")


def test_mocap_garbage_and_truncated(tmp_path: Path):
    f = tmp_path / "g.mat"
    f.write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    with pytest.raises(FormatError, match="not a readable MATLAB") as e:
        read_mocap_mat(f)
    assert str(f) in str(e.value)
    write_mocap_mat(tmp_path / "ok.mat", labels(), mocap_array(4))
    data = (tmp_path / "ok.mat").read_bytes()
    (tmp_path / "cut.mat").write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match="cut.mat"):
        read_mocap_mat(tmp_path / "cut.mat")
    with pytest.raises(DataError, match="missing mocap"):
        read_mocap(tmp_path / "nothing.c3d")


def test_c3d_without_reader_says_what_to_install(tmp_path: Path, monkeypatch):
    import sys

    for reader in ("ezc3d", "c3d"):  # neither reader importable, whatever this environment has installed
        monkeypatch.setitem(sys.modules, reader, None)
    f = tmp_path / "Walking_1.c3d"
    f.write_bytes(b"\x02P" + bytes(510))
    with pytest.raises(DataError, match=r"swarmpose\[humaneva\]") as e:
        read_c3d(f)
    assert "Walking_1.mat" in str(e.value)


class _FakeC3dReader:
    """Stands in for ``c3d.Reader`` (point rows: x, y, z, residual, cameras; residual -1 = invalid)."""

    point_labels = ["PELO          ", "RASI          "]
    point_rate = 120.0

    def __init__(self, handle):
        handle.read()

    def read_frames(self):
        for i in range(3):
            pts = np.array([[1.0 + i, 2.0, 3.0, 0.5, 7], [9.0, 9.0, 9.0, -1.0 if i == 1 else 0.2, 0]])
            yield i + 1, pts, np.zeros((0, 0))


def test_c3d_package_glue(tmp_path: Path, monkeypatch):
    import sys
    import types

    monkeypatch.setitem(sys.modules, "ezc3d", None)  # force the 'c3d' path
    monkeypatch.setitem(sys.modules, "c3d", types.SimpleNamespace(Reader=_FakeC3dReader))
    f = tmp_path / "Walking_1.c3d"
    f.write_bytes(b"x")
    m = read_c3d(f)
    assert m.labels == ("PELO", "RASI") and m.frame_rate == 120.0 and m.markers.shape == (3, 2, 3)
    np.testing.assert_array_equal(m.markers[:, 0, 0], [1, 2, 3])
    np.testing.assert_array_equal(m.markers[1, 1], [0, 0, 0])  # invalid point -> (0, 0, 0), HumanEva's convention
    np.testing.assert_array_equal(m.markers[2, 1], [9, 9, 9])

    class Broken:
        def __init__(self, handle):
            raise ValueError("bad header")

    monkeypatch.setitem(sys.modules, "c3d", types.SimpleNamespace(Reader=Broken))
    with pytest.raises(FormatError, match="cannot parse C3D.*bad header") as e:
        read_c3d(f)
    assert str(f) in str(e.value)


def test_ezc3d_glue(tmp_path: Path, monkeypatch):
    import sys
    import types

    pts = np.zeros((4, 2, 3))
    pts[:3, 0] = np.arange(9.0).reshape(3, 3)
    pts[:3, 1] = np.nan  # ezc3d marks invalid points NaN
    doc = {"data": {"points": pts},
           "parameters": {"POINT": {"LABELS": {"value": ["PELO ", "RASI"]}, "LABELS2": {"value": ["X"]},
                                    "RATE": {"value": [120.0]}}}}
    monkeypatch.setitem(sys.modules, "ezc3d", types.SimpleNamespace(c3d=lambda path: doc))
    f = tmp_path / "Walking_1.c3d"
    f.write_bytes(b"x")
    m = read_c3d(f)
    assert m.labels == ("PELO", "RASI") and m.markers.shape == (3, 2, 3)
    np.testing.assert_array_equal(m.markers[:, 0], np.arange(9.0).reshape(3, 3).T)
    assert (m.markers[:, 1] == 0).all()
