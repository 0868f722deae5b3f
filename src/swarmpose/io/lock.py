"""One writer per results folder: an advisory lock held while ``track`` or ``compare`` writes it.

Two processes resuming the same folder would track the same runs twice and write the same progress
files; the second is refused with the first one's process id. The lock is ``fcntl.flock`` on
``FOLDER/.swarmpose.lock``: the operating system drops it when its process ends, however it ends
(a killed run leaves the file, not the lock). Where ``fcntl`` does not exist (Windows) nothing is locked.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from swarmpose.errors import ConfigError

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

__all__ = ["LOCK_NAME", "folder_lock", "remove_unused_folder"]

#: Name of the lock file inside a locked folder.
LOCK_NAME = ".swarmpose.lock"


@contextmanager
def folder_lock(folder: Path) -> Iterator[Path]:
    """Hold the write lock of ``folder`` (created if missing) for the ``with`` block.

    Raises
    ------
    ConfigError
        Another process holds it (its pid named).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    with open(path, "a+", encoding="utf-8") as f:
        if fcntl is not None:
            try:
                fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                f.seek(0)
                pid = f.read().strip()
                who = f" (pid {pid})" if pid.isdigit() else ""
                raise ConfigError(f"{folder} is being written by another swarmpose process{who}: wait for it "
                                  "to finish, or stop it and continue with --resume") from None
        f.seek(0)
        f.truncate()
        f.write(f"{os.getpid()}\n")
        f.flush()
        yield path  # closing the file releases the lock


def remove_unused_folder(folder: Path) -> None:
    """Remove what a failed start left in a folder it created: the lock file and every empty folder, from
    the bottom up (``folder`` itself too when nothing else is left). Files are kept."""
    folder = Path(folder)
    (folder / LOCK_NAME).unlink(missing_ok=True)
    if not folder.is_dir():
        return
    for here, _, _ in sorted(os.walk(folder), key=lambda w: -len(Path(w[0]).parts)):  # deepest first
        try:
            Path(here).rmdir()
        except OSError:  # not empty: it keeps what was written there
            pass
