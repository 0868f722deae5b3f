"""What a results folder records about the inputs and the code that made it: the source's git revision, the
libraries' versions, and identities (hashes) of the sequence, its observation files, its ground truth and the body
model's spec, so that a resume or a reuse notices data, calibrations or code changed in place."""

from __future__ import annotations

import functools
import hashlib
import json
import os
import platform
import sys
from pathlib import Path

import numpy as np


@functools.lru_cache(maxsize=1)
def source_revision() -> str | None:
    """The git commit of the swarmpose source this process runs (``+dirty`` with uncommitted changes to
    tracked files), or None outside a git checkout: results name the code that made them."""
    import subprocess

    pkg = Path(__file__).resolve().parents[1]  # the swarmpose package folder
    env = {**os.environ, "GIT_OPTIONAL_LOCKS": "0"}

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(pkg), *args], capture_output=True, text=True, timeout=5,
                              check=True, env=env).stdout.strip()

    try:
        git("ls-files", "--error-unmatch", "__init__.py")  # tracked here: not a copy inside another repository
        head = git("rev-parse", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no", "--", ".")
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "") if head else None


def versions() -> dict[str, str]:
    """The versions a results folder's ``config.json`` records: swarmpose (and its git commit, where known), Python,
    numpy, scipy, numba, torch where the torch backend loaded it, the machine and its CPU count."""
    import numba
    import scipy

    from swarmpose import __version__

    out = {"swarmpose": __version__, "python": platform.python_version(), "numpy": np.__version__,
           "scipy": scipy.__version__, "numba": numba.__version__, "machine": platform.machine(),
           "cpus": str(os.cpu_count())}
    torch = sys.modules.get("torch")  # loaded by the torch fitness backend
    if torch is not None:
        out["torch"] = torch.__version__
    rev = source_revision()
    if rev:
        out["swarmpose_git"] = rev
    return out


#: Fields of ``sequence.json`` that change when the same data is synthesised again (time, version, paths).
_VOLATILE_SEQUENCE_FIELDS = (("source_clip",), ("provenance", "created_utc"), ("provenance", "swarmpose_version"),
                             ("provenance", "clip", "path"))


def sequence_identity(sequence_path: str | Path) -> str:
    """What identifies a sequence's data across moves and re-synthesis of its folder: a hash of its
    ``sequence.json`` (the source clip's sha256 and every synthesis setting) without the creation time,
    version and paths; for a dataset spec (``humaneva:...``) the spec itself."""
    meta = Path(str(sequence_path)) / "sequence.json"
    if not meta.is_file():
        return str(sequence_path)
    try:
        data = json.loads(meta.read_text())
    except (OSError, ValueError):
        return "sequence.json sha1 " + hashlib.sha1(meta.read_bytes()).hexdigest()[:16]
    for path in _VOLATILE_SEQUENCE_FIELDS:
        node = data
        for key in path[:-1]:
            node = node.get(key, {}) if isinstance(node, dict) else {}
        if isinstance(node, dict):
            node.pop(path[-1], None)
    canonical = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return "sequence.json sha1 " + hashlib.sha1(canonical.encode()).hexdigest()[:16]


def ground_truth_identity(gt_joints: np.ndarray) -> str:
    """A hash of the tracked frames' ground-truth joints: a resume checks that the data the finished runs
    were scored against (and started from, by IK) are still the sequence's. ``sequence_identity`` covers
    the synthesis record, not data files edited in place."""
    return hashlib.sha1(np.ascontiguousarray(gt_joints, dtype=np.float64).tobytes()).hexdigest()[:16]


def observation_identity(sequence_path: str | Path) -> dict[str, str] | None:
    """A hash per observation file of a sequence folder (the view archives, cameras, markers, backgrounds and
    frame table that ``sequence.json`` lists; the ground truth has :func:`ground_truth_identity`), so that a
    resume sees images or calibrations edited in place. A zip archive (``.zip``, ``.npz``) is hashed by its
    entries' names, CRC-32s and sizes, which a re-synthesis with the same settings reproduces (the archives'
    own bytes carry the writing time); other files by their bytes. ``None`` for a dataset spec, whose files
    the dataset readers own."""
    meta = Path(str(sequence_path)) / "sequence.json"
    if not meta.is_file():  # a dataset spec (``humaneva:...``) is not a folder
        return None
    try:
        files = json.loads(meta.read_text()).get("files", {})
    except (OSError, ValueError, AttributeError):
        return None
    if not isinstance(files, dict):
        return None
    listed = [v for k, v in files.items() if k != "ground_truth" and isinstance(v, str)]
    if isinstance(files.get("views"), dict):
        listed += [v for v in files["views"].values() if isinstance(v, str)]
    return {rel: file_identity(meta.parent / rel) for rel in sorted(set(listed))}


def file_identity(path: Path) -> str:
    """A file's hash: a zip archive's by its entries' names, CRC-32s and sizes, other files' by their bytes;
    ``"missing"`` when there is no file."""
    import zipfile

    if not path.is_file():
        return "missing"
    try:
        with zipfile.ZipFile(path) as archive:
            entries = [(e.filename, e.CRC, e.file_size) for e in archive.infolist()]
        return hashlib.sha1(repr(entries).encode()).hexdigest()[:16]
    except (zipfile.BadZipFile, OSError):
        digest = hashlib.sha1()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        return digest.hexdigest()[:16]


def model_identity(model: str) -> str:
    """A hash of the body model's spec text (a shipped name or a spec file): what the subject and the
    IK fit depend on, so that a spec edited in place is not mistaken for the old one."""
    from importlib import resources

    from swarmpose.body.spec import builtin_specs

    if model in builtin_specs():
        text = (resources.files("swarmpose.models") / f"{model}.json").read_bytes()
    else:
        text = Path(model).read_bytes()
    return hashlib.sha1(text).hexdigest()[:16]


def sequence_location(sequence_path: str | Path) -> str:
    """The sequence as recorded in ``config.json``: an absolute folder path (so that ``report`` finds it
    from any working directory), or a dataset spec (``humaneva:...``) as given."""
    from swarmpose.datasets import is_dataset_spec

    return str(sequence_path) if is_dataset_spec(sequence_path) else str(Path(str(sequence_path)).resolve())
