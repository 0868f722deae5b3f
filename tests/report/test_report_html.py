"""The self-contained HTML page of a report: Markdown rendered, local images embedded byte for byte (large
camera pictures as JPEG), everything else left as it was."""

from __future__ import annotations

import base64
import re
from pathlib import Path

import cv2
import numpy as np

from swarmpose.report.html import JPEG_ABOVE_BYTES, markdown_to_html, write_html


def _uris(page: str) -> list[tuple[str, bytes]]:
    return [(m, base64.b64decode(d)) for m, d in re.findall(r'src="data:([^;]+);base64,([^"]+)"', page)]


def _png(path: Path, img: np.ndarray) -> Path:
    assert cv2.imwrite(str(path), img)
    return path


def test_local_images_are_embedded_and_the_rest_is_left_alone(tmp_path: Path):
    small = _png(tmp_path / "plot.png", np.full((20, 30, 3), 200, np.uint8))
    (tmp_path / "sub").mkdir()
    gif = tmp_path / "sub" / "a b.gif"
    gif.write_bytes(b"GIF89a-not-really")
    text = ("# Title\n\nSome *text* and <script>alert(1)</script>.\n\n"
            "| run | D (mm) |\n| :--- | ---: |\n| 0 | 12.5 |\n\n"
            "![plot](plot.png)\n\n![gif](sub/a%20b.gif)\n\n![gone](missing.png)\n\n"
            "![web](https://example.org/x.png)\n\n[video](overlay.mp4)\n\n```\nswarmpose track X\n```\n")
    page = markdown_to_html(text, base=tmp_path, title="T <1>")
    uris = _uris(page)
    assert uris == [("image/png", small.read_bytes()), ("image/gif", gif.read_bytes())]
    assert 'src="missing.png"' in page and 'src="https://example.org/x.png"' in page
    assert 'href="overlay.mp4"' in page and "<pre><code>swarmpose track X\n</code></pre>" in page
    assert '<td style="text-align:right">12.5</td>' in page and "<title>T &lt;1&gt;</title>" in page
    assert "<script>" not in page  # raw HTML in the Markdown is shown as text, never run


def test_large_camera_pictures_go_in_as_jpeg_and_plots_stay_png(tmp_path: Path):
    rng = np.random.default_rng(0)
    photo = _png(tmp_path / "overlay.png", rng.integers(0, 256, (400, 500, 3), dtype=np.uint8))
    rgba = np.dstack([rng.integers(0, 256, (400, 500, 3), dtype=np.uint8), np.full((400, 500), 255, np.uint8)])
    plot = _png(tmp_path / "transparent.png", rgba)
    assert photo.stat().st_size > JPEG_ABOVE_BYTES and plot.stat().st_size > JPEG_ABOVE_BYTES
    page = markdown_to_html("![o](overlay.png)\n\n![p](transparent.png)\n", base=tmp_path)
    (m1, b1), (m2, b2) = _uris(page)
    assert m1 == "image/jpeg" and len(b1) < photo.stat().st_size
    assert cv2.imdecode(np.frombuffer(b1, np.uint8), cv2.IMREAD_UNCHANGED).shape == (400, 500, 3)
    assert (m2, b2) == ("image/png", plot.read_bytes())  # transparency kept: not re-encoded
    assert photo.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"  # the file itself is untouched


def test_write_html_names_the_page_after_the_markdown(tmp_path: Path):
    md = tmp_path / "summary.md"
    md.write_text("# Tracking report: `demo`\n\ntext\n", encoding="utf-8")
    out = write_html(md)
    assert out == tmp_path / "summary.html"
    page = out.read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>") and "<title>Tracking report: demo</title>" in page


def test_a_linked_local_video_is_embedded_up_to_the_size_limit(tmp_path: Path, monkeypatch):
    """The overlay video is part of the one file to send: an MP4 or WebM link becomes a <video> player and a GIF
    link an image, each a data: URI of the file's bytes; above MAX_VIDEO_EMBED_BYTES, a remote or a missing file
    the link stays."""
    import swarmpose.report.html as page_html

    mp4 = tmp_path / "overlay_run000.mp4"
    mp4.write_bytes(b"\x00\x00\x00\x18ftypisom" + bytes(range(256)))
    gif = tmp_path / "overlay_run001.gif"
    gif.write_bytes(b"GIF89a" + bytes(300))
    text = ("Video of every frame: [overlay_run000.mp4](overlay_run000.mp4)\n\n[run 1](overlay_run001.gif)\n\n"
            "[web](https://example.org/v.mp4) [gone](missing.mp4)\n")
    page = markdown_to_html(text, base=tmp_path)
    assert _uris(page) == [("video/mp4", mp4.read_bytes()), ("image/gif", gif.read_bytes())]
    assert re.search(r'<video controls[^>]* src="data:video/mp4;base64,[^"]+">overlay_run000.mp4</video>', page)
    assert re.search(r'<img src="data:image/gif;base64,[^"]+" alt="run 1"', page)
    assert 'href="overlay_run000.mp4"' not in page and 'href="overlay_run001.gif"' not in page
    assert 'href="https://example.org/v.mp4"' in page and 'href="missing.mp4"' in page
    monkeypatch.setattr(page_html, "MAX_VIDEO_EMBED_BYTES", 300)  # the GIF (306 bytes) is over, the MP4 not
    page = markdown_to_html(text, base=tmp_path)
    assert _uris(page) == [("video/mp4", mp4.read_bytes())] and 'href="overlay_run001.gif"' in page
