"""HumanEva folders -> MultiViewSequence: sync, lazy video, projection of ground truth, silhouettes, errors."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from he_fixtures import LOST, expected_joints15, texture

from swarmpose.datasets import dataset_sequence_name, is_dataset_spec, open_dataset_sequence
from swarmpose.datasets.humaneva import (
    BackgroundModel,
    HumanEvaFrames,
    VideoSource,
    humaneva_background_model,
    humaneva_sequence,
    humaneva_silhouette,
    open_humaneva,
    parse_humaneva_spec,
)
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError
from swarmpose.io.sequence import MultiViewSequence, open_sequence, write_sequence


def _patch(images: np.ndarray) -> np.ndarray:
    """The video frame index (0-based) each view shows, read from the fixture's 8x8 code block."""
    return np.rint(images[:, 1:7, 1:7].astype(float).mean(axis=(1, 2)) / 10.0).astype(int) - 1


def _on_dots(seq: MultiViewSequence, k: int, stream: str = "image") -> np.ndarray:
    """Per view, per joint: the brightest value within 1 px of the projected ground-truth joint."""
    imgs = seq.images(k) if stream == "image" else seq.silhouettes(k)
    out = np.zeros((seq.n_views, 15))
    for c, cam in enumerate(seq.cameras):
        uv = np.rint(cam.project(seq.gt_joints[k])).astype(int)
        assert (uv >= 1).all() and (uv[:, 0] < cam.width - 1).all() and (uv[:, 1] < cam.height - 1).all()
        out[c] = [imgs[c, v - 1:v + 2, u - 1:u + 2].max() for u, v in uv]
    return out


@pytest.fixture()
def he1_seq(he1, tmp_path):
    with humaneva_sequence(he1.spec + "?split=all", cache_dir=tmp_path / "cache") as seq:
        yield seq


def test_sequence_frames_sync_and_ground_truth(he1, he1_seq):
    seq = he1_seq
    assert isinstance(seq, MultiViewSequence)
    assert seq.view_names == ["C1", "C2", "C3"] and seq.image_size == (160, 120) and seq.frame_rate == 60.0
    # synchronized frames 6..18: C3 starts at video frame 7 and has 24 frames -> last F = 24 - 7 + 1 = 18
    assert seq.n_frames == 13 and seq.provenance["sync_frames"] == [6, 18]
    assert seq.provenance["video_start"] == {"C1": 6, "C2": 5, "C3": 7}
    np.testing.assert_allclose(seq.frame_times, np.arange(13) / 60.0)
    F = np.arange(6, 19)
    for k in (0, 4, 12):  # lazily decoded frame k shows video frame start + F - 1 (1-based)
        np.testing.assert_array_equal(_patch(seq.images(k)), [6 + F[k] - 2, 5 + F[k] - 2, 7 + F[k] - 2])
    # ground truth at mocap position T0 + (F - 1) s = 2F - 1; frame F = 7 brackets the lost marker
    expected = np.stack([expected_joints15(2 * f - 1) for f in F])
    bad = F == (LOST[1] + 1) // 2
    np.testing.assert_allclose(seq.gt_joints[~bad], expected[~bad], atol=1e-6)
    assert np.isnan(seq.gt_joints[bad]).all() and seq.provenance["invalid_frames"] == 1


def test_ground_truth_projects_onto_the_fixture_dots(he1_seq):
    seq = he1_seq
    for k in range(seq.n_frames):
        if np.isnan(seq.gt_joints[k]).any():
            continue
        assert _on_dots(seq, k).min() >= 200  # white dots (background texture is <= ~120)


def test_silhouette_stream_finds_the_dots(he1_seq):
    seq = he1_seq
    assert seq.streams == ("image", "silhouette") and seq.backgrounds().shape == (3, 120, 160)
    sil = seq.silhouettes(3)
    assert sil.dtype == np.uint8 and set(np.unique(sil)) <= {0, 1}
    assert _on_dots(seq, 3, "silhouette").mean() > 0.9
    rest = sil.copy()
    rest[:, :8, :8] = 0  # the frame-code block is not in the background footage
    assert rest.mean() < 0.05


