"""Tests of swarmpose.io.calibration: the real Pose2Sim demo files, round trips, up axis, units and errors."""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, DataError, FormatError
from swarmpose.io.calibration import detect_format, read_calibration, write_calibration
from swarmpose.io.calibration import opencv as cv_mod
from swarmpose.io.calibration import qualisys as qca_mod

CALIB_DIR = (Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "recordings"
             / "pose2sim-demo-single" / "calibration").resolve()
QCA = CALIB_DIR / "Calib.qca.txt"
TOML = CALIB_DIR / "Calib_scene.toml"


@pytest.fixture(scope="module")
def real_files() -> tuple[Path, Path]:
    if not (QCA.is_file() and TOML.is_file()):
        pytest.skip(f"shared calibration files not found in {CALIB_DIR} (the 'shared' folder sits beside the repo)")
    return QCA, TOML


def _angle_deg(R: np.ndarray) -> float:
    return math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(R) - 1.0) / 2.0))))


def assert_same_cameras(a: list[Camera], b: list[Camera], tol: float = 1e-6) -> None:
    assert [c.name for c in b] == [c.name for c in a]
    for x, y in zip(a, b, strict=True):
        assert y.size == x.size, x.name
        for f in ("fx", "fy", "cx", "cy", "skew"):
            assert abs(getattr(y, f) - getattr(x, f)) <= tol, (x.name, f, getattr(x, f), getattr(y, f))
        np.testing.assert_allclose(y.dist, x.dist, rtol=0, atol=tol)
        np.testing.assert_allclose(y.R, x.R, rtol=0, atol=tol)
        np.testing.assert_allclose(y.t, x.t, rtol=0, atol=tol)


# ---------------------------------------------------------------------- the real files
def test_read_toml_real(real_files):
    cal = read_calibration(real_files[1])
    assert cal.format == "toml" and cal.paths == (real_files[1],)
    assert cal.names == ["int_cam01_img", "int_cam02_img", "int_cam03_img", "int_cam04_img"]
    assert (cal.units, cal.units_source) == ("m", "format")
    assert (cal.up, cal.up_source) == ("+z", "detected")
    np.testing.assert_array_equal(cal.world_from_file, np.eye(4))
    assert cal.image_sizes == {n: (1088, 1920) for n in cal.names}
    c1 = cal.camera("int_cam01_img")
    assert c1.size == (1088, 1920)
    assert c1.fx == pytest.approx(1671.5012042021037, abs=1e-9)
    assert c1.cx == pytest.approx(564.6403499852015, abs=1e-9)
    assert c1.dist == pytest.approx((-0.05310342256182765, 0.1510044676505964, -0.00011989435671705446,
                                     0.0006503403122568441, 0.0), abs=1e-15)
    np.testing.assert_allclose(c1.t, [260.9476905995074, 964.1586618892432, 2932.963441842366], atol=1e-9)
    for c in cal.cameras:  # cameras 1.7 to 2.1 m high, 2 to 5 m from the middle of the floor
        assert 1700 < c.center[2] < 2100
        assert 2000 < np.linalg.norm(c.center[:2]) < 5000
    assert any("detected" in n and "+z" in n for n in cal.notes)


def test_read_qualisys_real(real_files):
    cal = read_calibration(real_files[0])
    assert cal.format == "qualisys"
    assert cal.names == ["cam01", "cam02", "cam03", "cam04"]
    assert (cal.units, cal.units_source, cal.up, cal.up_source) == ("mm", "format", "+z", "detected")
    c1 = cal.camera("cam01")
    assert c1.size == (1088, 1920)
    assert c1.fx == pytest.approx(107599.671875 / 64) and c1.fy == pytest.approx(107588.828125 / 64)
    assert c1.cx == pytest.approx(34110.316406 / 64) and c1.cy == pytest.approx(60680.792969 / 64)
    assert c1.dist == pytest.approx((-0.046183, 0.139983, 0.000608, 0.00069, 0.0))
    np.testing.assert_allclose(c1.center, [1460.2323709212087, -1909.1590482454608, 1896.5058524092062],
                               atol=1e-6)
    toml = read_calibration(real_files[1])
    for q, t in zip(cal.cameras, toml.cameras, strict=True):  # same lenses: similar intrinsics
        assert abs(q.fx - t.fx) < 20 and abs(q.cx - t.cx) < 50 and abs(q.cy - t.cy) < 50
        assert abs(q.dist[0] - t.dist[0]) < 0.025  # k1 about -0.05 in both: no /64 on distortion


