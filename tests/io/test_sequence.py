"""The multi-view sequence format: exact round trip, lazy reading, errors that name the bad file."""

from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError
from swarmpose.io.sequence import (
    Frame,
    InMemoryFrames,
    MarkerData,
    MultiViewSequence,
    SequenceWriter,
    open_sequence,
    write_sequence,
)

T, C, H, W = 5, 3, 24, 32


def _cameras() -> list[Camera]:
    return [Camera.look_at(f"V{i}", eye=(3000.0 * np.cos(i), 3000.0 * np.sin(i), 2000.0), target=(0, 0, 900),
                           f=40.0, width=W, height=H, dist=(-0.05, 0, 0, 0, 0)) for i in range(C)]


def _sequence(rng: np.random.Generator, *, markers: bool = True) -> MultiViewSequence:
    images = rng.integers(0, 256, (T, C, H, W), dtype=np.uint8)
    masks = rng.integers(0, 2, (T, C, H, W), dtype=np.uint8)
    sils = rng.integers(0, 2, (T, C, H, W), dtype=np.uint8)
    md = None
    if markers:
        names = ("pelvis", "head_top")
        pos = [[rng.normal(10, 5, (int(rng.integers(0, 4)), 2)) for _ in range(C)] for _ in range(T)]
        ids = [[rng.integers(-1, 2, len(p)).astype(np.int16) for p in frame] for frame in pos]
        md = MarkerData.from_lists(names, pos, ids, rng.normal(size=(T, C, 2, 2)), rng.uniform(size=(T, C, 2)) > 0.3)
    return MultiViewSequence(
        cameras=_cameras(), frame_rate=60.0, n_frames=T,
        reader=InMemoryFrames(image=images, mask=masks, silhouette=sils),
        frame_times=np.arange(T) / 60.0 + 0.25, backgrounds=rng.integers(0, 256, (C, H, W), dtype=np.uint8),
        gt_joints=rng.normal(size=(T, 15, 3)) * 500.0, markers=md,
        world_from_source=np.diag([2.0, 2.0, 2.0, 1.0]), provenance={"seed": 7, "note": "test"},
        source_clip="/somewhere/clip.bvh")


@pytest.fixture()
def written(tmp_path: Path) -> tuple[MultiViewSequence, Path]:
    seq = _sequence(np.random.default_rng(0))
    return seq, write_sequence(tmp_path / "seq", seq)


def test_round_trip_identical_arrays(written):
    seq, path = written
    with open_sequence(path) as back:
        assert back.n_frames == T and len(back) == T and back.frame_rate == 60.0
        assert back.cameras == seq.cameras and back.view_names == ["V0", "V1", "V2"]
        assert back.image_size == (W, H) and back.streams == ("image", "mask", "silhouette")
        np.testing.assert_array_equal(back.frame_times, seq.frame_times)
        np.testing.assert_array_equal(back.backgrounds(), seq.backgrounds())
        np.testing.assert_array_equal(back.gt_joints, seq.gt_joints)
        np.testing.assert_array_equal(back.world_from_source, seq.world_from_source)
        assert back.provenance == {"seed": 7, "note": "test"} and back.source_clip == "/somewhere/clip.bvh"
        assert back.marker_names == ("pelvis", "head_top")
        np.testing.assert_array_equal(back.marker_data.projections, seq.marker_data.projections)
        np.testing.assert_array_equal(back.marker_data.visible, seq.marker_data.visible)
        for k in range(T):
            for getter in ("images", "masks", "silhouettes"):
                a, b = getattr(back, getter)(k), getattr(seq, getter)(k)
                assert a.dtype == np.uint8 and a.shape == (C, H, W)
                np.testing.assert_array_equal(a, b)
            for a, b in zip(back.markers(k), seq.markers(k), strict=True):
                np.testing.assert_array_equal(a, b)
            for a, b in zip(back.marker_ids(k), seq.marker_ids(k), strict=True):
                np.testing.assert_array_equal(a, b)
        frames = list(back)
        assert [f.index for f in frames] == list(range(T))
        assert isinstance(frames[2], Frame) and frames[2].time == pytest.approx(2 / 60 + 0.25)
        np.testing.assert_array_equal(frames[3].images, seq.images(3))


