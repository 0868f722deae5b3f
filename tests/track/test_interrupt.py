"""Ctrl-C: the parallel runs stop at once (no waiting for queued jobs), and the CLI says how to go on."""

from __future__ import annotations

import json
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

import typer
from typer.testing import CliRunner

from swarmpose.cli.common import fail_on_user_error
from swarmpose.track.runner import _stop_pool, _worker_init


def test_stop_pool_terminates_the_workers_at_once():
    pool = ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_worker_init, initargs=(1,))
    futures = [pool.submit(time.sleep, 60) for _ in range(5)]
    deadline = time.monotonic() + 60
    while not any(f.running() for f in futures):
        assert time.monotonic() < deadline, "the pool never started a job"
        time.sleep(0.05)
    procs = list(pool._processes.values())
    t0 = time.monotonic()
    _stop_pool(pool)
    assert time.monotonic() - t0 < 15
    for p in procs:
        p.join(timeout=5)
    assert all(not p.is_alive() for p in procs), [(p.pid, p.exitcode) for p in procs]


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