def test_qualisys_and_toml_describe_the_same_rig(real_files):
    q, t = read_calibration(real_files[0]).cameras, read_calibration(real_files[1]).cameras
    # measured: centre distances differ by -101, -46, -24, -79, -107, -8 mm (the .qca.txt's are shorter);
    # relative rotations by 1.0, 3.4, 2.1, 2.6, 1.2, 1.8 degrees
    for i, j in itertools.combinations(range(4), 2):
        dq = np.linalg.norm(q[i].center - q[j].center)
        dt = np.linalg.norm(t[i].center - t[j].center)
        assert abs(dq - dt) < 150.0, (i, j, dq, dt)
        rel = (q[i].R @ q[j].R.T) @ (t[i].R @ t[j].R.T).T
        assert _angle_deg(rel) < 4.5, (i, j, _angle_deg(rel))
    for cams in (q, t):  # every optical axis points at the middle of the floor (measured 7 to 12 degrees)
        mid = np.mean([c.center for c in cams], axis=0) * np.array([1.0, 1.0, 0.0])
        for c in cams:
            to_mid = (mid - c.center) / np.linalg.norm(mid - c.center)
            assert math.degrees(math.acos(float(c.R[2] @ to_mid))) < 15.0, c.name


def test_qualisys_convention_is_the_only_one_that_agrees(real_files, monkeypatch):
    """Without the half turn about the camera's x axis, relative rotations disagree by far more."""
    monkeypatch.setattr(qca_mod, "QUALISYS_TO_OPENCV", np.eye(3))
    q = read_calibration(real_files[0], up="+z").cameras
    t = read_calibration(real_files[1]).cameras
    worst = max(_angle_deg((q[i].R @ q[j].R.T) @ (t[i].R @ t[j].R.T).T)
                for i, j in itertools.combinations(range(4), 2))
    assert worst > 30.0


def test_qualisys_video_crop_shifts_the_principal_point(real_files, tmp_path):
    text = real_files[0].read_text(encoding="ascii")
    text = text.replace('<fov_video bottom="1919" left="0" right="1087" top="0"/>',
                        '<fov_video bottom="1019" left="100" right="739" top="20"/>', 1)
    p = tmp_path / "crop.qca.txt"
    p.write_text(text, encoding="ascii")
    c1 = read_calibration(p).camera("cam01")
    assert c1.size == (640, 1000)
    assert c1.cx == pytest.approx(34110.316406 / 64 - 100) and c1.cy == pytest.approx(60680.792969 / 64 - 20)


# ---------------------------------------------------------------------- round trips
def random_cameras(seed: int, n: int = 4) -> list[Camera]:
    rng = np.random.default_rng(seed)
    cams = []
    for i in range(n):
        if i == n - 1:  # a half turn: where a naive Rodrigues conversion loses precision
            axis = rng.normal(size=3)
            R = Rotation.from_rotvec(math.pi * axis / np.linalg.norm(axis)).as_matrix()
        else:
            R = Rotation.random(random_state=int(rng.integers(1 << 30))).as_matrix()
        fx = float(rng.uniform(300.0, 3000.0))
        w, h = int(rng.integers(64, 4096)), int(rng.integers(64, 4096))
        cams.append(Camera(
            name=f"cam-{i}_{seed}", width=w, height=h, fx=fx, fy=fx * float(rng.uniform(0.98, 1.02)),
            cx=float(rng.uniform(0, w)), cy=float(rng.uniform(0, h)),
            skew=0.0 if i == 0 else float(rng.uniform(-0.01, 0.01)),
            dist=tuple(float(v) for v in rng.normal(scale=[0.1, 0.05, 0.002, 0.002, 0.02])),
            R=R, t=rng.uniform(-5000.0, 5000.0, size=3)))
    return cams


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("fmt,name,units", [("toml", "calib.toml", "m"), ("opencv", "calib.yml", "m"),
                                            ("opencv", "calib.xml", "mm"), ("opencv", "calib.yaml", "cm"),
                                            ("easymocap", "intri.yml", "m")])
