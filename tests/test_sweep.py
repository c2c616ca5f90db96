"""Sweeps on a Dask local cluster: the same rows as a plain loop, resume without re-running,
failed jobs recorded, a killed worker's jobs re-run elsewhere, each job exactly once."""

from __future__ import annotations

import os
import signal
import threading
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

from usvfast.cli import app
from usvfast.sweep import load_spec, run_job, run_sweep
from usvfast.sweep.engine import open_client
from usvfast.sweep.summary import pareto_front

REPO = Path(__file__).resolve().parents[1]
JOYRIDE_SPEC = REPO / "configs" / "sweep-joyride.toml"
TESTS = Path(__file__).resolve().parent


@pytest.fixture(autouse=True)
def workers_import_test_jobs(monkeypatch):
    # Local-cluster workers are new processes: they find tests/sweepjobs.py through PYTHONPATH.
    path = os.pathsep.join(p for p in (str(TESTS), os.environ.get("PYTHONPATH", "")) if p)
    monkeypatch.setenv("PYTHONPATH", path)


def _spec(tmp_path: Path, body: str, name: str = "spec.toml") -> Path:
    (tmp_path / "rec.txt").write_text("a recording\n")
    p = tmp_path / name
    p.write_text(body)
    return p


SLOW = """
[sweep]
kind = "sweepjobs:slow_job"
base = "none"
recordings = ["rec.txt"]
metric = "x2"
[grid]
x = [{xs}]
sleep = [{sleep}]
"""


def test_grid_expands_every_combination_with_stable_ids():
    spec = load_spec(JOYRIDE_SPEC)
    assert len(spec.jobs) == 72
    assert len({j.job_id for j in spec.jobs}) == 72
    assert {
        (j.params["base"], j.params["tracker.q"], j.params["tracker.sigma"]) for j in spec.jobs
    } == {
        (b, q, s)
        for b in ("joyride-cv", "joyride")
        for q in (1.0, 2.0, 5.0, 10.0, 20.0, 50.0)
        for s in (10, 15, 20, 25, 30, 40.0)
    }
    assert [j.job_id for j in load_spec(JOYRIDE_SPEC).jobs] == [j.job_id for j in spec.jobs]


def test_latin_hypercube_search_is_reproducible_and_inside_its_ranges(tmp_path):
    body = """
[sweep]
kind = "plots"
base = "joyride"
recordings = ["rec.txt"]
[search]
method = "lhs"
budget = 12
seed = 3
[search.ranges]
"tracker.q" = {low = 0.5, high = 50.0, log = true}
"tracker.delete_steps" = [5, 60]
"""
    a, b = load_spec(_spec(tmp_path, body)), load_spec(_spec(tmp_path, body))
    assert [j.params for j in a.jobs] == [j.params for j in b.jobs]
    q = np.array([j.params["tracker.q"] for j in a.jobs])
    steps = [j.params["tracker.delete_steps"] for j in a.jobs]
    assert len(a.jobs) == 12 and np.all((q >= 0.5) & (q <= 50.0))
    assert all(isinstance(s, int) and 5 <= s <= 60 for s in steps)
    # Latin hypercube: one point in each of the 12 equal strata of log q.
    strata = np.floor(12 * np.log(q / 0.5) / np.log(100.0)).astype(int)
    assert sorted(strata) == list(range(12))


@pytest.mark.parametrize(
    ("body", "match"),
    [
        ("[sweep]\nkind='plots'\nbase='joyride'\nrecordings=['missing.mat']\n", "does not exist"),
        ("[sweep]\nkind='plots'\nbase='j'\nrecordings=['rec.txt']\ncolour='red'\n", "colour"),
        ("[sweep]\nkind='nope'\nbase='j'\nrecordings=['rec.txt']\n", "sweep.kind"),
        ("[sweep]\nkind='plots'\nbase=3\nrecordings=['rec.txt']\n", "sweep.base"),
        ("[sweep]\nkind='plots'\nbase='j'\nrecordings=['rec.txt']\n[grid]\nq=[]\n", "grid.q"),
        ("[sweep]\nkind='plots'\nbase='j'\nrecordings=['rec.txt']\n[grdi]\n", "grdi"),
        ("[sweep\n", "not valid TOML"),
    ],
)
def test_bad_specs_name_the_key_and_the_file(tmp_path, body, match):
    path = _spec(tmp_path, body)
    with pytest.raises(ValueError, match=match) as e:
        load_spec(path)
    assert str(path) in str(e.value)


