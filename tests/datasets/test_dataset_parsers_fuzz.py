"""Every parser turns garbage into a FormatError/DataError that names the file -- never another exception."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarmpose.datasets.humaneva import (
    parse_calibration,
    read_background_mat,
    read_mocap_mat,
    read_mp,
    read_offsets,
)
from swarmpose.datasets.leewalk import read_number_table
from swarmpose.errors import DataError, FormatError

TEXT_PARSERS = {
    "cal": parse_calibration,
    "ofs": read_offsets,
    "mp": read_mp,
    "txt": lambda p: read_number_table(p, 31, "ground-truth parameter file"),
}

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers().map(str))
tokens = st.one_of(numbers, st.text(min_size=1, max_size=6), st.sampled_from(["=", "$", "#", "1e999", "-", ".", "e5"]))
lines = st.lists(st.lists(tokens, max_size=8).map(" ".join), max_size=30).map("\n".join)

_settings = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def check_clean_failure(parser, path: Path) -> None:
    """The parser either succeeds or raises FormatError/DataError naming the file; anything else fails."""
    try:
        parser(path)
    except (FormatError, DataError) as exc:
        assert str(path) in str(exc)


@pytest.mark.parametrize("ext", sorted(TEXT_PARSERS))
@_settings
@given(text=lines)
def test_text_parsers_on_token_soup(ext: str, text: str):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"f.{ext}"
        p.write_text(text, encoding="utf-8", errors="surrogatepass")
        check_clean_failure(TEXT_PARSERS[ext], p)


@pytest.mark.parametrize("ext", sorted(TEXT_PARSERS))
@_settings
@given(data=st.binary(max_size=400))
def test_text_parsers_on_bytes(ext: str, data: bytes):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"f.{ext}"
        p.write_bytes(data)
        check_clean_failure(TEXT_PARSERS[ext], p)


@_settings
@given(n=st.integers(0, 40), bad=st.integers(0, 39), token=st.text(max_size=5))
def test_calibration_truncated_or_corrupted_anywhere(n: int, bad: int, token: str):
    vals = ["1000", "1000", "320", "240", "0", "0", "0", "0", "0", "0", "1", "0", "0", "0", "1", "0", "0", "0", "1",
            "0", "0", "4000"] * 2
    vals = vals[:n]
    if bad < len(vals):
        vals[bad] = token
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "C1.cal"
        p.write_text("\n".join(vals))
        try:
            v = parse_calibration(p)
        except FormatError as exc:
            assert str(p) in str(exc) and (exc.line is not None or exc.field is not None)
        else:  # the file holds 22 whitespace-separated numbers (an empty or blank token just drops one)
            assert len(p.read_text().split()) == 22 and np.isfinite(v.T).all()


@_settings
@given(data=st.binary(max_size=600), header=st.booleans())
def test_mat_readers_on_bytes(data: bytes, header: bool):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "Walking_1.mat"
        p.write_bytes((b"MATLAB 5.0 MAT-file, Platform: GLNXA64" + bytes(88) + b"\x00\x01IM" if header else b"") + data)
        check_clean_failure(read_mocap_mat, p)
        check_clean_failure(read_background_mat, p)


@_settings
@given(cut=st.floats(0.0, 1.0))
def test_truncated_mocap_mat(cut: float):
    from he_fixtures import labels, mocap_array, write_mocap_mat

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "Walking_1.mat"
        write_mocap_mat(p, labels(), mocap_array(3))
        raw = p.read_bytes()
        p.write_bytes(raw[: int(len(raw) * cut)])
        check_clean_failure(read_mocap_mat, p)