def test_round_trip_through_the_sequence_format(he1_seq, tmp_path):
    seq = he1_seq
    path = write_sequence(tmp_path / "out", seq)
    with open_sequence(path) as back:
        assert back.n_frames == seq.n_frames and back.view_names == seq.view_names
        assert back.cameras == seq.cameras
        np.testing.assert_array_equal(back.gt_joints, seq.gt_joints)
        np.testing.assert_array_equal(back.backgrounds(), seq.backgrounds())
        for k in (0, 7):
            np.testing.assert_array_equal(back.images(k), seq.images(k))
            np.testing.assert_array_equal(back.silhouettes(k), seq.silhouettes(k))
        assert back.provenance["source"] == "humaneva"


def test_greyscale_cameras_and_explicit_frames(he1, tmp_path):
    with humaneva_sequence(he1.spec + "?cams=BW1,BW2,BW3,BW4&frames=8-10", cache_dir=tmp_path) as seq:
        assert seq.view_names == ["BW1", "BW2", "BW3", "BW4"] and seq.image_size == (164, 124)
        assert seq.n_frames == 3
        np.testing.assert_array_equal(_patch(seq.images(0)), [6 + 8 - 2, 6 + 8 - 2, 7 + 8 - 2, 6 + 8 - 2])
        assert _on_dots(seq, 2).min() >= 200


def test_camera_kinds_cannot_be_mixed(he1, tmp_path):
    with pytest.raises(ShapeError, match="different image sizes"):
        humaneva_sequence(he1.spec + "?cams=C1,BW1", cache_dir=tmp_path)


def test_official_partition_is_the_default(he1, tmp_path):
    trial = open_humaneva(he1.subject_dir, "Walking", 1)
    assert trial.dataset == "HumanEva-I" and trial.frame_range() == (6, 590)
    assert trial.frame_range("train") == (591, 1203)
    with pytest.raises(DataError, match="frames 6-590 requested"):
        humaneva_sequence(he1.spec, cache_dir=tmp_path)  # the fixture is far shorter than the real trial
    with pytest.raises(DataError, match="frames 6-40 requested"):
        humaneva_sequence(he1.spec + "?frames=6-40", cache_dir=tmp_path)


def test_humaneva_ii_image_folders(he2, tmp_path):
    with humaneva_sequence(he2.spec + "?split=all", cache_dir=tmp_path) as seq:
        assert seq.provenance["dataset"] == "HumanEva-II"
        assert seq.view_names == ["C1", "C2", "C3", "C4"] and seq.n_frames == 20
        np.testing.assert_array_equal(_patch(seq.images(0)), [0, 0, 0, 0])  # PNG: exact
        np.testing.assert_array_equal(_patch(seq.images(19)), [19] * 4)
        np.testing.assert_allclose(seq.gt_joints[5], expected_joints15(1 + 5 * 2), atol=1e-6)
        assert _on_dots(seq, 5).min() == 255
        assert seq.provenance["risk"] == {"C1": 1e80, "C2": 1e60, "C3": 1e30, "C4": 1e80}
        assert _on_dots(seq, 5, "silhouette").mean() > 0.9
    assert open_humaneva(he2.subject_dir, "Combo", 4).frame_range() == (2, 1258)