def test_joyride_sweep_on_the_local_cluster_equals_a_plain_loop(tmp_path):
    spec = load_spec(JOYRIDE_SPEC)
    result = run_sweep(spec, tmp_path, engine="local", workers=2)
    assert result.ran == 72 and (result.table["status"] == "ok").all()
    assert result.table["worker"].nunique() == 2  # both workers took jobs
    loop = pd.DataFrame([run_job(j) for j in spec.jobs])
    metrics = [c for c in loop if c.startswith(("metric.", "param."))]
    metrics.remove("metric.ms_per_scan")  # a timing, not a result
    got = result.table.set_index("job_id").loc[loop["job_id"], metrics].reset_index(drop=True)
    pd.testing.assert_frame_equal(got, loop[metrics])
    # Over the q x sigma grid, the IMM + existence preset (joyride) keeps one fragment more
    # often than the constant-velocity preset (joyride-cv), and at one fragment it covers more
    # of the target with fewer false tracks.
    one = loop[loop["metric.fragments"] == 1]
    imm, cv = (one[one["param.base"] == b] for b in ("joyride", "joyride-cv"))
    assert len(imm) > len(cv) > 0
    assert imm["metric.coverage"].max() > cv["metric.coverage"].max() >= 0.94
    assert imm["metric.tracks_elsewhere"].min() < cv["metric.tracks_elsewhere"].min()
    assert imm["metric.tracks_elsewhere"].median() < cv["metric.tracks_elsewhere"].median()


def test_resume_runs_only_the_jobs_not_finished(tmp_path):
    spec = load_spec(_spec(tmp_path, SLOW.format(xs="1, 2, 3, 4, 5, 6", sleep="0.0")))
    first = run_sweep(spec, tmp_path / "out", workers=1)
    assert first.ran == 6
    # A crash after three jobs: only three parts rows survive.
    table = first.table
    for p in (tmp_path / "out" / "results.parts").glob("*.parquet"):
        p.unlink()
    table.iloc[:3].to_parquet(tmp_path / "out" / "results.parts" / "part-000001.parquet")
    again = run_sweep(spec, tmp_path / "out", workers=1)
    assert (again.ran, again.skipped) == (3, 3)
    assert sorted(again.table["job_id"]) == sorted(j.job_id for j in spec.jobs)
    assert (again.table["metric.x2"].sort_values().to_numpy() == [1, 4, 9, 16, 25, 36]).all()
    nothing = run_sweep(spec, tmp_path / "out", workers=1)
    assert (nothing.ran, nothing.skipped, len(nothing.table)) == (0, 6, 6)


def test_a_failing_job_is_a_row_with_its_error_and_the_sweep_goes_on(tmp_path):
    body = SLOW.format(xs="1, 2, 3", sleep="0.0") + "fail = [false, true]\n"
    spec = load_spec(_spec(tmp_path, body))
    result = run_sweep(spec, tmp_path / "out", workers=2)
    t = result.table
    assert len(t) == 6
    bad = t[t["status"] == "error"]
    assert len(bad) == 3 and bad["param.fail"].all()
    assert bad["error"].str.contains("RuntimeError: job asked to fail").all()
    assert (t.loc[t["status"] == "ok", "metric.x2"].sort_values() == [1, 4, 9]).all()
    # Errors are finished jobs: not run again unless asked.
    assert run_sweep(spec, tmp_path / "out", workers=1).ran == 0
    assert run_sweep(spec, tmp_path / "out", workers=1, retry_failed=True).ran == 3
    assert len(run_sweep(spec, tmp_path / "out", workers=1).table) == 6


def test_a_killed_worker_has_its_jobs_rerun_and_every_job_appears_once(tmp_path):
    spec = load_spec(_spec(tmp_path, SLOW.format(xs=", ".join(map(str, range(16))), sleep="0.4")))
    killed = threading.Event()
    with open_client("local", workers=2) as client:
        pids = sorted(client.run(os.getpid).values())

        def kill_one_busy_worker():
            threading.Event().wait(1.0)  # both workers are inside their first jobs
            os.kill(pids[0], signal.SIGKILL)
            killed.set()

        threading.Thread(target=kill_one_busy_worker, daemon=True).start()
        result = run_sweep(spec, tmp_path / "out", client=client)
        assert killed.is_set()
        # The nanny restarted the killed worker: a new process replaced it.
        assert pids[0] not in client.run(os.getpid).values()
    t = result.table
    assert len(t) == 16 and t["job_id"].is_unique
    assert (t["status"] == "ok").all()
    assert sorted(t["metric.x2"]) == [float(x * x) for x in range(16)]


