"""TRC and C3D export: written from known joints and read back (TRC with swarmpose's parser, C3D with ezc3d),
the values agree to 0.01 mm once the axes are undone; `swarmpose export --out x.trc / x.c3d` writes joints.npz."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from swarmpose.cli.app import app
from swarmpose.errors import ConfigError, FormatError, ShapeError
from swarmpose.export.c3d_export import write_c3d
from swarmpose.export.trc import TRC_FROM_WORLD, TRC_HEADER_KEYS, read_trc, write_trc
from swarmpose.joints import JOINTS15

OPENSIM_KEYS = "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames"


def known_joints(T: int = 9, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Random joints (world mm, up to 5 m from the origin) with a few missing, and their times at 20 fps."""
    rng = np.random.default_rng(seed)
    J = rng.uniform(-5000.0, 5000.0, (T, 15, 3))
    J[:, :, 2] = rng.uniform(0.0, 2000.0, (T, 15))
    J[2 % T, 4, 0] = np.nan  # one coordinate missing: the point is missing
    J[5 % T, 14] = np.nan
    J[T - 1, 14, 2] = np.inf  # the last marker of the last row: its empty fields end the row
    return J, np.arange(T) / 20.0


def missing(J: np.ndarray) -> np.ndarray:
    return ~np.isfinite(J).all(axis=2)


def test_trc_layout_is_opensims(tmp_path: Path):
    """Field names and order of OpenSim's TRCFileAdapter: five header lines, a blank line, then the rows, each
    value followed by a tab; frames from 1; a missing marker's three fields empty."""
    J, t = known_joints()
    path = write_trc(tmp_path / "walk.trc", J, t)
    lines = path.read_text(encoding="utf-8").split("\n")
    assert lines[0] == "PathFileType\t4\t(X/Y/Z)\twalk.trc"
    assert lines[1] == OPENSIM_KEYS and tuple(lines[1].split("\t")) == TRC_HEADER_KEYS
    assert lines[2] == "20\t20\t9\t15\tmm\t20\t1\t9"
    assert lines[3] == "Frame#\tTime\t" + "".join(f"{n}\t\t\t" for n in JOINTS15)
    assert lines[4] == "\t\t" + "".join(f"X{k}\tY{k}\tZ{k}\t" for k in range(1, 16))
    assert lines[5] == ""
    rows = [ln.split("\t") for ln in lines[6:] if ln]
    assert len(rows) == 9 and [r[0] for r in rows] == [str(k) for k in range(1, 10)]
    assert [float(r[1]) for r in rows] == pytest.approx(t, abs=1e-9)
    assert all(len(r) == 2 + 45 + 1 and r[-1] == "" for r in rows)  # the tab after the last value
    assert rows[2][2 + 3 * 4: 5 + 3 * 4] == ["", "", ""]  # l_wrist of frame 3
    assert rows[5][2 + 3 * 14: 5 + 3 * 14] == ["", "", ""]
    assert "nan" not in path.read_text().lower() and "inf" not in path.read_text().lower()
    assert lines[-1] == ""  # the file ends with a line break


@pytest.mark.parametrize("units", ["mm", "m"])
def test_trc_round_trip(tmp_path: Path, units: str):
    J, t = known_joints()
    names, times, points, header = read_trc(write_trc(tmp_path / "m.trc", J, t, units=units))
    assert names == list(JOINTS15) and header["Units"] == units and header["NumFrames"] == 9
    assert header["DataRate"] == header["CameraRate"] == header["OrigDataRate"] == 20.0
    np.testing.assert_allclose(times, t, atol=1e-9)
    world = points @ TRC_FROM_WORLD / (1.0 if units == "mm" else 0.001)  # undo trc = A world (A orthogonal)
    np.testing.assert_array_equal(np.isnan(world).any(axis=2), missing(J))
    assert np.isnan(world[missing(J)]).all()  # a point is missing as a whole
    ok = ~missing(J)
    np.testing.assert_allclose(world[ok], J[ok], atol=0.01)


