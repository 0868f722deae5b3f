"""A sequence's binary features kept on disk between runs: each frame's silhouettes and edge pixels.

Decoding a frame's images and finding its silhouettes and edges costs a core tens of milliseconds (four
644x484 PNGs: ~18 ms to decode, ~3 ms of background subtraction, ~2 ms of edges); every run of a sequence
repeats it for the same frames. The store keeps the two binary maps that this work produces
(:func:`swarmpose.features.binary_features`), so a later run of the same sequence reads a frame in about a
millisecond and only blurs its edges (:func:`swarmpose.features.features_from_binary`). The tracker's results
are the same to the last bit with or without it: a run computes the binary maps, stores them and then goes
on exactly as a run that read them.

Layout: ``ROOT/<sequence folder name>-<key>/`` with ``store.json`` (what the key was made of) and one file
per frame, ``<frame>.bits``: the magic ``SPF1`` and the zlib-compressed ``numpy.packbits`` of the
``(2, C, H, W)`` maps (silhouettes, edge pixels); a 644x484 four-view frame takes ~20 kB. The key hashes
everything the maps depend on: the sequence's identity and its observation files' identities
(:func:`swarmpose.track.provenance.sequence_identity`, :func:`~swarmpose.track.provenance.observation_identity`:
images edited in place make a new key), the tracked views, the feature options, the source of
``swarmpose.features`` and OpenCV's version. Files are written to a temporary name and renamed, so runs in
parallel processes may share a store; a file that does not read back whole is computed again and replaced.
Dataset specs (``humaneva:...``), whose files the dataset readers own, get no store.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import zlib
from pathlib import Path

import numpy as np

from swarmpose.errors import DataError
from swarmpose.track.provenance import observation_identity, sequence_identity

__all__ = ["FeatureStore", "STORE_FORMAT"]

STORE_FORMAT = 1
_MAGIC = b"SPF1"


def _features_source_sha1() -> str:
    import swarmpose.features as features

    return hashlib.sha1(Path(features.__file__).read_bytes()).hexdigest()[:16]


class FeatureStore:
    """One sequence's stored binary features (see the module docstring); ``shape`` is ``(C, H, W)``."""

    def __init__(self, folder: Path, shape: tuple[int, int, int]):
        self.folder = Path(folder)
        self.shape = tuple(int(n) for n in shape)
        self.read = 0  # frames read back from the store, and computed (and stored), through this object
        self.computed = 0

    @classmethod
    def for_sequence(cls, root: str | os.PathLike[str], sequence_path: str | os.PathLike[str],
                     view_names: list[str], feature_options: tuple[dict, dict],
                     shape: tuple[int, int, int]) -> FeatureStore | None:
        """The store under ``root`` for this sequence, views and feature options; None for a dataset spec.

        Raises
        ------
        DataError
            ``root`` (or the store's folder) cannot be created or written.
        """
        import cv2

        observations = observation_identity(sequence_path)
        if observations is None:
            return None
        sil, edge = feature_options
        identity = {
            "format": STORE_FORMAT,
            "sequence": sequence_identity(sequence_path),
            "observations": observations,
            "views": list(view_names),
            "silhouette_options": {k: sil[k] for k in sorted(sil)},
            "edge_options": {k: edge[k] for k in sorted(edge)},
            "features_source_sha1": _features_source_sha1(),
            "opencv": cv2.__version__,
            "shape": [int(n) for n in shape],
        }
        key = hashlib.sha1(json.dumps(identity, sort_keys=True).encode()).hexdigest()[:12]
        folder = Path(root) / f"{Path(str(sequence_path)).name}-{key}"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            meta = folder / "store.json"
            if not meta.is_file():
                _write_atomic(meta, (json.dumps({"key": key, **identity}, indent=1) + "\n").encode())
        except OSError as exc:
            raise DataError(f"feature store {folder}: cannot be written ({exc.strerror or exc}); pass another "
                            "--feature-cache folder, or --feature-cache off") from None
        return cls(folder, shape)

    def _file(self, k: int) -> Path:
        return self.folder / f"{int(k):07d}.bits"

    def get(self, k: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Frame ``k``'s ``(silhouettes, edge pixels)``, each ``(C, H, W)`` uint8 in {0, 1}; None when the
        frame is not stored or its file does not read back whole."""
        try:
            data = self._file(k).read_bytes()
        except OSError:
            return None
        n = 2 * int(np.prod(self.shape))
        if data[:4] != _MAGIC:
            return None
        try:
            packed = zlib.decompress(data[4:])
        except zlib.error:
            return None
        if len(packed) != (n + 7) // 8:
            return None
        bits = np.unpackbits(np.frombuffer(packed, np.uint8), count=n).reshape(2, *self.shape)
        self.read += 1
        return bits[0], bits[1]

    def put(self, k: int, silhouettes: np.ndarray, pixels: np.ndarray) -> None:
        """Store frame ``k``'s maps (``(C, H, W)``, non-zero = set). A store that cannot be written (a full
        disk) is not an error: the run goes on and computes the frame again next time."""
        maps = np.stack([np.asarray(silhouettes) != 0, np.asarray(pixels) != 0])
        if maps.shape[1:] != self.shape:
            raise DataError(f"feature store {self.folder}: frame {k} has maps of shape {maps.shape[1:]}, the "
                            f"store holds {self.shape}")
        self.computed += 1
        try:
            _write_atomic(self._file(k), _MAGIC + zlib.compress(np.packbits(maps).tobytes(), 1))
        except OSError:
            return


def _write_atomic(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