def test_reading_is_lazy(written, tmp_path):
    """Opening checks the archive directory only; a damaged PNG fails when (and only when) it is read."""
    _, path = written
    src = path / "views" / "V1.zip"
    with zipfile.ZipFile(src) as zin:
        entries = {n: zin.read(n) for n in zin.namelist()}
    entries["image/000003.png"] = b"not a png"
    with zipfile.ZipFile(src, "w") as zout:
        for n, data in entries.items():
            zout.writestr(n, data)
    with open_sequence(path) as seq:
        seq.images(2)
        with pytest.raises(FormatError, match=r"V1\.zip.*image/000003\.png"):
            seq.images(3)


def test_without_optional_parts(tmp_path):
    seq = MultiViewSequence(cameras=_cameras(), frame_rate=25.0, n_frames=2)
    path = write_sequence(tmp_path / "bare", seq)
    with open_sequence(path) as back:
        assert back.images(0) is None and back.masks(1) is None and back.markers(0) is None
        assert back.backgrounds() is None and back.gt_joints is None and back.streams == ()
        np.testing.assert_array_equal(back.frame_times, [0.0, 0.04])


def test_subsample():
    seq = MultiViewSequence(cameras=_cameras(), frame_rate=60.0, n_frames=61)
    np.testing.assert_array_equal(seq.subsample(20), np.arange(0, 61, 3))
    np.testing.assert_array_equal(seq.subsample(60), np.arange(61))
    idx = seq.subsample(25)  # non-integer ratio: nearest frames to j / 25 s
    np.testing.assert_array_equal(idx[:6], [0, 2, 5, 7, 10, 12])
    with pytest.raises(ConfigError, match="fps"):
        seq.subsample(120)


# ---------------------------------------------------------------------- malformed folders
def test_missing_sequence_json(written):
    _, path = written
    (path / "sequence.json").unlink()
    with pytest.raises(DataError, match=r"sequence\.json"):
        open_sequence(path)


@pytest.mark.parametrize("name", ["cameras.json", "frames.npz", "backgrounds.npz", "ground_truth.npz",
                                  "markers.npz", "views/V2.zip"])
def test_missing_file_is_named(written, name):
    _, path = written
    (path / name).unlink()
    with pytest.raises(DataError, match=name.replace(".", r"\.")):
        open_sequence(path)


@pytest.mark.parametrize("name", ["views/V0.zip", "markers.npz", "ground_truth.npz", "backgrounds.npz",
                                  "cameras.json", "frames.npz"])
def test_truncated_file_is_named(written, name):
    _, path = written
    f = path / name
    data = f.read_bytes()
    f.write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match=name.split("/")[-1].replace(".", r"\.")):
        open_sequence(path)


def test_missing_frame_entry_is_named(written):
    _, path = written
    src = path / "views" / "V2.zip"
    with zipfile.ZipFile(src) as zin:
        entries = {n: zin.read(n) for n in zin.namelist() if n != "mask/000004.png"}
    with zipfile.ZipFile(src, "w") as zout:
        for n, data in entries.items():
            zout.writestr(n, data)
    with pytest.raises(FormatError, match=r"V2\.zip.*mask/000004\.png"):
        open_sequence(path)


def _edit_meta(path: Path, **changes) -> None:
    meta = json.loads((path / "sequence.json").read_text())
    for k, v in changes.items():
        if v is None:
            del meta[k]
        else:
            meta[k] = v
    (path / "sequence.json").write_text(json.dumps(meta))


