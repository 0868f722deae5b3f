"""The user documentation: no process words, length limits, and links that resolve.

README.md and docs/*.md are a user's guide and today's results; CHANGELOG.md holds the history. None of
them may use the words of the development process ("stop 24", "helper", "audit"). Every relative link
must point to a file of the repository, and a link to a heading of a Markdown file must name one.
"""

from __future__ import annotations

import re
import unicodedata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
CHANGELOG = ROOT / "CHANGELOG.md"
DOCS = sorted((ROOT / "docs").glob("*.md"))
USER_DOCS = [README, *DOCS]
ALL_DOCS = [*USER_DOCS, *([CHANGELOG] if CHANGELOG.is_file() else [])]

PROCESS_WORDS = re.compile(r"\bstops?[ -]\d+|helper|audit", re.IGNORECASE)
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE_LINK = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$", re.MULTILINE)
FENCE = re.compile(r"^(```|~~~).*?^\1", re.MULTILINE | re.DOTALL)
EXTERNAL = re.compile(r"^[a-z][a-z0-9+.-]*:", re.IGNORECASE)  # http:, https:, mailto:, ...


def _name(path: Path) -> str:
    return str(path.relative_to(ROOT))


def _prose(text: str) -> str:
    """The text without fenced code blocks (links are not links inside them)."""
    return FENCE.sub("", text)


def _links(text: str) -> list[str]:
    prose = _prose(text)
    return INLINE_LINK.findall(prose) + REFERENCE_LINK.findall(prose)


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"`|\*\*|__", "", heading.strip().lower())
    kept = "".join(ch for ch in text if ch in " -_" or unicodedata.category(ch)[0] in "LN")
    return kept.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    seen: dict[str, int] = {}
    out = set()
    for line in _prose(path.read_text(encoding="utf-8")).splitlines():
        m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        slug = _slug(m.group(1))
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


@pytest.mark.parametrize("path", ALL_DOCS, ids=_name)
def test_no_process_words(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    hits = [f"line {text.count(chr(10), 0, m.start()) + 1}: {m.group(0)!r}" for m in PROCESS_WORDS.finditer(text)]
    assert not hits, f"{_name(path)} uses words of the development process: {', '.join(hits)}"


def test_readme_is_short() -> None:
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= 200, f"README.md has {n} lines; at most 200 (details belong in docs/)"


def test_accuracy_is_short() -> None:
    path = ROOT / "docs" / "accuracy.md"
    n = len(path.read_text(encoding="utf-8").splitlines())
    assert n <= 250, f"docs/accuracy.md has {n} lines; at most 250"


@pytest.mark.parametrize("path", ALL_DOCS, ids=_name)
def test_relative_links_resolve(path: Path) -> None:
    broken = []
    for target in _links(path.read_text(encoding="utf-8")):
        if EXTERNAL.match(target):
            continue
        file_part, _, anchor = target.partition("#")
        dest = (path.parent / file_part).resolve() if file_part else path
        if not dest.exists():
            broken.append(f"{target} (no such file)")
        elif anchor and dest.suffix == ".md" and anchor.lower() not in _anchors(dest):
            broken.append(f"{target} (no such heading in {dest.name})")
    assert not broken, f"{_name(path)} links to: {', '.join(broken)}"


def test_the_checks_see_links() -> None:
    """The link pattern finds inline, image and reference links, and skips code blocks."""
    text = "[a](docs/x.md#y) ![b](img/c.png)\n\n[c]: other.md\n```\n[d](not/a/link.md)\n```\n"
    assert sorted(_links(text)) == ["docs/x.md#y", "img/c.png", "other.md"]
    assert _slug("GPU backend (PyTorch)") == "gpu-backend-pytorch"
    assert _slug("The walk at 20 fps, per algorithm") == "the-walk-at-20-fps-per-algorithm"