def test_sweep_command_writes_results_and_plots(tmp_path):
    out = tmp_path / "sweep"
    res = CliRunner().invoke(
        app, ["sweep", str(JOYRIDE_SPEC), "--engine", "local", "--out", str(out)]
    )
    assert res.exit_code == 0, res.output
    t = pd.read_parquet(out / "results.parquet")
    assert len(t) == 72 and set(t["status"]) == {"ok"}
    assert (out / "pareto.png").stat().st_size > 10_000
    assert (out / "rmse_vs_tracker.q.png").exists()
    assert "72 jobs (72 run now, 0 finished before, 0 failed)" in res.output


def test_engine_errors_are_clean(tmp_path):
    with pytest.raises(ValueError, match="ray"), open_client("ray"):
        pass
    with pytest.raises(ValueError, match="address"), open_client("dask"):
        pass
    with pytest.raises(ValueError, match="workers"), open_client("local", workers=0):
        pass


def test_missing_dask_is_one_clean_line(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # as if not installed
    with pytest.raises(ImportError, match=r"usvfast\[cluster\]"), open_client("local"):
        pass


@given(st.lists(st.tuples(st.integers(0, 6), st.integers(0, 6)), min_size=1, max_size=30))
def test_pareto_front_equals_brute_force(points):
    acc, cost = np.array(points, dtype=float).T
    front = pareto_front(acc, cost)
    undominated = {
        (a, c)
        for a, c in points
        if not any(a2 <= a and c2 <= c and (a2, c2) != (a, c) for a2, c2 in points)
    }
    assert {(acc[i], cost[i]) for i in front} == undominated
    assert len(front) == len(undominated)  # one point per undominated value
    assert np.all(np.diff(cost[front]) > 0)


def test_pareto_front_needs_one_cost_per_accuracy():
    with pytest.raises(ValueError, match=r"accuracy, cost: expected two \(n,\) arrays"):
        pareto_front(np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match="accuracy: expected a 1-D array"):
        pareto_front(np.zeros((2, 4)), np.zeros((2, 4)))
    np.testing.assert_array_equal(pareto_front([np.nan, 1.0, 0.5], [0.0, 1.0, 2.0]), [1, 2])


def test_harbour_sweep_over_eight_simulated_recordings_equals_a_plain_loop(tmp_path):
    # Eight short simulated harbour recordings x two JPDA detection probabilities, through the
    # whole pipeline (LiDAR and camera chains, the thesis tracker) on the local cluster.
    from usvfast.sim.recording import SimulationOptions, simulate

    for seed in range(101, 109):
        simulate(tmp_path / f"rec{seed}", SimulationOptions(seed=seed, duration=3.0))
    spec_path = tmp_path / "harbour.toml"
    spec_path.write_text(
        """
[sweep]
kind = "pipeline"
base = "recording"
recordings = [{path = "rec*/recording.toml", truth = "{dir}/truth.csv"}]
metric = "thesis.rmse"
[grid]
"tracker.prob_detect" = [0.75, 0.9]
"""
    )
    spec = load_spec(spec_path)
    assert len(spec.jobs) == 16
    result = run_sweep(spec, tmp_path / "out", workers=2)
    t = result.table
    assert (t["status"] == "ok").all(), t.loc[t["status"] != "ok", "error"].tolist()
    assert t["recording"].nunique() == 8
    loop = pd.DataFrame([run_job(j) for j in spec.jobs])
    results = [
        c
        for c in loop
        if c.startswith(("metric.thesis.", "metric.clear_mot.", "param."))
        and not c.endswith("real_time_factor")
    ]
    assert "metric.thesis.rmse" in results and "metric.clear_mot.mota" in results
    got = t.set_index("job_id").loc[loop["job_id"], results].reset_index(drop=True)
    pd.testing.assert_frame_equal(got, loop[results])
    assert (t["time.tracker"] > 0).all() and (t["metric.real_time_factor"] > 0).all()
