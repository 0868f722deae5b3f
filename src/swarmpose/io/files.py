"""Reading the product's own result files safely: a truncated, corrupt or hand-edited file gives a
:class:`~swarmpose.errors.FormatError` naming it, never a traceback or a pickle load."""

from __future__ import annotations

import json
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.errors import FormatError

__all__ = ["load_npz", "read_json_object"]


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
