"""A report's Markdown as one self-contained HTML page (images embedded), to open in a browser or mail.

The Markdown written by :func:`swarmpose.report.write_summary` and the comparison report is rendered with
markdown-it-py (CommonMark with tables); every local image it names (relative to the Markdown's folder, or an
absolute path) is embedded as a ``data:`` URI, so the page needs no other file. Links (the overlay video) stay
relative.
"""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path
from urllib.parse import unquote, urlsplit

__all__ = ["markdown_to_html", "write_html"]

_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg",
         ".svg": "image/svg+xml", ".webp": "image/webp"}
#: Images larger than this stay linked instead of embedded (a long overlay GIF would make the page slow).
MAX_EMBED_BYTES = 8 * 1024 * 1024

_CSS = """
body { font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: #1d1d1f;
       max-width: 1100px; margin: 2em auto; padding: 0 1.2em; }
h1 { font-size: 1.6em; border-bottom: 1px solid #ddd; padding-bottom: .3em; }
h2 { font-size: 1.25em; margin-top: 1.8em; border-bottom: 1px solid #eee; padding-bottom: .2em; }
table { border-collapse: collapse; margin: .8em 0; font-size: 14px; }
th, td { border: 1px solid #d0d7de; padding: 3px 9px; }
th { background: #f3f5f7; }
tr:nth-child(even) td { background: #fafbfc; }
td { font-variant-numeric: tabular-nums; }
img { max-width: 100%; height: auto; display: block; margin: .6em 0; }
code, pre { font-family: ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; font-size: 13px; }
pre { background: #f6f8fa; padding: .7em 1em; overflow-x: auto; border-radius: 4px; }
blockquote { margin: .6em 0; padding: .2em 1em; border-left: 4px solid #e3b341; background: #fffbea; }
"""


#: Opaque PNGs above this size (the overlays: camera pictures) are embedded as JPEG when that is smaller.
JPEG_ABOVE_BYTES = 300 * 1024
JPEG_QUALITY = 90


def _as_jpeg(path: Path) -> bytes | None:
    """The picture as JPEG bytes, or None when it has transparency or cannot be read."""
    import cv2
    import numpy as np

    img = cv2.imdecode(np.fromfile(path, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None or (img.ndim == 3 and img.shape[2] == 4):
        return None
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    return buf.tobytes() if ok else None


def _embed(src: str, base: Path) -> str | None:
    """A ``data:`` URI for a local image next to the page, or None (remote, missing, too large).

    Large opaque PNGs (the overlays, which are camera pictures) go in as JPEG, about 5 times smaller; the
    plots stay PNG. The files in the folder are not changed.
    """
    parts = urlsplit(src)
    if parts.scheme or parts.netloc or not parts.path:
        return None
    path = base / unquote(parts.path)
    mime = _MIME.get(path.suffix.lower())
    if mime is None or not path.is_file() or path.stat().st_size > MAX_EMBED_BYTES:
        return None
    data = path.read_bytes()
    if mime == "image/png" and len(data) > JPEG_ABOVE_BYTES:
        jpeg = _as_jpeg(path)
        if jpeg is not None and len(jpeg) < len(data):
            mime, data = "image/jpeg", jpeg
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def markdown_to_html(text: str, *, base: str | os.PathLike[str] = ".", title: str = "swarmpose report") -> str:
    """Render Markdown ``text`` as a whole HTML page, embedding the images found relative to ``base``."""
    from markdown_it import MarkdownIt

    md = MarkdownIt("commonmark", {"html": False}).enable("table")
    base = Path(base)
    default_image = md.renderer.rules.get("image")

    def image(renderer, tokens, idx, options, env):  # bound to the renderer by add_render_rule
        tok = tokens[idx]
        uri = _embed(str(tok.attrGet("src") or ""), base)
        if uri is not None:
            tok.attrSet("src", uri)
        return default_image(tokens, idx, options, env)

    md.add_render_rule("image", image)
    body = md.render(text)
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n{body}</body>\n</html>\n")


def write_html(markdown_file: str | os.PathLike[str], *, out: str | os.PathLike[str] | None = None,
               title: str | None = None) -> Path:
    """Write the HTML page of a Markdown report beside it (``summary.md`` -> ``summary.html``).

    Parameters
    ----------
    markdown_file : path-like
        The Markdown written by the report; its images are looked up relative to its folder.
    out : path-like, optional
        Default: the same name with ``.html``. Relative links in the page then still resolve.
    title : str, optional
        The page title; default the Markdown's first heading.

    Returns
    -------
    pathlib.Path
    """
    src = Path(markdown_file)
    text = src.read_text(encoding="utf-8")
    if title is None:
        first = next((ln for ln in text.splitlines() if ln.startswith("# ")), "# swarmpose report")
        title = first[2:].replace("`", "").strip()
    page = markdown_to_html(text, base=src.parent, title=title)
    out_path = Path(out) if out is not None else src.with_suffix(".html")
    out_path.write_text(page, encoding="utf-8")
    return out_path