@pytest.mark.parametrize(("changes", "field"), [
    ({"version": 2}, "version"),
    ({"format": "other"}, "format"),
    ({"n_frames": None}, "n_frames"),
    ({"image_size": [32]}, "image_size"),
    ({"streams": ["image", "depth"]}, "streams"),
    ({"n_frames": 6}, "frame_times"),
])
def test_bad_metadata_field_is_named(written, changes, field):
    _, path = written
    _edit_meta(path, **changes)
    with pytest.raises(FormatError, match=field) as exc:
        open_sequence(path)
    assert "sequence.json" in str(exc.value) or "frames.npz" in str(exc.value)


@pytest.mark.parametrize(("times", "said"), [
    (np.array([0.0, 1 / 60, np.nan, 3 / 60, 4 / 60]), "finite, frame 2"),
    (np.array([0.0, 1 / 60, 3 / 60, 2 / 60, 4 / 60]), "increase strictly, frame 3"),
    (np.arange(T) * 1000.0 / 60.0, "does not match the frame rate 60"),  # milliseconds
    (np.arange(T) / 25.0, "does not match the frame rate 60"),
])
def test_frame_times_that_would_pick_wrong_frames_are_refused(written, times, said):
    """Times not finite, not increasing or not at the frame rate made subsample() return no frames or the
    wrong ones; the file is refused, named."""
    _, path = written
    np.savez(path / "frames.npz", frame_times=times)
    with pytest.raises(FormatError, match=said) as exc:
        open_sequence(path)
    assert "frames.npz" in str(exc.value) and "frame_times" in str(exc.value)
    with pytest.raises(ConfigError, match=said):
        MultiViewSequence(cameras=_cameras(), frame_rate=60.0, n_frames=T, frame_times=times)


def test_a_dropped_frame_and_an_offset_start_are_accepted():
    times = np.r_[0.0, 1, 2, 4, 5, 6] / 60.0 + 12.5  # one frame missing, the clock not at 0
    seq = MultiViewSequence(cameras=_cameras(), frame_rate=60.0, n_frames=6, frame_times=times)
    np.testing.assert_array_equal(seq.frame_times, times)


def test_two_views_sharing_one_archive_are_refused(written):
    _, path = written
    meta = json.loads((path / "sequence.json").read_text())
    meta["files"]["views"]["V0"] = meta["files"]["views"]["V1"]
    (path / "sequence.json").write_text(json.dumps(meta))
    with pytest.raises(FormatError, match=r"same archive.*V1\.zip") as exc:
        open_sequence(path)
    assert "sequence.json" in str(exc.value)


def test_wrong_array_shape_is_named(written):
    _, path = written
    np.savez_compressed(path / "ground_truth.npz", joints=np.zeros((T, 14, 3)))
    with pytest.raises(FormatError, match=r"ground_truth\.npz.*joints"):
        open_sequence(path)


