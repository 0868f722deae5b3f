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

__all__ = ["console", "err_console", "escape", "print_json", "fail_on_user_error", "to_jsonable", "count"]

# soft_wrap: lines are not cut at 80 columns when stdout is a file or a pipe (tables still fit the width)
console = Console(soft_wrap=True)
err_console = Console(stderr=True, soft_wrap=True)

F = TypeVar("F", bound=Callable[..., Any])


def count(n: int, word: str) -> str:
    """``1 frame``, ``2 frames``."""
    return f"{n} {word}{'' if n == 1 else 's'}"


def to_jsonable(obj: Any) -> Any:
    """Numpy scalars/arrays and paths to plain JSON types (NaN/inf become null)."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    if isinstance(obj, str | int | float | bool) or obj is None:
        return obj
    return str(obj)


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
        except KeyboardInterrupt:
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
