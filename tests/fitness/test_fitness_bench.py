"""``swarmpose bench fitness``: the table and the one-object JSON document."""

from __future__ import annotations

import json
import time

from typer.testing import CliRunner

from swarmpose.cli.app import app
from swarmpose.fitness import torch_available
from swarmpose.fitness.bench import time_call
from swarmpose.fitness.scene import demo_cameras

#: What --backends auto measures here.
AUTO = ["numba", *(["torch"] if torch_available() else []), "reference"]

QUICK = ["bench", "fitness", "--scales", "4", "--batches", "4,6", "--repeats", "1", "--min-time", "0.01",
         "--reference-max-batch", "2"]


def test_json_document():
    res = CliRunner().invoke(app, [*QUICK, "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)  # exactly one JSON object on stdout
    assert set(doc) >= {"machine", "rows", "prepare_ms"}
    assert doc["prepare_ms"] > 0 and doc["machine"]["cpu_count"] >= 1
    assert doc["settings"] == {"backends": AUTO, "scales": [4], "batches": [4, 6], "views": 4,
                               "repeats": 1, "min_time_s": 0.01, "reference_max_batch": 2, "seed": 0}
    assert {r["backend"] for r in doc["rows"]} == set(AUTO)
    assert ("torch" in doc["machine"]) == ("torch" in AUTO)
    for r in doc["rows"]:
        assert set(r) == {"backend", "width", "height", "batch", "evals_per_s", "ratio_to_reference"}
        assert (r["width"], r["height"]) == (161, 121) and r["batch"] in (4, 6) and r["evals_per_s"] > 0
        if r["backend"] == "reference":
            assert r["ratio_to_reference"] == 1.0


def test_table_and_errors():
    res = CliRunner().invoke(app, QUICK[:2] + ["--backends", "numba", *QUICK[2:]])
    assert res.exit_code == 0, res.output
    assert "evaluations/s" in res.stdout and "numba" in res.stdout and "161x121" in res.stdout
    bad = CliRunner().invoke(app, ["bench", "fitness", "--backends", "cuda"])
    assert bad.exit_code == 2
    bad = CliRunner().invoke(app, ["bench", "fitness", "--scales", "0"])
    assert bad.exit_code == 2


def test_views_option_sets_the_cameras(monkeypatch):
    """--views N benchmarks N cameras: recorded in the settings and the table title; 0 is refused."""
    import swarmpose.fitness.scene as scene

    made = []
    monkeypatch.setattr(scene, "demo_cameras", lambda n, **kw: made.append(n) or demo_cameras(n, **kw))
    res = CliRunner().invoke(app, [*QUICK[:2], "--backends", "numba", *QUICK[2:], "--views", "2", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["settings"]["views"] == 2 and made and set(made) == {2}
    res = CliRunner().invoke(app, [*QUICK[:2], "--backends", "numba", *QUICK[2:], "--views", "2"],
                             env={"COLUMNS": "200"})
    assert res.exit_code == 0 and "(2 views" in res.stdout and "2 raw 644x484 images" in res.stdout
    bad = CliRunner().invoke(app, ["bench", "fitness", "--views", "0"])
    assert bad.exit_code == 2 and "--views" in bad.output


def test_time_call_warms_up_for_min_time_before_timing():
    """The first call (a JIT compile, say) and the min_time of warm-up after it are not in the timed runs."""
    calls = []

    def fn():
        calls.append(len(calls))
        time.sleep(0.3 if len(calls) == 1 else 0.002)

    per_call = time_call(fn, repeats=2, min_time=0.05)
    assert per_call < 0.05  # ~0.002 s; the 0.3-s first call is not timed
    # 1 first call + >= 2 warm-up calls filling 0.05 s + >= 2 calls per timed run
    assert len(calls) >= 1 + 2 + 2 * 2