def test_round_trip(tmp_path, seed, fmt, name, units):
    cams = random_cameras(seed)
    written = write_calibration(tmp_path / name, cams, fmt, units=units)
    assert all(p.is_file() for p in written)
    assert len(written) == (2 if fmt == "easymocap" else 1)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in written)  # no temporary left
    cal = read_calibration(tmp_path / name, up="+z")
    assert cal.format == fmt
    assert (cal.units, cal.units_source) == (units, "format")
    assert_same_cameras(cams, cal.cameras)
    assert cal.image_sizes == {c.name: c.size for c in cams}


def test_easymocap_pair_explicit_paths_and_keys(tmp_path):
    cams = random_cameras(5, n=2)
    intri, extri = write_calibration(tmp_path / "a" / "intri.yml", cams, "easymocap",
                                     extrinsics_path=tmp_path / "b" / "extri.yml")
    cal = read_calibration(intri, extrinsics=extri, up="+z")
    assert cal.format == "easymocap" and cal.paths == (intri, extri)
    assert_same_cameras(cams, cal.cameras)
    text_i, text_e = intri.read_text(), extri.read_text()
    for c in cams:
        for key in (f"K_{c.name}", f"dist_{c.name}", f"H_{c.name}", f"W_{c.name}"):
            assert re.search(rf"^{key}:", text_i, re.M), key
        for key in (f"R_{c.name}", f"Rot_{c.name}", f"T_{c.name}"):
            assert re.search(rf"^{key}:", text_e, re.M), key
    assert f"H_{cams[0].name}: {cams[0].height}\n" in text_i  # an int
    assert "cols: 5" in text_i  # dist 1x5
    # T in metres: EasyMocap's unit
    import cv2

    fs = cv2.FileStorage(str(extri), cv2.FILE_STORAGE_READ)
    np.testing.assert_allclose(fs.getNode(f"T_{cams[0].name}").mat().ravel(), cams[0].t / 1000.0, rtol=1e-15)


def test_extri_found_beside_intri_and_the_other_way(tmp_path):
    cams = random_cameras(6, n=2)
    write_calibration(tmp_path / "intri.yml", cams, "easymocap")
    assert detect_format(tmp_path / "intri.yml") == "easymocap"
    assert detect_format(tmp_path / "extri.yml") == "easymocap"
    for p in ("intri.yml", "extri.yml"):
        cal = read_calibration(tmp_path / p, up="+z")
        assert cal.paths == (tmp_path / "intri.yml", tmp_path / "extri.yml")
        assert_same_cameras(cams, cal.cameras)


def test_toml_writer_is_deterministic_and_readable_by_tomllib(tmp_path):
    import tomllib

    cams = random_cameras(7)
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    write_calibration(a, cams, "toml")
    write_calibration(b, cams, "toml")
    assert a.read_bytes() == b.read_bytes()
    doc = tomllib.loads(a.read_text())
    assert set(doc) == {c.name for c in cams} | {"metadata"}
    first = doc[cams[0].name]
    assert first["size"] == [cams[0].width, cams[0].height] and first["fisheye"] is False
    np.testing.assert_allclose(first["translation"], cams[0].t / 1000.0, rtol=1e-15)