def test_dispatch_helpers(he1, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the background cache goes to ./cache/humaneva
    spec = he1.spec + "?split=all&cams=C1,C2"
    assert is_dataset_spec(spec) and is_dataset_spec(Path(spec)) and not is_dataset_spec(tmp_path)
    assert dataset_sequence_name(spec) == "S1_Walking_1-C1-C2"
    with open_dataset_sequence(Path(spec)) as seq:  # a Path made from the spec works too
        assert seq.view_names == ["C1", "C2"]
    assert (tmp_path / "cache" / "humaneva").is_dir()
    with open_dataset_sequence(spec, silhouettes=False) as seq:
        assert seq.streams == ("image",)
    with open_sequence(spec) as seq:  # swarmpose.datasets registers its prefixes with io's open_sequence
        assert seq.view_names == ["C1", "C2"]


@pytest.mark.parametrize(("spec", "match"), [
    ("humaneva:/x/S1/Walking", "Action>_<Trial"),
    ("humaneva:/x/S1/Walking_1?cam=C1", "unknown humaneva option 'cam'"),
    ("humaneva:/x/S1/Walking_1?frames=6", "frames must look like"),
    ("humaneva:/x/S1/Walking_1?dataset=III", "dataset must be"),
    ("humaneva:", "needs a path"),
    ("humaneva:/x/S1/Walking_1?cams=", "cams names no camera"),
    ("humaneva:/x/S1/Walking_1?cams=,", "cams names no camera"),
])
def test_spec_errors(spec, match):
    with pytest.raises(ConfigError, match=match):
        parse_humaneva_spec(spec)


def test_spec_parsing():
    s = parse_humaneva_spec("humaneva:/data/HumanEva/S2/ThrowCatch_2?cams=BW1,BW2&split=test&bgframes=0&dataset=I")
    assert (s.subject_dir, s.action, s.trial) == (Path("/data/HumanEva/S2"), "ThrowCatch", "2")
    assert s.options == {"cameras": ("BW1", "BW2"), "split": "test", "background_frames": None,
                         "dataset": "HumanEva-I"}


def test_missing_and_broken_files_are_named(he1_copy, tmp_path):
    sd = he1_copy.subject_dir
    (sd / "Image_Data" / "Walking_1_(C2).avi").unlink()
    with pytest.raises(DataError, match=r"Walking_1_\(C2\)\.avi: missing video"):
        humaneva_sequence(he1_copy.spec + "?split=all", cache_dir=tmp_path)
    with pytest.raises(DataError, match=rf"missing video.*`swarmpose datasets check {re.escape(str(sd))}` lists"):
        open_dataset_sequence(he1_copy.spec + "?split=all", cache_dir=tmp_path)  # what track opens with
    (sd / "Image_Data" / "Walking_1_(C2).avi").write_bytes(b"RIFF\x00\x00" + bytes(300))
    with pytest.raises((DataError, FormatError), match=r"Walking_1_\(C2\)\.avi"):
        humaneva_sequence(he1_copy.spec + "?split=all", cache_dir=tmp_path)
    (sd / "Sync_Data" / "Walking_1_(C3).ofs").write_text("9\n5\n")
    with pytest.raises(FormatError, match=r"Walking_1_\(C3\)\.ofs.*truncated"):
        open_humaneva(sd, "Walking", 1)
    for f in (sd / "Sync_Data").glob("*.ofs"):
        f.unlink()
    with pytest.raises(DataError, match="no sync file"):
        open_humaneva(sd, "Walking", 1)
    with pytest.raises(DataError, match="no such HumanEva subject"):
        open_humaneva(sd.parent / "S9", "Walking", 1)


def test_missing_mp_and_labels_named(he1_copy, tmp_path):
    sd = he1_copy.subject_dir
    (sd / "Mocap_Data" / "S1.mp").unlink()
    with pytest.raises(DataError, match=r"S1\.mp: missing subject measurement"):
        humaneva_sequence(he1_copy.spec + "?split=all", cache_dir=tmp_path)


def test_without_background_footage_there_is_no_silhouette_stream(he1_copy, tmp_path):
    shutil.rmtree(he1_copy.root / "Background")
    with humaneva_sequence(he1_copy.spec + "?split=all", cache_dir=tmp_path) as seq:
        assert seq.streams == ("image",) and seq.backgrounds() is None


def test_background_cache_is_reused(he1, tmp_path):
    with humaneva_sequence(he1.spec + "?split=all&cams=C1", cache_dir=tmp_path) as a:
        files = sorted(tmp_path.glob("background-C1-*.npz"))
        assert len(files) == 1
        mtime = files[0].stat().st_mtime_ns
        with humaneva_sequence(he1.spec + "?split=all&cams=C1", cache_dir=tmp_path) as b:
            np.testing.assert_array_equal(a.backgrounds(), b.backgrounds())
        assert files[0].stat().st_mtime_ns == mtime


# ---------------------------------------------------------------------- background model (in memory)
def _model(rng, h=40, w=50, sigma=3.0):
    """Three recording sessions of one scene under slightly different light."""
    base = np.repeat(texture(rng, w, h)[..., None], 3, 2).astype(int)
    bgs = [np.clip(base + d, 0, 255).astype(np.uint8) for d in (0, 4, -4)]
    frames = [[np.clip(b + rng.normal(0, sigma, b.shape), 0, 255).astype(np.uint8) for _ in range(30)] for b in bgs]
    return bgs, humaneva_background_model(frames)


def test_background_model_statistics():
    rng = np.random.default_rng(0)
    bgs, model = _model(rng)
    assert model.means.shape == (3, 40, 50, 3)
    np.testing.assert_allclose(model.means * 255, np.stack(bgs), atol=3.0)
    assert 1.5 < np.sqrt(model.variances.mean()) * 255 < 4.5
    const = humaneva_background_model([[np.full((4, 5, 3), 100, np.uint8)] * 3])
    assert np.all(const.variances == np.float32(1e-3))  # zero variance -> 1e-3, as the support code


def test_humaneva_silhouette_detects_a_square_and_filters_specks():
    rng = np.random.default_rng(1)
    bgs, model = _model(rng)
    frame = np.clip(bgs[1] + rng.normal(0, 3.0, bgs[1].shape), 0, 255).astype(np.uint8)
    truth = np.zeros((40, 50), np.uint8)
    truth[10:30, 15:35] = 1
    frame[truth == 1] = (200, 40, 40)
    frame[2, 2] = (255, 255, 255)  # a one-pixel speck
    sil = humaneva_silhouette(frame, model, min_area=10)
    assert sil[2, 2] == 0 and (sil == truth).mean() > 0.99
    assert humaneva_silhouette(frame, model, min_area=0)[2, 2] == 1
    frame[35:38, 40:45] = 250  # a second blob of 15 px survives min_area but not largest_only
    assert humaneva_silhouette(frame, model)[36, 42] == 1
    assert humaneva_silhouette(frame, model, largest_only=True)[36, 42] == 0
    # a higher risk makes the test less sensitive (HumanEva-II uses 1e30-1e80)
    faint = np.clip(bgs[0].astype(int) + 25, 0, 255).astype(np.uint8)
    assert humaneva_silhouette(faint, model, min_area=0).mean() > 0.9
    assert humaneva_silhouette(faint, model, min_area=0, risk=1e80).mean() < 0.1
    grey = faint[..., 0]
    np.testing.assert_array_equal(humaneva_silhouette(grey, model, min_area=0),
                                  humaneva_silhouette(faint, model, min_area=0))
    with pytest.raises(ConfigError):
        humaneva_silhouette(frame, model, risk=0)
    with pytest.raises(ShapeError):
        humaneva_silhouette(frame[:10], model)
    with pytest.raises(ShapeError):
        BackgroundModel(model.means, model.variances[:1])


def test_video_source_reads_avi_and_folders(he1, he2):
    with VideoSource(he1.subject_dir / "Image_Data" / "Walking_1_(C1).avi") as v:
        assert v.n_frames == 24 and v.size == (160, 120)
        order = [5, 6, 2, 23, 0]  # sequential and random access
        codes = [int(round(v.read(i)[1:7, 1:7].mean() / 10)) - 1 for i in order]
        assert codes == order
        with pytest.raises(IndexError):
            v.read(24)
    with VideoSource(he2.subject_dir / "Image_Data" / "Combo_4_(C2)") as v:
        assert v.n_frames == 20 and v.read(3)[0, 0, 0] == 40
    with pytest.raises(DataError, match="missing video"):
        VideoSource(he1.subject_dir / "Image_Data" / "nothing.avi")


def test_frame_reader_protocol_checks():
    with pytest.raises(ShapeError):
        HumanEvaFrames([], np.zeros((3, 2)))


class _ClosedCapture:
    def __init__(self, *a):
        pass

    def isOpened(self):
        return False

    def release(self):
        pass


def test_imageio_fallback(he1, monkeypatch):
    import imageio.v2 as iio

    import swarmpose.datasets.humaneva.video as he

    monkeypatch.setattr(he.cv2, "VideoCapture", _ClosedCapture)
    frames = [np.full((6, 8, 3), 10 * i, np.uint8) for i in range(4)]

    class FakeReader:
        def count_frames(self):
            return len(frames)

        def get_data(self, i):
            return frames[i]

        def close(self):
            pass

    path = he1.subject_dir / "Image_Data" / "Walking_1_(C1).avi"
    asked = []
    monkeypatch.setattr(iio, "get_reader", lambda p, format=None: asked.append(format) or FakeReader())
    with VideoSource(path) as v:
        assert v.n_frames == 4 and v.size == (8, 6) and v.read(3)[0, 0, 0] == 30
    assert asked == ["FFMPEG"]  # not every imageio plugin in turn

    def failing(p, format=None):
        raise ValueError("no backend for .avi")

    monkeypatch.setattr(iio, "get_reader", failing)
    with pytest.raises(DataError, match=r"OpenCV could not open it and imageio failed .*swarmpose\[video\]") as e:
        VideoSource(path)
    assert str(path) in str(e.value)