def test_marker_ids_outside_the_names_are_named(written):
    """ids index the marker names (or -1 for a false detection): an id equal to the number of names is one
    past the end and refused."""
    _, path = written
    with np.load(path / "markers.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    assert arrays["ids"].size > 0
    arrays["ids"] = arrays["ids"].copy()
    arrays["ids"][0] = 2  # 2 names: valid ids are -1, 0 and 1
    np.savez_compressed(path / "markers.npz", **arrays)
    with pytest.raises(FormatError, match=r"markers\.npz.*ids must be in \[-1, 2\), got -?\d+\.\.2"):
        open_sequence(path)


def test_a_camera_of_another_image_size_is_named(written):
    _, path = written
    rig = json.loads((path / "cameras.json").read_text())
    cams = rig["cameras"] if isinstance(rig, dict) else rig
    cams[1]["width"] = W * 2
    (path / "cameras.json").write_text(json.dumps(rig))
    with pytest.raises(FormatError, match=rf"cameras\.json.*camera 'V1' is {2 * W}x{H}, the sequence {W}x{H}"):
        open_sequence(path)


def test_invalid_json(written):
    _, path = written
    (path / "sequence.json").write_text('{"format": "swarmpose-sequence",\n "version": }')
    with pytest.raises(FormatError, match=r"sequence\.json.*line 2"):
        open_sequence(path)


# ---------------------------------------------------------------------- writer guards
def test_writer_refuses_foreign_folders_and_disorder(tmp_path):
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    with pytest.raises(DataError, match="not empty"):
        SequenceWriter(foreign, _cameras(), 60.0, 2)
    with pytest.raises(DataError, match="holds no sequence"):
        SequenceWriter(foreign, _cameras(), 60.0, 2, overwrite=True)
    assert (foreign / "notes.txt").is_file()
    w = SequenceWriter(tmp_path / "new", _cameras(), 60.0, 2, streams=("image",))
    img = np.zeros((C, H, W), np.uint8)
    with pytest.raises(ConfigError, match="in order"):
        w.write_frame(1, image=img)
    with pytest.raises(ShapeError, match="expected"):
        w.write_frame(0, image=img[:, :, :5])
    w.write_frame(0, image=img)
    with pytest.raises(DataError, match="1 frames written"):
        w.finish()
    assert not (tmp_path / "new" / "sequence.json").exists()


def test_overwrite_replaces_a_sequence(written):
    seq, path = written
    write_sequence(path, seq, overwrite=True)
    with open_sequence(path) as back:
        assert back.n_frames == T
    shutil.rmtree(path)


def test_in_memory_validation():
    with pytest.raises(ShapeError, match="gt_joints"):
        MultiViewSequence(cameras=_cameras(), frame_rate=60.0, n_frames=2, gt_joints=np.zeros((3, 15, 3)))
    with pytest.raises(ConfigError, match="frame_rate"):
        MultiViewSequence(cameras=_cameras(), frame_rate=0.0, n_frames=2)
    with pytest.raises(ShapeError, match="uint8"):
        InMemoryFrames(image=np.zeros((2, C, H, W), np.float32))
    with pytest.raises(ShapeError, match="sum to"):
        MarkerData(("a",), np.ones((2, C), np.int64), np.zeros((3, 2)), np.zeros(3, np.int16))


def test_subject_measurements_round_trip_and_named_errors(tmp_path):
    from swarmpose.body.measurements import SubjectMeasurements

    values = {"LSHO-RSHO": 380.0, "STRN-T10": 230.0, "LKneeWidth": 104.0, "RKneeWidth": 106.0,
              "LAnkleWidth": 72.0, "RAnkleWidth": 74.0, "LElbowWidth": 70.0, "RElbowWidth": 72.0,
              "LWristWidth": 52.0, "RWristWidth": 54.0, "LShoulderOffset": 45.0, "RShoulderOffset": 47.0}
    m = SubjectMeasurements.from_dict({**values, "source": "calipers"})
    seq = _sequence(np.random.default_rng(1), markers=False)
    seq.subject_measurements = m
    path = write_sequence(tmp_path / "seq", seq)
    with open_sequence(path) as back:
        assert back.subject_measurements == m
    _edit_meta(path, subject_measurements={**values, "LKneeWidth": "wide"})
    with pytest.raises(FormatError, match=r"sequence\.json.*subject_measurements\.LKneeWidth"):
        open_sequence(path)
    _edit_meta(path, subject_measurements=None)  # optional: older sequences have none
    with open_sequence(path) as back:
        assert back.subject_measurements is None


def test_registered_source_prefixes_open_through_open_sequence(tmp_path, monkeypatch):
    import swarmpose.io.sequence as sequence_module
    from swarmpose.io.sequence import register_source_scheme

    monkeypatch.setattr(sequence_module, "_SOURCE_OPENERS", {})
    with pytest.raises(DataError, match="no reader is registered for 'fake:' sources"):
        open_sequence("fake:/somewhere")
    path = write_sequence(tmp_path / "seq", _sequence(np.random.default_rng(2), markers=False))
    asked = []
    register_source_scheme("fake:", lambda source: asked.append(source) or open_sequence(path))
    with open_sequence(Path("fake:/somewhere")) as seq:
        assert seq.n_frames == T
    assert asked == ["fake:/somewhere"]
    with pytest.raises(ConfigError, match="a name and a colon"):
        register_source_scheme("fake", lambda source: None)
