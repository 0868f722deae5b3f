"""A report's Markdown as one self-contained HTML page (images embedded), to open in a browser or mail.

The Markdown written by :func:`swarmpose.report.write_summary` and the comparison report is rendered with
markdown-it-py (CommonMark with tables); every local image it names (relative to the Markdown's folder, or an
absolute path) is embedded as a ``data:`` URI, so the page needs no other file. A link to a local video (the
overlay video: MP4 or WebM in a ``<video>`` player, an animated GIF as an image) is embedded the same way up to
:data:`MAX_VIDEO_EMBED_BYTES`; a larger one, and every other link, stays a relative link.
"""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path
from urllib.parse import unquote, urlsplit

__all__ = ["MAX_EMBED_BYTES", "MAX_VIDEO_EMBED_BYTES", "markdown_to_html", "write_html"]

_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg",
         ".svg": "image/svg+xml", ".webp": "image/webp"}
#: Images larger than this stay linked instead of embedded (a long overlay GIF would make the page slow).
MAX_EMBED_BYTES = 8 * 1024 * 1024
#: A linked video larger than this stays a link instead of being embedded (the report says so in a note).
MAX_VIDEO_EMBED_BYTES = 50_000_000
_VIDEO_MIME = {".mp4": "video/mp4", ".webm": "video/webm", ".gif": "image/gif"}

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
img, video { max-width: 100%; height: auto; display: block; margin: .6em 0; }
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


def _local_file(src: str, base: Path) -> Path | None:
    """The local file a relative (or absolute) link names, or None (remote, an anchor, missing)."""
    parts = urlsplit(src)
    if parts.scheme or parts.netloc or not parts.path:
        return None
    path = base / unquote(parts.path)
    return path if path.is_file() else None


def _embed(src: str, base: Path) -> str | None:
    """A ``data:`` URI for a local image next to the page, or None (remote, missing, too large).

    Large opaque PNGs (the overlays, which are camera pictures) go in as JPEG, about 5 times smaller; the
    plots stay PNG. The files in the folder are not changed.
    """
    path = _local_file(src, base)
    mime = None if path is None else _MIME.get(path.suffix.lower())
    if mime is None or path.stat().st_size > MAX_EMBED_BYTES:
        return None
    data = path.read_bytes()
    if mime == "image/png" and len(data) > JPEG_ABOVE_BYTES:
        jpeg = _as_jpeg(path)
        if jpeg is not None and len(jpeg) < len(data):
            mime, data = "image/jpeg", jpeg
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def _video_element(src: str, label: str, base: Path) -> str | None:
    """The HTML that embeds a linked local video (``<video>``; an animated GIF: ``<img>``) as a ``data:`` URI, or
    None when ``src`` is not one or is larger than :data:`MAX_VIDEO_EMBED_BYTES`."""
    path = _local_file(src, base)
    mime = None if path is None else _VIDEO_MIME.get(path.suffix.lower())
    if mime is None or path.stat().st_size > MAX_VIDEO_EMBED_BYTES:
        return None
    uri = f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")
    name = html.escape(label or path.name)
    if mime == "image/gif":
        return f'<img src="{uri}" alt="{name}" title="{name}">'
    # the link text is what a browser without the format shows
    return f'<video controls loop playsinline preload="metadata" title="{name}" src="{uri}">{name}</video>'


def _embed_videos(state) -> None:
    """markdown-it core rule: each link to a local video becomes the video itself (:func:`_video_element`)."""
    from markdown_it.token import Token

    base = state.env.get("base")
    if base is None:
        return
    for block in state.tokens:
        if block.type != "inline" or not block.children:
            continue
        out, kids, i = [], block.children, 0
        while i < len(kids):
            tok = kids[i]
            if tok.type == "link_open":
                end = next((j for j in range(i + 1, len(kids)) if kids[j].type == "link_close"), None)
                label = "".join(k.content for k in kids[i + 1:end]) if end is not None else ""
                element = None if end is None else _video_element(str(tok.attrGet("href") or ""), label, base)
                if element is not None:
                    embedded = Token("html_inline", "", 0)
                    embedded.content = element
                    out.append(embedded)
                    i = end + 1
                    continue
            out.append(tok)
            i += 1
        block.children = out


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
    md.core.ruler.push("embed_videos", _embed_videos)
    body = md.render(text, {"base": base})
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
