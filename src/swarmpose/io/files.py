"""The product's own result files: read safely (a truncated, corrupt or hand-edited file gives a
:class:`~swarmpose.errors.FormatError` naming it, never a traceback or a pickle load) and written whole or
not at all."""

from __future__ import annotations

import json
import os
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import FormatError

__all__ = ["load_npz", "read_json_object", "save_npz", "SAVE_PIECE_BYTES"]

#: The most bytes :func:`save_npz` holds beyond the arrays themselves: each array is written in pieces this size.
SAVE_PIECE_BYTES = 1 << 20


def read_json_object(path: Path) -> dict[str, Any]:
    """The JSON object in ``path``.

    Raises
    ------
    FormatError
        Not valid JSON (the line is named) or not an object.
    OSError
        The file cannot be read.
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise FormatError(f"not valid JSON ({exc.msg})", path=path, line=exc.lineno) from None
    except UnicodeDecodeError:
        raise FormatError("not a UTF-8 text file", path=path) from None
    if not isinstance(data, dict):
        raise FormatError("expected a JSON object", path=path)
    return data


def load_npz(path: Path, required: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` file ``path`` (``allow_pickle=False``), checking ``required`` names.

    Raises
    ------
    FormatError
        A required array is missing, or the file is not a readable ``.npz`` (truncated, corrupt, not
        an archive, or holding pickled objects).
    """
    try:
        with open(path, "rb") as fh:
            if fh.read(4)[:2] != b"PK":  # every .npz is a zip archive
                raise FormatError("not an .npz archive (it does not begin like a zip file)", path=path)
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in required if k not in z.files]
            if missing:
                raise FormatError(f"missing array(s) {missing}", path=path)
            return {k: z[k] for k in z.files}
    except (FormatError, PermissionError, FileNotFoundError):
        raise  # a permission or a missing file is said as such (the CLI names the path)
    except (zipfile.BadZipFile, zlib.error, KeyError, OSError, ValueError, EOFError, SyntaxError) as exc:
        raise FormatError(f"cannot read .npz (truncated or corrupt?): {exc}", path=path) from None


def save_npz(path: Path, **arrays: Any) -> None:
    """Write ``arrays`` to the ``.npz`` file ``path`` as :func:`numpy.savez` does (uncompressed, no pickles),
    atomically (a temporary file beside it, then renamed), and without copying them: each array's bytes go
    out in pieces of :data:`SAVE_PIECE_BYTES` (``numpy.savez`` holds a copy of each array while writing it:
    7 MB for a 20,000-frame track's joints).

    Raises
    ------
    ValueError
        An array of Python objects (it would need a pickle).
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp.npz")
    try:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, value in arrays.items():
                a = np.asanyarray(value)
                if a.dtype.hasobject:
                    raise ValueError(f"{name}: an array of Python objects cannot be saved without a pickle")
                if not a.flags.c_contiguous:  # a copy only where the array is not laid out in C order
                    a = np.ascontiguousarray(a)
                with zf.open(name + ".npy", "w", force_zip64=True) as fh:
                    _write_npy(fh, a)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _write_npy(fh: Any, a: np.ndarray) -> None:
    """The ``.npy`` header of ``a`` (format 1.0, or 2.0 when it does not fit), then its bytes in pieces."""
    header = np.lib.format.header_data_from_array_1_0(a)
    try:
        np.lib.format.write_array_header_1_0(fh, header)
    except ValueError:  # a header over 64 KiB
        np.lib.format.write_array_header_2_0(fh, header)
    if a.size == 0 or a.itemsize == 0:
        return
    data = a.reshape(-1).view(np.uint8)
    for start in range(0, len(data), SAVE_PIECE_BYTES):
        fh.write(data[start:start + SAVE_PIECE_BYTES])
