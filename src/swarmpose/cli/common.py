"""Shared pieces of the CLI: console, JSON output, turning library errors into clear messages."""

from __future__ import annotations

import functools
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape

from swarmpose.errors import SwarmposeError
from swarmpose.io.jsonable import to_jsonable

__all__ = [
    "DEFAULT_FEATURE_CACHE", "FEATURE_CACHE_HELP", "feature_cache", "Interrupted", "console", "err_console",
    "escape", "print_json", "fail_on_user_error", "to_jsonable", "count", "interrupted_tracking",
    "saved_frames"]

# soft_wrap: lines are not cut at 80 columns when stdout is a file or a pipe (tables still fit the width)
console = Console(soft_wrap=True)
err_console = Console(stderr=True, soft_wrap=True)

F = TypeVar("F", bound=Callable[..., Any])

#: The algorithm of `track`, `demo` and `bench track` when none is named.
DEFAULT_ALGO = "refined-heading"

#: `track --backward-path`'s default: swarmpose.track.path.DEFAULT_PATH_WEIGHT (not imported here, which would
#: import the tracker's data sources with every command; the tests check the two are equal).
DEFAULT_BACKWARD_PATH = 0.3

#: `--feature-cache` of the commands that track: the folder of the feature stores (track.feature_store).
DEFAULT_FEATURE_CACHE = "cache/features"
FEATURE_CACHE_HELP = ("Folder that keeps each sequence's silhouettes and edge pixels between runs (a later run of "
                      "the same sequence, views and --features reads them instead of decoding the images; the "
                      "results are the same); 'off': compute every frame.")


def feature_cache(value: str | None) -> Path | None:
    """``--feature-cache``'s folder, or None for ``off``."""
    if value is None or value.strip().lower() in ("off", "none", ""):
        return None
    return Path(value)


def count(n: int, word: str) -> str:
    """``1 frame``, ``2 frames``."""
    return f"{n} {word}{'' if n == 1 else 's'}"


def print_json(data: Any) -> None:
    """Print exactly one JSON object on stdout (the ``--json`` contract)."""
    sys.stdout.write(json.dumps(to_jsonable(data), indent=None) + "\n")
    sys.stdout.flush()


def _os_message(exc: OSError) -> str:
    """``PATH: reason`` for a file-system error (``[Errno 17] File exists: '/dev/null'`` reads badly)."""
    if not exc.filename or not exc.strerror:
        return str(exc)
    hint = ""
    if isinstance(exc, FileExistsError | NotADirectoryError):
        hint = " (a file stands where a folder is needed)"
    return f"{exc.filename}: {exc.strerror}{hint}"


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, with what the command had saved by then in ``message`` (:func:`interrupted_tracking`)."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


def saved_frames(folder: Path) -> int:
    """Frames tracked and saved under ``folder`` (a `track` results folder, or a `compare` folder with one
    results folder per clip and entry): the sum of every run's ``progress.npz`` count, which a run replaces
    after each frame and keeps when it finishes; 0 when there is none."""
    total = 0
    for progress in sorted(Path(folder).glob("**/run_*/progress.npz")):
        try:
            with np.load(progress) as z:
                total += max(0, int(z["done"]))
        except (OSError, ValueError, KeyError):  # one being replaced as the run stopped: a resume reports it
            continue
    return total


def interrupted_tracking(folder: Path | None) -> Interrupted:
    """The Ctrl-C message of `track` and `compare` tracking into ``folder`` (None: not chosen yet, as while a
    clip is synthesised): the frames saved there and how to go on from them, or that none was saved."""
    frames = saved_frames(folder) if folder is not None else 0
    if frames:
        return Interrupted(f"interrupted; {count(frames, 'frame')} tracked so far {'is' if frames == 1 else 'are'} "
                           f"saved in {folder}: run the same command with --resume to continue")
    return Interrupted("interrupted before any frame was saved: nothing to resume (run the same command to start "
                       "again)")


def fail_on_user_error(func: F) -> F:
    """Turn swarmpose's own errors (bad files, bad options) and file-system errors (an output path under a file,
    no permission) into a one-line message and exit code 2.

    Under ``--json`` (a ``json_out`` argument that is true) stdout also gets the one JSON object the
    contract promises, ``{"error": MESSAGE, "exit_code": 2}``, so a script reading stdout sees why.
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except BrokenPipeError:  # stdout closed by the reader (`| head`): nothing to report to
            raise
        except KeyboardInterrupt as exc:
            if isinstance(exc, Interrupted):  # the command said what it had saved (`track`, `compare`)
                message = exc.message
            else:
                message = ("interrupted; the frames tracked so far are saved: run the same command with --resume "
                           "to continue" if "resume" in kwargs else "interrupted")
            err_console.print(f"[bold red]{escape(message)}[/bold red]", highlight=False)
            if kwargs.get("json_out") is True:
                print_json({"error": message, "exit_code": 130})
            raise typer.Exit(code=130) from None
        except (SwarmposeError, OSError) as exc:  # OSError: a path that cannot be read or written
            message = _os_message(exc) if isinstance(exc, OSError) else str(exc)
            err_console.print(f"[bold red]error:[/bold red] {escape(message)}", highlight=False)
            if kwargs.get("json_out") is True:
                print_json({"error": message, "exit_code": 2})
            raise typer.Exit(code=2) from None

    return wrapper  # type: ignore[return-value]


def note_upsampling(clip: Path, fps: float) -> None:
    """Say on stderr when ``--fps`` is above the clip's capture rate: frames between captured ones are
    interpolated (joint rotations slerped), not measured."""
    from swarmpose.io.bvh import read_bvh

    try:
        rate = read_bvh(clip).frame_rate
    except Exception:  # noqa: BLE001 - the caller reads the file again and reports its errors itself
        return
    if fps > rate * (1 + 1e-6):
        err_console.print(f"note: {escape(str(clip))} is captured at {rate:g} Hz; at --fps {fps:g} the frames "
                          "between captured ones are interpolated, not measured", highlight=False)


def names_a_folder(path: str) -> bool:
    """``--out`` text that means a folder: an existing one, or one named with a trailing separator
    (``out/``; typer's ``Path`` would drop the slash, so such options take ``str``)."""
    return path.endswith(("/", os.sep)) or Path(path).is_dir()
