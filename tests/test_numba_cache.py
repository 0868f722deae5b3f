"""numba's on-disk cache (``cache=True``) is invalidated only by edits to the file that defines a cached
kernel, not by edits to the kernels it calls from other files (numba docs, "Notes on Caching", cache
limitations). A module whose kernels call kernels of other swarmpose files therefore records a hash of those
files, ``INLINED_SOURCES_SHA1``: editing them fails this test until the hash line is updated, and updating it
edits the dependent file, so every cache (a checkout's, a user's after ``git pull``) recompiles."""

from __future__ import annotations

import ast
import hashlib
import importlib
from pathlib import Path

import swarmpose

SRC = Path(swarmpose.__file__).parent


def _kernel_modules() -> set[Path]:
    return {p for p in SRC.rglob("*.py") if "njit" in p.read_text(encoding="utf-8")}


def _imported_kernel_files(path: Path, kernels: set[Path]) -> set[Path]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "swarmpose":
            f = SRC.parent / (node.module.replace(".", "/") + ".py")
            if f in kernels:
                out.add(f)
    return out


def _inlined(path: Path, kernels: set[Path]) -> list[Path]:
    """Every kernel file ``path`` reaches through imports, transitively."""
    todo, seen = list(_imported_kernel_files(path, kernels)), set()
    while todo:
        f = todo.pop()
        if f not in seen:
            seen.add(f)
            todo += list(_imported_kernel_files(f, kernels))
    return sorted(seen, key=lambda f: f.relative_to(SRC).as_posix())


def sources_sha1(files: list[Path]) -> str:
    h = hashlib.sha1()
    for f in files:
        h.update(f.relative_to(SRC).as_posix().encode())
        h.update(f.read_bytes().replace(b"\r\n", b"\n"))
    return h.hexdigest()[:16]


def test_kernels_that_inline_other_files_name_their_hash():
    kernels = _kernel_modules()
    dependents = {p: _inlined(p, kernels) for p in kernels}
    dependents = {p: d for p, d in dependents.items() if d}
    assert {p.relative_to(SRC).as_posix() for p in dependents} >= {"fitness/_numba.py", "render/project.py"}
    for path, inlined in dependents.items():
        rel = path.relative_to(SRC).with_suffix("")
        module = importlib.import_module("swarmpose." + ".".join(rel.parts))
        expected = sources_sha1(inlined)
        assert getattr(module, "INLINED_SOURCES_SHA1", None) == expected, (
            f"{path.relative_to(SRC)} calls kernels of {', '.join(f.relative_to(SRC).as_posix() for f in inlined)}, "
            f"which changed: set INLINED_SOURCES_SHA1 = \"{expected}\" in it (numba's cache of its kernels does "
            "not see edits to other files)")
