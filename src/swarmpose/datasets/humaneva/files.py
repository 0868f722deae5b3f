"""Reading the release's files with errors that name them: whitespace-separated numbers and MATLAB
``.mat`` files."""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from swarmpose.errors import DataError, FormatError

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")


def _read_bytes(p: Path, what: str) -> bytes:
    """The bytes of ``p``; a missing file, a folder or a read error is a DataError naming it and ``what``."""
    if not p.exists():
        raise DataError(f"{p}: missing {what}")
    if not p.is_file():
        raise DataError(f"{p}: not a file ({what} expected)")
    try:
        return p.read_bytes()
    except OSError as exc:
        raise DataError(f"{p}: cannot read {what}: {exc}") from exc


def _read_text(path: str | os.PathLike[str], what: str) -> tuple[Path, str]:
    p = Path(path)
    return p, _read_bytes(p, what).decode("latin-1")  # never fails; non-numeric bytes are reported as bad tokens


def _tokens(text: str) -> list[tuple[int, str]]:
    out = []
    for lineno, line in enumerate(text.split("\n"), 1):
        out.extend((lineno, tok) for tok in line.split())
    return out


def _number(tok: str, path: Path, line: int, fld: str) -> float:
    if not _NUMBER.match(tok):
        shown = tok if len(tok) <= 40 else tok[:37] + "..."
        raise FormatError(f"not a number: {shown!r} (expected {fld})", path=path, line=line, field=fld)
    v = float(tok)
    if not math.isfinite(v):
        raise FormatError(f"{fld} is out of range: {tok!r}", path=path, line=line, field=fld)
    return v


def _fixed_numbers(path: Path, text: str, fields: Sequence[str], kind: str, extra_hint: str = "") -> list[float]:
    toks = _tokens(text)
    n = len(fields)
    if len(toks) > n:
        line, tok = toks[n]
        hint = extra_hint if extra_hint and len(toks) == 25 else ""
        raise FormatError(f"{len(toks)} values, a {kind} file holds exactly {n} ({', '.join(fields)}); first extra "
                          f"value {tok[:40]!r}{hint}", path=path, line=line)
    values = [_number(tok, path, line, fields[i]) for i, (line, tok) in enumerate(toks)]
    if len(values) < n:
        last_line = toks[-1][0] if toks else 1
        raise FormatError(f"truncated: {len(values)} of {n} numbers; {fields[len(values)]} and later are missing",
                          path=path, line=last_line, field=fields[len(values)])
    return values


def _loadmat(p: Path, what: str, v73_hint: str = "") -> dict[str, Any]:
    """``scipy.io.loadmat`` (structs as objects, squeezed) with errors that name the file."""
    import io

    import scipy.io

    raw = _read_bytes(p, what)
    try:
        return scipy.io.loadmat(io.BytesIO(raw), squeeze_me=True, struct_as_record=False)
    except NotImplementedError:
        raise FormatError(f"MATLAB v7.3 (HDF5) .mat files are not supported; re-save it with -v7{v73_hint}",
                          path=p) from None
    except Exception as exc:  # scipy raises many types on corrupt or truncated input; name the file
        raise FormatError(f"not a readable MATLAB .mat file ({type(exc).__name__}: {exc})", path=p) from None
