"""Ctrl-C: the parallel runs stop at once (no waiting for queued jobs), and the CLI says how to go on."""

from __future__ import annotations

import json
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import typer
from typer.testing import CliRunner

from swarmpose.cli.common import fail_on_user_error
from swarmpose.track.runner import _stop_pool, _worker_init


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # an exited process that nobody has reaped yet is a zombie: it has ended
        return "\nState:\tZ" not in Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True


def _still_running(pids: list[int], within_s: float) -> list[int]:
    """The processes of ``pids`` still running after waiting up to ``within_s`` for them to end."""
    deadline = time.monotonic() + within_s
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    return [p for p in pids if _alive(p)]


def test_stop_pool_terminates_the_workers_at_once():
    pool = ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_worker_init, initargs=(1,))
    futures = [pool.submit(time.sleep, 60) for _ in range(5)]
    deadline = time.monotonic() + 60
    while not any(f.running() for f in futures):
        assert time.monotonic() < deadline, "the pool never started a job"
        time.sleep(0.05)
    pids = list(pool._processes)
    t0 = time.monotonic()
    _stop_pool(pool)
    assert time.monotonic() - t0 < 15
    # asked of the OS: Process.is_alive() can say True for a moment while the pool's own thread reaps it
    assert not _still_running(pids, 10.0)


def test_an_interrupted_command_exits_130_with_the_resume_hint_and_one_json_object():
    app = typer.Typer()

    @app.command()
    @fail_on_user_error
    def track(resume: bool = False, json_out: bool = typer.Option(False, "--json")) -> None:
        raise KeyboardInterrupt

    res = CliRunner().invoke(app, ["--json"])
    assert res.exit_code == 130
    data = json.loads(res.stdout)
    assert data["exit_code"] == 130 and "--resume" in data["error"] and "--resume" in res.stderr


def test_workers_end_when_their_parent_is_killed(tmp_path):
    """A parent killed outright (SIGKILL, or SIGTERM from a batch system) leaves no worker tracking on."""
    import signal
    import subprocess
    import sys

    script = tmp_path / "parent.py"
    script.write_text(
        "import multiprocessing, os, sys, time\n"
        "from concurrent.futures import ProcessPoolExecutor\n"
        "from swarmpose.track.runner import _worker_init\n"
        "if __name__ == '__main__':\n"
        "    pool = ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context('spawn'),\n"
        "                               initializer=_worker_init, initargs=(1, None, os.getpid()))\n"
        "    futures = [pool.submit(time.sleep, 120) for _ in range(2)]\n"
        "    while not all(f.running() for f in futures):\n"
        "        time.sleep(0.05)\n"
        "    print(' '.join(str(p) for p in pool._processes), flush=True)\n"
        "    time.sleep(120)\n")
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        pids = [int(p) for p in proc.stdout.readline().split()]
        assert len(pids) == 2
    finally:
        proc.kill()
        proc.wait()

    left = _still_running(pids, 30.0)
    for p in left:
        os.kill(p, signal.SIGKILL)
    assert not left, f"workers {left} outlived their parent"