def test_trc_axes_are_opensims_y_up(tmp_path: Path):
    """World (x, y, z) with z up is written (x, z, -y): up is +Y, forward stays +X, the subject's left is -Z."""
    J = np.zeros((2, 15, 3))
    J[:, JOINTS15.index("head_top")] = [100.0, 200.0, 1700.0]
    J[:, JOINTS15.index("l_hip")] = [0.0, 120.0, 900.0]
    _, _, points, _ = read_trc(write_trc(tmp_path / "a.trc", J, [0.0, 0.1]))
    np.testing.assert_allclose(points[0, JOINTS15.index("head_top")], [100.0, 1700.0, -200.0])
    np.testing.assert_allclose(points[0, JOINTS15.index("l_hip")], [0.0, 900.0, -120.0])
    np.testing.assert_allclose(TRC_FROM_WORLD @ TRC_FROM_WORLD.T, np.eye(3))
    assert np.linalg.det(TRC_FROM_WORLD) == pytest.approx(1.0)  # a rotation, not a mirror


def test_trc_frame_rate_and_times(tmp_path: Path):
    """The rate is frame_rate when given, else 1 / the median interval; the Time column keeps the times given."""
    J, _ = known_joints(T=4)
    t = np.array([0.5, 0.533, 0.583, 0.617])  # uneven, as tracked at 25 fps from 60
    names, times, _, header = read_trc(write_trc(tmp_path / "u.trc", J, t, frame_rate=25.0))
    assert header["DataRate"] == 25.0 and times == pytest.approx(t, abs=1e-9)
    _, _, _, header = read_trc(write_trc(tmp_path / "v.trc", J, np.arange(4) / 60.0))
    assert header["DataRate"] == pytest.approx(60.0)
    with pytest.raises(ConfigError, match="give frame_rate"):
        write_trc(tmp_path / "one.trc", J[:1], [0.0])
    assert read_trc(write_trc(tmp_path / "one.trc", J[:1], [0.0], frame_rate=30.0)).header["NumFrames"] == 1


def test_trc_errors_leave_no_file(tmp_path: Path):
    J, t = known_joints(T=3)
    for kwargs, error, match in (({"units": "cm"}, ConfigError, "mm, m"),
                                 ({"names": JOINTS15[:14]}, ShapeError, "15 markers but 14 names"),
                                 ({"names": ["a\tb", *JOINTS15[1:]]}, ConfigError, "without tabs"),
                                 ({"frame_rate": 0.0}, ConfigError, "frame_rate must be > 0")):
        with pytest.raises(error, match=match):
            write_trc(tmp_path / "x.trc", J, t, **kwargs)
    with pytest.raises(ConfigError, match="increasing"):
        write_trc(tmp_path / "x.trc", J, [0.0, 0.1, 0.1])
    with pytest.raises(ShapeError, match="one per frame"):
        write_trc(tmp_path / "x.trc", J, [0.0, 0.1])
    with pytest.raises(ShapeError, match=r"\(T, M, 3\)"):
        write_trc(tmp_path / "x.trc", J[..., :2], t)
    assert list(tmp_path.iterdir()) == []


