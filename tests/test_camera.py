"""Tests of swarmpose.camera: Bouguet projection, F matrix, scaling, rig files, validation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from swarmpose.camera import Camera, fundamental_matrix, load_rig, save_rig
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError

# R = Rz(90 deg): maps world (x, y, z) to (-y, x, z)
RZ90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
T = np.array([100.0, -50.0, 2000.0])
X_WORLD = np.array([150.0, -300.0, 0.0])
DIST = (0.1, -0.05, 0.001, 0.002, 0.01)


def make_cam(**kw) -> Camera:
    args = dict(name="c0", width=644, height=484, fx=1000.0, fy=1010.0, cx=320.0, cy=240.0, R=RZ90, t=T)
    args.update(kw)
    return Camera(**args)


# ---------------------------------------------------------------------- projection
def test_project_known_point_without_distortion():
    # x_cam = R X + t = (300, 150, 0) + (100, -50, 2000) = (400, 100, 2000)
    # a = 400/2000 = 0.2, b = 100/2000 = 0.05
    # u = fx a + cx = 1000 * 0.2 + 320 = 520 ;  v = fy b + cy = 1010 * 0.05 + 240 = 290.5
    cam = make_cam()
    np.testing.assert_allclose(cam.cam_from_world(X_WORLD), [400.0, 100.0, 2000.0], rtol=0, atol=1e-12)
    uv, z = cam.project_with_depth(X_WORLD)
    np.testing.assert_allclose(uv, [520.0, 290.5], rtol=0, atol=1e-9)
    assert z == pytest.approx(2000.0)


def test_project_known_point_with_distortion_and_skew():
    # a = 0.2, b = 0.05 (as above); k1, k2, p1, p2, k3 = 0.1, -0.05, 0.001, 0.002, 0.01; skew = 0.002
    # r2 = 0.04 + 0.0025 = 0.0425 ; r4 = 0.00180625 ; r6 = 0.000076765625
    # radial = 1 + 0.1*0.0425 - 0.05*0.00180625 + 0.01*0.000076765625 = 1.00416045515625
    # x_d = a*radial + 2 p1 a b + p2 (r2 + 2 a^2)
    #     = 0.20083209103125 + 0.00002 + 0.002 * 0.1225 = 0.20109709103125
    # y_d = b*radial + p1 (r2 + 2 b^2) + 2 p2 a b
    #     = 0.0502080227578125 + 0.001 * 0.0475 + 0.00004 = 0.0502955227578125
    # u = fx (x_d + skew y_d) + cx = 1000 * (0.20109709103125 + 0.000100591045515625) + 320
    #   = 521.197682076765625
    # v = fy y_d + cy = 1010 * 0.0502955227578125 + 240 = 290.798477985390625
    cam = make_cam(dist=DIST, skew=0.002)
    np.testing.assert_allclose(cam.project(X_WORLD), [521.197682076765625, 290.798477985390625], rtol=0, atol=1e-9)


def test_project_batched_any_leading_shape():
    rng = np.random.default_rng(0)
    cam = make_cam(dist=DIST, skew=0.001)
    pts = rng.normal(scale=300.0, size=(2, 5, 7, 3))
    uv = cam.project(pts)
    assert uv.shape == (2, 5, 7, 2)
    flat = np.array([cam.project(p) for p in pts.reshape(-1, 3)])
    np.testing.assert_allclose(uv.reshape(-1, 2), flat, rtol=0, atol=1e-9)
    uv2, z = cam.project_with_depth(pts)
    assert z.shape == (2, 5, 7)
    np.testing.assert_array_equal(uv2, uv)


def test_K_P_center_consistent():
    cam = make_cam(skew=0.003)
    assert cam.K[0, 1] == pytest.approx(0.003 * 1000.0)
    np.testing.assert_allclose(cam.cam_from_world(cam.center), 0.0, atol=1e-9)
    rng = np.random.default_rng(1)
    pts = rng.normal(scale=200.0, size=(20, 3))
    h = np.hstack([pts, np.ones((20, 1))]) @ cam.P.T
    np.testing.assert_allclose(h[:, :2] / h[:, 2:], cam.project(pts), rtol=0, atol=1e-9)
    np.testing.assert_allclose(cam.world_from_cam(cam.cam_from_world(pts)), pts, atol=1e-9)


def test_look_at_geometry():
    cam = Camera.look_at("a", eye=(4000.0, 0.0, 1500.0), target=(0.0, 0.0, 1000.0))
    assert cam.size == (644, 484)
    np.testing.assert_allclose(cam.center, [4000.0, 0.0, 1500.0], atol=1e-9)
    np.testing.assert_allclose(cam.project([0.0, 0.0, 1000.0]), [321.5, 241.5], atol=1e-9)
    # higher in the world -> smaller v; world +y seen from +x looking at -x is on the image right
    up = cam.project([0.0, 0.0, 1200.0])
    right = cam.project([0.0, 200.0, 1000.0])
    assert up[1] < 241.5 and abs(up[0] - 321.5) < 1e-6
    assert right[0] > 321.5
    with pytest.raises(ConfigError):
        Camera.look_at("b", eye=(0, 0, 5000.0), target=(0, 0, 0))  # looking along 'up'
    with pytest.raises(ConfigError):
        Camera.look_at("b", eye=(1.0, 2.0, 3.0), target=(1.0, 2.0, 3.0))


def test_points_behind_camera_have_negative_depth():
    cam = make_cam()
    _, z = cam.project_with_depth([[0.0, 0.0, 0.0], [0.0, 0.0, -5000.0]])
    assert z[0] > 0 and z[1] < 0


# ---------------------------------------------------------------------- undistortion
def test_undistort_inverts_distortion():
    cam = make_cam(dist=DIST, skew=0.002)
    ideal = make_cam(skew=0.002)
    rng = np.random.default_rng(2)
    pts = np.column_stack([rng.uniform(-700, 700, 200), rng.uniform(-500, 500, 200), rng.uniform(-500, 500, 200)])
    uv = cam.project(pts)
    np.testing.assert_allclose(cam.undistort_points(uv), ideal.project(pts), rtol=0, atol=1e-6)
    xyz = cam.cam_from_world(pts)
    np.testing.assert_allclose(cam.undistort_points(uv, output="normalized"), xyz[:, :2] / xyz[:, 2:], atol=1e-9)
    with pytest.raises(ConfigError):
        cam.undistort_points(uv, output="metres")


# ---------------------------------------------------------------------- fundamental matrix
def _ring_cam(name, azimuth_deg, radius, height, f, skew=0.0, dist=(0.0,) * 5):
    a = math.radians(azimuth_deg)
    return Camera.look_at(name, eye=(radius * math.cos(a), radius * math.sin(a), height),
                          target=(0.0, 0.0, 1000.0), f=f, dist=dist, skew=skew)


@settings(max_examples=60, deadline=None)
@given(
    az_a=st.floats(0.0, 360.0),
    delta=st.floats(15.0, 345.0),
    r_a=st.floats(2500.0, 7000.0),
    r_b=st.floats(2500.0, 7000.0),
    h_a=st.floats(500.0, 3000.0),
    h_b=st.floats(500.0, 3000.0),
    f_a=st.floats(300.0, 3000.0),
    f_b=st.floats(300.0, 3000.0),
    skew=st.floats(-0.01, 0.01),
    seed=st.integers(0, 2**32 - 1),
)
def test_fundamental_matrix_epipolar_constraint(az_a, delta, r_a, r_b, h_a, h_b, f_a, f_b, skew, seed):
    cam_a = _ring_cam("a", az_a, r_a, h_a, f_a, skew=skew)
    cam_b = _ring_cam("b", az_a + delta, r_b, h_b, f_b)
    F = fundamental_matrix(cam_a, cam_b)
    assert np.linalg.norm(F) == pytest.approx(1.0)
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-1000, -1000, 0], [1000, 1000, 2000], size=(50, 3))
    xa = np.column_stack([cam_a.project(pts), np.ones(50)])
    xb = np.column_stack([cam_b.project(pts), np.ones(50)])
    resid = np.einsum("ni,ij,nj->n", xb, F, xa)
    # relative to scale: |x_b^T F x_a| / (|x_b| |F| |x_a|) ~ 0
    rel = np.abs(resid) / (np.linalg.norm(xb, axis=1) * np.linalg.norm(xa, axis=1))
    assert rel.max() < 1e-10
    # and geometrically: distance of x_b from the epipolar line F x_a, in pixels
    lines = xa @ F.T
    dist_px = np.abs(resid) / np.hypot(lines[:, 0], lines[:, 1])
    assert dist_px.max() < 1e-6


def test_fundamental_matrix_rank_epipoles_and_distortion():
    cam_a = _ring_cam("a", 0.0, 4000.0, 1500.0, 1000.0, dist=DIST)
    cam_b = _ring_cam("b", 100.0, 4500.0, 1400.0, 900.0, dist=(-0.2, 0.05, 0.0, 0.0, 0.0))
    F = fundamental_matrix(cam_a, cam_b)
    s = np.linalg.svd(F, compute_uv=False)
    assert s[2] < 1e-12 * s[0]
    e_a = cam_a.P @ np.append(cam_b.center, 1.0)  # image of b's centre in a
    e_b = cam_b.P @ np.append(cam_a.center, 1.0)
    np.testing.assert_allclose(F @ e_a / np.linalg.norm(e_a), 0.0, atol=1e-12)
    np.testing.assert_allclose(F.T @ e_b / np.linalg.norm(e_b), 0.0, atol=1e-12)
    # with distortion the constraint holds for undistorted pixels
    rng = np.random.default_rng(3)
    pts = rng.uniform([-800, -800, 0], [800, 800, 1800], size=(100, 3))
    ua = cam_a.undistort_points(cam_a.project(pts))
    ub = cam_b.undistort_points(cam_b.project(pts))
    xa, xb = np.column_stack([ua, np.ones(100)]), np.column_stack([ub, np.ones(100)])
    lines = xa @ F.T
    d = np.abs(np.einsum("ni,ni->n", xb, lines)) / np.hypot(lines[:, 0], lines[:, 1])
    assert d.max() < 1e-6
    # ... but not for the raw distorted ones
    xa_raw = np.column_stack([cam_a.project(pts), np.ones(100)])
    xb_raw = np.column_stack([cam_b.project(pts), np.ones(100)])
    lines = xa_raw @ F.T
    d_raw = np.abs(np.einsum("ni,ni->n", xb_raw, lines)) / np.hypot(lines[:, 0], lines[:, 1])
    assert d_raw.max() > 0.1
    with pytest.raises(ConfigError):
        fundamental_matrix(cam_a, cam_a)


# ---------------------------------------------------------------------- scaling
@pytest.mark.parametrize("factor", [0.5, 0.25, 2.0, 1 / 3])
def test_scaled_matches_resized_pixels(factor):
    cam = make_cam(dist=DIST, skew=0.001, width=644, height=484)
    small = cam.scaled(factor)
    rng = np.random.default_rng(4)
    pts = rng.normal(scale=400.0, size=(100, 3))
    np.testing.assert_allclose(small.project(pts), (cam.project(pts) + 0.5) * factor - 0.5, rtol=0, atol=1e-9)
    assert small.width == int(math.floor(644 * factor + 0.5))
    assert small.height == int(math.floor(484 * factor + 0.5))


def test_scaled_half_size_values():
    cam = make_cam()
    half = cam.scaled(0.5)
    assert (half.width, half.height) == (322, 242)
    assert (half.fx, half.fy) == (500.0, 505.0)
    assert (half.cx, half.cy) == ((320.0 + 0.5) / 2 - 0.5, (240.0 + 0.5) / 2 - 0.5)
    # the centre of the full image maps to the centre of the half image
    centre = Camera.look_at("c", (4000.0, 0, 1000.0), (0, 0, 1000.0))
    np.testing.assert_allclose(centre.scaled(0.5).project([0, 0, 1000.0]), [(322 - 1) / 2, (242 - 1) / 2])
    with pytest.raises(ConfigError):
        cam.scaled(0.0)


# ---------------------------------------------------------------------- serialisation
def _awkward_cam(name="cam1"):
    cam = Camera.look_at(name, eye=(4062.123456789, 663.1 + 0.2, 1528.000001), target=(0.1, 0.2, 1000.3),
                         f=1000.0 / 3.0, dist=(0.1 + 0.2, -1e-17, 1 / 7, 2.0**-40, -0.3))
    return cam


def test_dict_round_trip_exact():
    cam = _awkward_cam()
    d = cam.to_dict()
    text = json.dumps(d)
    back = Camera.from_dict(json.loads(text))
    assert back == cam
    np.testing.assert_array_equal(back.R, cam.R)
    assert back.fx == cam.fx and back.dist == cam.dist and back.t.tolist() == cam.t.tolist()


def test_rig_round_trip_exact(tmp_path):
    cams = [_awkward_cam("a"), make_cam(name="b", dist=DIST, skew=0.002), make_cam(name="c").scaled(1 / 3)]
    path = tmp_path / "rig.json"
    save_rig(path, cams)
    doc = json.loads(path.read_text())
    assert doc["format"] == "swarmpose-rig" and doc["version"] == 1
    back = load_rig(path)
    assert back == cams
    for a, b in zip(back, cams, strict=True):
        assert a.to_dict() == b.to_dict()


def test_camera_arrays_read_only():
    cam = make_cam()
    with pytest.raises(ValueError):
        cam.R[0, 0] = 2.0
    with pytest.raises(ValueError):
        cam.t[0] = 2.0
    with pytest.raises(AttributeError):
        cam.fx = 3.0  # frozen


# ---------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"R": RZ90 * 1.01}, "R"),
        ({"R": np.diag([1.0, 1.0, -1.0])}, "R"),  # det -1
        ({"R": np.eye(2)}, "R"),
        ({"t": [1.0, 2.0]}, "t"),
        ({"t": [np.nan, 0.0, 0.0]}, "t"),
        ({"fx": 0.0}, "fx"),
        ({"fy": -5.0}, "fy"),
        ({"cx": float("inf")}, "cx"),
        ({"width": 0}, "width"),
        ({"height": 10.5}, "height"),
        ({"dist": (0.1, 0.2, 0.0, 0.0)}, "dist"),
        ({"dist": (0.1, 0.2, 0.0, 0.0, float("nan"))}, "dist"),
        ({"name": ""}, "name"),
    ],
)
def test_invalid_camera_raises_config_error(kw, field):
    with pytest.raises(ConfigError, match=field) as info:
        make_cam(**kw)
    assert isinstance(info.value, ValueError)


def test_project_bad_shape():
    with pytest.raises(ShapeError):
        make_cam().project(np.zeros((4, 2)))
    with pytest.raises(ShapeError):
        make_cam().undistort_points(np.zeros((4, 3)))


def test_load_rig_errors(tmp_path):
    good = make_cam().to_dict()
    path = tmp_path / "rig.json"

    def write(doc):
        path.write_text(json.dumps(doc))

    missing = dict(good)
    del missing["fx"]
    write({"format": "swarmpose-rig", "version": 1, "cameras": [missing]})
    with pytest.raises(FormatError, match="fx") as info:
        load_rig(path)
    assert str(path) in str(info.value) and info.value.field == "fx"

    write({"format": "swarmpose-rig", "version": 1, "cameras": [dict(good, R=(np.eye(3) * 2).tolist())]})
    with pytest.raises(FormatError, match="orthonormal") as info:
        load_rig(path)
    assert info.value.field == "R"

    write({"format": "swarmpose-rig", "version": 1, "cameras": [dict(good, fx="1000")]})
    with pytest.raises(FormatError, match="fx"):
        load_rig(path)
    write({"format": "swarmpose-rig", "version": 1, "cameras": [dict(good, lens="wide")]})
    with pytest.raises(FormatError, match="lens"):
        load_rig(path)
    write({"format": "other", "version": 1, "cameras": []})
    with pytest.raises(FormatError, match="format"):
        load_rig(path)
    write({"format": "swarmpose-rig", "version": 2, "cameras": []})
    with pytest.raises(FormatError, match="version"):
        load_rig(path)
    write({"format": "swarmpose-rig", "version": 1})
    with pytest.raises(FormatError, match="cameras"):
        load_rig(path)
    write({"format": "swarmpose-rig", "version": 1, "cameras": [good, good]})
    with pytest.raises(FormatError, match="unique"):
        load_rig(path)
    path.write_text('{"format": "swarmpose-rig",\n "version": 1,,}')
    with pytest.raises(FormatError, match="line 2"):
        load_rig(path)
    with pytest.raises(DataError):
        load_rig(tmp_path / "nope.json")
    path.write_bytes(b"\x89PNG\r\n\x1a\n\xff")  # an image saved under the rig's name
    with pytest.raises(FormatError, match="not a UTF-8 text file") as info:
        load_rig(path)
    assert str(path) in str(info.value)
    with pytest.raises(ConfigError):
        save_rig(tmp_path / "dup.json", [make_cam(), make_cam()])