def test_failed_write_keeps_the_old_file(tmp_path, monkeypatch):
    p = tmp_path / "rig.yml"
    write_calibration(p, random_cameras(8, n=2), "opencv")
    before = p.read_bytes()

    def boom(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(cv_mod, "_write_extrinsics", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        write_calibration(p, random_cameras(9, n=2), "opencv")
    assert p.read_bytes() == before
    assert [x.name for x in tmp_path.iterdir()] == ["rig.yml"]


# ---------------------------------------------------------------------- units and sizes
def _plain_opencv(path: Path, cams: list[Camera], unit_mm: float, with_size: bool = True) -> Path:
    """An EasyMocap-layout file without a 'units' key (as other tools write it), T in ``unit_mm`` mm."""
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.startWriteStruct("names", cv2.FileNode_SEQ)
    for c in cams:
        fs.write("", c.name)
    fs.endWriteStruct()
    for c in cams:
        fs.write(f"K_{c.name}", c.K)
        fs.write(f"dist_{c.name}", np.array([c.dist[:4]]))  # 1x4
        if with_size:
            fs.write(f"H_{c.name}", c.height)
            fs.write(f"W_{c.name}", c.width)
        fs.write(f"R_{c.name}", cv2.Rodrigues(np.asarray(c.R))[0])
        fs.write(f"T_{c.name}", (c.t / unit_mm)[:, None])
    fs.release()
    return path


def _ring(n: int = 4, up=(0.0, 0.0, 1.0), f: float = 1000.0) -> list[Camera]:
    """Cameras 3.5 m around a person at the origin, 2 m high, in a z-up world."""
    cams = []
    for i in range(n):
        a = 2 * math.pi * i / n + 0.3
        cams.append(Camera.look_at(f"c{i}", eye=(3500 * math.cos(a), 3500 * math.sin(a), 2000.0),
                                   target=(0.0, 0.0, 1000.0), up=up, f=f, dist=(-0.05, 0.01, 0.0, 0.0, 0.0)))
    return cams


@pytest.mark.parametrize("unit,unit_mm", [("m", 1000.0), ("mm", 1.0)])
def test_plain_opencv_units_detected(tmp_path, unit, unit_mm):
    cams = _ring()
    cal = read_calibration(_plain_opencv(tmp_path / "calib.yml", cams, unit_mm))
    assert (cal.format, cal.units, cal.units_source) == ("opencv", unit, "detected")
    assert any("length unit detected" in n for n in cal.notes)
    assert_same_cameras(cams, cal.cameras, tol=1e-9)


def test_units_override(tmp_path):
    cams = _ring()
    p = _plain_opencv(tmp_path / "calib.yml", cams, 10.0)  # centimetres: detection says mm
    assert read_calibration(p).units == "mm"
    cal = read_calibration(p, units="cm")
    assert (cal.units, cal.units_source) == ("cm", "stated")
    assert_same_cameras(cams, cal.cameras, tol=1e-9)
    toml = tmp_path / "c.toml"
    write_calibration(toml, cams, "toml")
    cal = read_calibration(toml, units="mm")
    assert (cal.units, cal.units_source) == ("mm", "stated")
    np.testing.assert_allclose(cal.cameras[0].t, cams[0].t / 1000.0, atol=1e-9)
    assert any("overrides" in n for n in cal.notes)


def test_sizes_fill_a_file_without_them(tmp_path):
    cams = _ring(2)
    p = _plain_opencv(tmp_path / "calib.yml", cams, 1000.0, with_size=False)
    with pytest.raises(FormatError) as e:
        read_calibration(p)
    assert str(p) in str(e.value) and "'c0'" in str(e.value) and "W_c0" in str(e.value)
    cal = read_calibration(p, sizes={"c0": (644, 484), "c1": (644, 484)})
    assert [c.size for c in cal.cameras] == [(644, 484)] * 2 and cal.image_sizes is None
    assert_same_cameras(cams, cal.cameras, tol=1e-9)


def test_sizes_differing_from_the_file_are_noted(real_files):
    cal = read_calibration(real_files[1], sizes={"int_cam01_img": (1080, 1920)})
    assert cal.camera("int_cam01_img").size == (1088, 1920)
    assert any("1080x1920" in n and "int_cam01_img" in n for n in cal.notes)


# ---------------------------------------------------------------------- up axis
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # (x, y, z) -> (x, -z, y)


def _y_up_rig() -> list[Camera]:
    """The ring of :func:`_ring` built in a y-up world: heights along +y."""
    cams = []
    for i in range(4):
        a = 2 * math.pi * i / 4 + 0.3
        cams.append(Camera.look_at(f"c{i}", eye=(3500 * math.cos(a), 2000.0, 3500 * math.sin(a)),
                                   target=(0.0, 1000.0, 0.0), up=(0.0, 1.0, 0.0), f=1000.0))
    return cams


@pytest.mark.parametrize("up", [None, "+y", "y"])
def test_y_up_rig_turned_to_z_up(tmp_path, up):
    file_cams = _y_up_rig()
    p = tmp_path / "yup.toml"
    write_calibration(p, file_cams, "toml")
    cal = read_calibration(p, up=up)
    assert cal.up == "+y" and cal.up_source == ("detected" if up is None else "stated")
    np.testing.assert_array_equal(cal.world_from_file[:3, :3], Y_UP_TO_Z_UP)
    np.testing.assert_array_equal(cal.world_from_file[3], [0.0, 0.0, 0.0, 1.0])
    np.testing.assert_array_equal(cal.world_from_file[:3, 3], 0.0)
    rng = np.random.default_rng(0)
    pts_file = rng.uniform([-800, 0, -800], [800, 1800, 800], size=(50, 3))
    pts_world = (cal.world_from_file @ np.c_[pts_file, np.ones(50)].T).T[:, :3]
    for fc, c in zip(file_cams, cal.cameras, strict=True):
        np.testing.assert_allclose(c.project(pts_world), fc.project(pts_file), atol=1e-6)
        assert 1900 < c.center[2] < 2100  # 2 m up, now along z
        assert -c.R[1] @ np.array([0.0, 0.0, 1.0]) > 0.9  # the image's up is the world's up
    np.testing.assert_allclose(cal.file_from_world @ cal.world_from_file, np.eye(4), atol=1e-15)


@pytest.mark.parametrize("axis", ["+x", "-x", "+y", "-y", "+z", "-z"])
def test_every_up_axis_detected_and_turned(tmp_path, axis):
    k, sign = "xyz".index(axis[1]), 1.0 if axis[0] == "+" else -1.0
    up = np.zeros(3)
    up[k] = sign
    # a proper rotation B taking +z to this axis, independent of the reader's choice
    B = Rotation.align_vectors([up], [[0.0, 0.0, 1.0]])[0].as_matrix() if axis != "-z" else np.diag([1.0, -1, -1])
    z_cams = _ring()
    file_cams = [Camera.look_at(c.name, eye=B @ c.center, target=B @ np.array([0.0, 0.0, 1000.0]), up=up,
                                f=1000.0) for c in z_cams]
    p = _plain_opencv(tmp_path / "rig.yml", file_cams, 1.0)
    cal = read_calibration(p)
    assert (cal.up, cal.up_source, cal.units) == (axis, "detected", "mm")
    A = cal.world_from_file[:3, :3]
    assert np.linalg.det(A) == pytest.approx(1.0)
    np.testing.assert_allclose(A @ up, [0.0, 0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(A @ A.T, np.eye(3), atol=1e-15)
    for zc, c in zip(z_cams, cal.cameras, strict=True):
        assert c.center[2] == pytest.approx(zc.center[2], abs=1e-6)  # heights as in the z-up rig
        np.testing.assert_allclose(c.R[1] @ [0.0, 0.0, 1.0], zc.R[1] @ [0.0, 0.0, 1.0], atol=1e-9)


def test_up_not_detectable(tmp_path):
    # cameras looking straight down with image-up along +x, -x, +y, -y: the mean cancels
    cams = [Camera.look_at(f"c{i}", eye=(0.0, 0.0, 3000.0 + i), target=(0.0, 0.0, 0.0), up=u)
            for i, u in enumerate([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)])]
    p = tmp_path / "down.toml"
    write_calibration(p, cams, "toml")
    with pytest.raises(ConfigError, match="up="):
        read_calibration(p)
    assert read_calibration(p, up="+z").up_source == "stated"


# ---------------------------------------------------------------------- format detection
def test_detect_format(tmp_path, real_files):
    assert detect_format(real_files[0]) == "qualisys"
    assert detect_format(real_files[1]) == "toml"
    xml = tmp_path / "calib.xml"  # a Qualisys file under another name: told by its content
    xml.write_bytes(real_files[0].read_bytes())
    assert detect_format(xml) == "qualisys"
    write_calibration(tmp_path / "cv.xml", _ring(2), "opencv")
    assert detect_format(tmp_path / "cv.xml") == "opencv"
    write_calibration(tmp_path / "cv.yaml", _ring(2), "opencv")
    assert detect_format(tmp_path / "cv.yaml") == "opencv"
    odd = tmp_path / "calib.dat"
    odd.write_text("hello\n")
    with pytest.raises(FormatError, match=r"calib\.dat.*fmt="):
        detect_format(odd)


# ---------------------------------------------------------------------- errors
@pytest.mark.parametrize("name", ["nope.toml", "nope.qca.txt", "nope.yml", "intri.yml"])
def test_missing_file(tmp_path, name):
    with pytest.raises(DataError, match=re.escape(str(tmp_path / name))):
        read_calibration(tmp_path / name)


def test_missing_extrinsics_file(tmp_path):
    write_calibration(tmp_path / "intri.yml", _ring(2), "easymocap")
    (tmp_path / "extri.yml").unlink()
    with pytest.raises(DataError, match="gone.yml"):
        read_calibration(tmp_path / "intri.yml", extrinsics=tmp_path / "gone.yml")
    with pytest.raises(FormatError, match="extrinsics="):
        read_calibration(tmp_path / "intri.yml", fmt="easymocap")
    with pytest.raises(FormatError, match=r"intri\.yml.*'R_c0'.*extrinsics="):  # read as one file: says why
        read_calibration(tmp_path / "intri.yml")


def _toml_text(real_files) -> str:
    return real_files[1].read_text(encoding="utf-8")


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_toml_parse_error_names_file_and_line(tmp_path):
    p = _write(tmp_path, "bad.toml", '[cam]\nname = "a"\nmatrix = [[1, 2]\n')
    with pytest.raises(FormatError) as e:
        read_calibration(p)
    assert str(p) in str(e.value) and e.value.line is not None and f"line {e.value.line}" in str(e.value)


@pytest.mark.parametrize("field", ["matrix", "distortions", "rotation", "translation"])
def test_toml_missing_field(tmp_path, real_files, field):
    text = re.sub(rf"^{field} = .*\n", "", _toml_text(real_files), count=1, flags=re.M)
    p = _write(tmp_path, "c.toml", text)
    with pytest.raises(FormatError) as e:
        read_calibration(p)
    msg = str(e.value)
    assert str(p) in msg and "'int_cam01_img'" in msg and f"'{field}'" in msg and e.value.field == field


def test_toml_fisheye_is_an_error(tmp_path, real_files):
    p = _write(tmp_path, "f.toml", _toml_text(real_files).replace("fisheye = false", "fisheye = true", 1))
    with pytest.raises(FormatError, match=r"f\.toml.*'fisheye'.*'int_cam01_img'.*not supported"):
        read_calibration(p)


def test_toml_bad_values(tmp_path, real_files):
    text = _toml_text(real_files)
    bad = {
        "distortions": re.sub(r"^distortions = .*$", "distortions = [ 0.1, 0.2, 0.3]", text, count=1, flags=re.M),
        "size": text.replace("size = [ 1088.0, 1920.0]", "size = [ 1088.5, 1920.0]", 1),
        "matrix": text.replace("[ 0.0, 0.0, 1.0]]", "[ 0.0, 0.0, 2.0]]", 1),
    }
    for field, t in bad.items():
        p = _write(tmp_path, f"{field}.toml", t)
        with pytest.raises(FormatError) as e:
            read_calibration(p)
        assert str(p) in str(e.value) and f"'{field}'" in str(e.value) and "int_cam01_img" in str(e.value)


def test_qualisys_parse_error_names_file_and_line(tmp_path, real_files):
    lines = real_files[0].read_text(encoding="ascii").splitlines()
    lines[5] = lines[5].replace("/>", ">")  # an unclosed element
    p = _write(tmp_path, "bad.qca.txt", "\n".join(lines))
    with pytest.raises(FormatError) as e:
        read_calibration(p)
    assert str(p) in str(e.value) and e.value.line is not None


@pytest.mark.parametrize("attr,field", [("focalLengthU", "intrinsic.focalLengthU"), ("r22", "transform.r22"),
                                        ("serial", "serial")])
def test_qualisys_missing_attribute(tmp_path, real_files, attr, field):
    text = re.sub(rf' {attr}="[^"]*"', "", real_files[0].read_text(encoding="ascii"), count=1)
    p = _write(tmp_path, "m.qca.txt", text)
    with pytest.raises(FormatError) as e:
        read_calibration(p)
    assert str(p) in str(e.value) and e.value.field == field and f"'{field}'" in str(e.value)
    if attr != "serial":
        assert "'cam01'" in str(e.value)


def test_qualisys_transform_not_a_rotation(tmp_path, real_files):
    text = real_files[0].read_text(encoding="ascii").replace('r11="0.5536380477336265"', 'r11="0.9"', 1)
    p = _write(tmp_path, "r.qca.txt", text)
    with pytest.raises(FormatError, match=r"r\.qca\.txt.*'transform'.*'cam01'.*not a rotation"):
        read_calibration(p)


def test_opencv_parse_error_names_file_and_line(tmp_path):
    p = _write(tmp_path, "bad.yml", "%YAML:1.0\n---\nnames:\n  - a\nK_a: [1, 2, 3\n")
    with pytest.raises(FormatError) as e:
        read_calibration(p)
    assert str(p) in str(e.value) and e.value.line is not None


def _edit_yaml(path: Path, key: str, new_block: str | None) -> None:
    """Replace (or with None delete) the top-level entry ``key`` of a FileStorage YAML file."""
    text = path.read_text()
    pat = re.compile(rf"^{re.escape(key)}:.*?(?=^\S|\Z)", re.M | re.S)
    assert pat.search(text), key
    path.write_text(pat.sub(new_block or "", text, count=1))


def _mat(rows: int, cols: int, data: list[float]) -> str:
    return f"!!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: {data}\n"


@pytest.mark.parametrize("key", ["names", "K_c1", "dist_c1", "T_c1"])
def test_opencv_missing_field(tmp_path, key):
    p = tmp_path / "calib.yml"
    write_calibration(p, _ring(2), "opencv")
    _edit_yaml(p, key, None)
    with pytest.raises(FormatError) as e:
        read_calibration(p)
    assert str(p) in str(e.value) and f"'{key}'" in str(e.value) and e.value.field == key
    if key != "names":
        assert "camera 'c1'" in str(e.value)


def test_easymocap_missing_field_names_the_extrinsics_file(tmp_path):
    intri, extri = write_calibration(tmp_path / "intri.yml", _ring(2), "easymocap")
    _edit_yaml(extri, "T_c0", None)
    with pytest.raises(FormatError) as e:
        read_calibration(intri)
    assert str(extri) in str(e.value) and "'T_c0'" in str(e.value) and "'c0'" in str(e.value)


def test_opencv_rotation_errors(tmp_path):
    p = tmp_path / "calib.yml"
    write_calibration(p, _ring(2), "opencv")
    good = p.read_text()
    _edit_yaml(p, "Rot_c0", "Rot_c0: " + _mat(3, 3, [1.0, 0, 0, 0, 1, 0, 0, 0, -1]))  # a reflection
    with pytest.raises(FormatError, match=r"calib\.yml.*'Rot_c0'.*'c0'.*not a rotation"):
        read_calibration(p)
    p.write_text(good)
    _edit_yaml(p, "Rot_c0", "Rot_c0: " + _mat(3, 3, [1.0, 0, 0, 0, 1, 0, 0, 0, 1]))  # a rotation, not R_c0's
    with pytest.raises(FormatError, match=r"'Rot_c0'.*disagrees with R_c0"):
        read_calibration(p)
    p.write_text(good)
    _edit_yaml(p, "Rot_c0", None)
    _edit_yaml(p, "R_c0", None)
    with pytest.raises(FormatError, match=r"'R_c0'.*missing"):
        read_calibration(p)


def test_opencv_distortion_coefficients(tmp_path):
    cams = _ring(2)
    p = tmp_path / "calib.yml"
    write_calibration(p, cams, "opencv")
    d = list(cams[1].dist)
    _edit_yaml(p, "dist_c1", "dist_c1: " + _mat(1, 8, d + [0.0, 0.0, 0.0]))  # 8 with zeros beyond k3: fine
    assert_same_cameras(cams, read_calibration(p).cameras, tol=1e-9)
    _edit_yaml(p, "dist_c1", "dist_c1: " + _mat(1, 8, d + [0.0, 0.01, 0.0]))  # rational model: refused
    with pytest.raises(FormatError, match=r"calib\.yml.*'dist_c1'.*'c1'.*beyond k1 k2 p1 p2 k3"):
        read_calibration(p)
    _edit_yaml(p, "dist_c1", "dist_c1: " + _mat(1, 3, d[:3]))
    with pytest.raises(FormatError, match=r"'dist_c1'.*at least 4"):
        read_calibration(p)


def test_bad_arguments(tmp_path, real_files):
    with pytest.raises(ConfigError, match="fmt"):
        read_calibration(real_files[1], fmt="json")
    with pytest.raises(ConfigError, match="up must be"):
        read_calibration(real_files[1], up="upwards")
    with pytest.raises(ConfigError, match="units"):
        read_calibration(real_files[1], units="inch")
    with pytest.raises(ConfigError, match="metres"):
        write_calibration(tmp_path / "a.toml", _ring(2), "toml", units="mm")
    with pytest.raises(ConfigError, match="fmt"):
        write_calibration(tmp_path / "a.qca.txt", _ring(2), "qualisys")
    cams = [Camera.look_at("cam.1", eye=(3000.0, 0, 2000), target=(0.0, 0, 1000))]
    with pytest.raises(ConfigError, match="cam.1"):
        write_calibration(tmp_path / "a.yml", cams, "opencv")
    assert not list(tmp_path.iterdir())