def test_read_trc_takes_other_writers_rows_and_refuses_other_files(tmp_path: Path):
    """Rows without the trailing tab (and CRLF line ends), as other tools write them, read the same."""
    text = ("PathFileType\t4\t(X/Y/Z)\tother.trc\r\n" + OPENSIM_KEYS + "\r\n60\t60\t2\t2\tm\t60\t1\t2\r\n"
            "Frame#\tTime\tRHip\t\t\tRKnee\t\t\r\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\r\n\r\n"
            "1\t0.000\t0.1\t0.2\t0.3\t0.4\t0.5\t0.6\r\n2\t0.0167\t0.11\t0.21\t0.31\r\n")
    (tmp_path / "other.trc").write_bytes(text.encode())
    names, times, points, header = read_trc(tmp_path / "other.trc")
    assert names == ["RHip", "RKnee"] and header["Units"] == "m" and header["FileName"] == "other.trc"
    np.testing.assert_allclose(times, [0.0, 0.0167])
    np.testing.assert_allclose(points[0], [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    assert np.isnan(points[1, 1]).all() and np.isfinite(points[1, 0]).all()
    (tmp_path / "bad.trc").write_text(text.replace("OrigDataStartFrame", "StartFrame"))
    with pytest.raises(FormatError, match="line 2"):
        read_trc(tmp_path / "bad.trc")
    (tmp_path / "bad.trc").write_text(text.replace("0.0167", "soon"))
    with pytest.raises(FormatError, match="line 8"):
        read_trc(tmp_path / "bad.trc")


def test_c3d_without_ezc3d_says_how_to_install(tmp_path: Path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ezc3d", None)  # import ezc3d raises ImportError
    J, t = known_joints(T=3)
    with pytest.raises(ConfigError, match=r"pip install 'swarmpose\[export\]'"):
        write_c3d(tmp_path / "x.c3d", J, t)
    assert not (tmp_path / "x.c3d").exists()
    res, _ = small_results(tmp_path / "res", np.arange(3) / 20.0)
    bad = CliRunner().invoke(app, ["export", str(res), "--out", str(tmp_path / "x.c3d"), "--json"])
    assert bad.exit_code == 2 and "pip install 'swarmpose[export]'" in json.loads(bad.stdout)["error"]
    assert not (tmp_path / "x.c3d").exists()


def test_c3d_round_trip(tmp_path: Path):
    ezc3d = pytest.importorskip("ezc3d", reason="C3D export needs ezc3d (pip install 'swarmpose[export]')")
    J, t = known_joints()
    path = write_c3d(tmp_path / "m.c3d", J, t)
    assert [p.name for p in tmp_path.iterdir()] == ["m.c3d"]  # no temporary file left
    c = ezc3d.c3d(str(path))
    point = c["parameters"]["POINT"]
    assert list(point["LABELS"]["value"]) == list(JOINTS15)
    assert float(point["RATE"]["value"][0]) == 20.0 and c["header"]["points"]["frame_rate"] == 20.0
    assert list(point["UNITS"]["value"]) == ["mm"]
    assert list(point["X_SCREEN"]["value"]) == ["+X"] and list(point["Y_SCREEN"]["value"]) == ["+Z"]
    assert int(c["parameters"]["ANALOG"]["USED"]["value"][0]) == 0 and c["data"]["analogs"].size == 0
    xyz = c["data"]["points"][:3].transpose(2, 1, 0)  # (3, M, T) -> (T, M, 3), the world's own axes
    assert xyz.shape == J.shape
    residuals = c["data"]["meta_points"]["residuals"][0].T  # (T, M)
    np.testing.assert_array_equal(residuals < 0, missing(J))
    assert (residuals[missing(J)] == -1).all() and np.isnan(xyz[missing(J)]).all()
    ok = ~missing(J)
    np.testing.assert_allclose(xyz[ok], J[ok], atol=0.01)
    with pytest.raises(ConfigError, match="frame_rate must be > 0"):
        write_c3d(tmp_path / "bad.c3d", J, t, frame_rate=-1.0)


# --------------------------------------------------------------------------- through `swarmpose export`


def small_results(root: Path, times: np.ndarray, fps: float = 20.0) -> tuple[Path, np.ndarray]:
    """A results folder with the layout `swarmpose track` writes (config.json, run_000/track.npz and
    joints.npz), holding a walking balan31's joints at ``times``; return it and the joints."""
    from swarmpose.body.model import load_model

    model = load_model("balan31")
    T = len(times)
    P = np.zeros((T, model.n_params))
    P[:, model.param_index("pelvis_tx")] = 1000.0 * times  # 1 m/s
    P[:, model.param_index("pelvis_tz")] = 950.0
    P[:, model.param_index("l_hip_flex")] = 0.4 * np.sin(2.0 * np.pi * times)
    P[:, model.param_index("r_knee_flex")] = 0.3 + 0.3 * np.cos(2.0 * np.pi * times)
    joints = model.joints15(P)
    root.mkdir(parents=True)
    (root / "config.json").write_text(json.dumps({"algo": "sppso", "fps": fps, "model": "balan31", "runs": 1,
                                                  "frames": T}))
    run = root / "run_000"
    run.mkdir()
    np.savez(run / "track.npz", params=P, joints=joints, frame_indices=np.round(times * 60).astype(int),
             seconds=np.full(T, 0.5), evaluations=np.full(T, 1000))
    np.savez(run / "joints.npz", joints=joints, gt_joints=joints, frame_times=times, world_from_source=np.eye(4))
    return root, joints


def _export(args: list[str]) -> dict:
    res = CliRunner().invoke(app, ["export", *args, "--json"])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def test_export_trc_agrees_with_joints_npz(tmp_path: Path):
    res, joints = small_results(tmp_path / "res", np.arange(6) / 20.0)
    for units, scale in (("mm", 1.0), ("m", 0.001)):
        out = tmp_path / f"walk_{units}.trc"
        data = _export([str(res), "--out", str(out), "--units", units])
        assert data["file"] == str(out) and data["format"] == "trc" and data["units"] == units
        assert data["frames"] == 6 and data["frame_rate"] == 20.0 and data["axes"] == "y_up"
        assert data["from_world"] == "(x, z, -y)" and data["missing_points"] == 0 and data["resampled"] is False
        names, times, points, header = read_trc(out)
        assert names == list(JOINTS15) and header["Units"] == units and header["DataRate"] == 20.0
        np.testing.assert_allclose(times, np.arange(6) / 20.0, atol=1e-9)
        np.testing.assert_allclose(points @ TRC_FROM_WORLD / scale, joints, atol=0.01)
    text = CliRunner().invoke(app, ["export", str(res), "--out", str(tmp_path / "t.trc")])
    assert text.exit_code == 0 and "15 markers (Y up: (x, z, -y) of the world, mm)" in " ".join(text.output.split())


def test_export_c3d_agrees_with_joints_npz(tmp_path: Path):
    ezc3d = pytest.importorskip("ezc3d", reason="C3D export needs ezc3d (pip install 'swarmpose[export]')")
    res, joints = small_results(tmp_path / "res", np.arange(6) / 20.0)
    out = tmp_path / "walk.c3d"
    data = _export([str(res), "--out", str(out)])
    assert data["file"] == str(out) and data["format"] == "c3d" and data["units"] == "mm"
    assert data["frames"] == 6 and data["axes"] == "z_up" and data["from_world"] == "(x, y, z)"
    c = ezc3d.c3d(str(out))
    assert list(c["parameters"]["POINT"]["LABELS"]["value"]) == list(JOINTS15)
    assert float(c["parameters"]["POINT"]["RATE"]["value"][0]) == 20.0
    np.testing.assert_allclose(c["data"]["points"][:3].transpose(2, 1, 0), joints, atol=0.01)
    again = CliRunner().invoke(app, ["export", str(res), "--out", str(out), "--json"])
    assert again.exit_code == 2 and "exists; add --force" in json.loads(again.stdout)["error"]
    assert _export([str(res), "--out", str(out), "--force"])["frames"] == 6


def test_export_puts_uneven_frames_on_an_even_clock(tmp_path: Path):
    """25 fps tracked from 60 fps: frames 33 and 50 ms apart. As for BVH, the joints are interpolated onto
    t0 + k / 25 (C3D has one rate); --no-resample keeps the tracked frames, and a TRC file their times."""
    t = np.round(np.arange(8) / 25 * 60) / 60
    res, joints = small_results(tmp_path / "res", t, fps=25.0)
    data = _export([str(res), "--out", str(tmp_path / "even.trc")])
    assert data["resampled"] is True and data["frames"] == 8 and data["tracked_frames"] == 8
    _, times, points, header = read_trc(tmp_path / "even.trc")
    np.testing.assert_allclose(times, np.arange(8) / 25.0, atol=1e-6)
    world = points @ TRC_FROM_WORLD
    expected = np.stack([np.interp(times, t, joints[:, j, a]) for j in range(15) for a in range(3)], axis=1)
    np.testing.assert_allclose(world.reshape(8, 45), expected, atol=0.01)
    kept = _export([str(res), "--out", str(tmp_path / "kept.trc"), "--no-resample"])
    assert kept["resampled"] is False
    _, times, points, header = read_trc(tmp_path / "kept.trc")
    assert header["DataRate"] == 25.0 and times == pytest.approx(t, abs=1e-6)
    np.testing.assert_allclose(points @ TRC_FROM_WORLD, joints, atol=0.01)


def test_export_options_that_do_not_fit_the_format_are_refused(tmp_path: Path):
    res, _ = small_results(tmp_path / "res", np.arange(3) / 20.0)
    runner = CliRunner()
    for args, message in ((["--out", str(tmp_path / "x.trc"), "--z-up"], "--z-up applies to BVH files"),
                          (["--out", str(tmp_path / "x.trc"), "--order", "XYZ", "--rest-facing", "+x"],
                           "--order, --rest-facing apply to BVH files"),
                          (["--out", str(tmp_path / "x.trc"), "--units", "cm"], "--unit must be one of mm, m for TRC"),
                          (["--out", str(tmp_path / "x.c3d"), "--unit", "m"], "--unit must be one of mm for C3D"),
                          (["--out", str(tmp_path / "x.txt")], "the suffix picks the format: .bvh, .trc or .c3d")):
        bad = runner.invoke(app, ["export", str(res), *args, "--json"])
        assert bad.exit_code == 2, bad.output
        assert message in json.loads(bad.stdout)["error"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]
