"""scripts/sweep (doc/sweeps.md): on a real Dask cluster on 127.0.0.1 (a scheduler and two
workers, one killed mid-sweep) every run's row arrives once and equals a single simulate
run with the same values; an interrupted sweep resumes without running a row twice.

Run by scripts/test (cmake/python.cmake); MECHANISM_SIM_WS names the workspace
scripts/sweep uses, MECHANISM_SIM_SIMULATE the simulate binary.
"""
import csv
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

SOURCE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SWEEP = os.path.join(SOURCE, "scripts/sweep")
SIMULATE = os.environ.get("MECHANISM_SIM_SIMULATE", "")
FOUR_BAR_DRIVEN = os.path.join(SOURCE, "urdf/four_bar_driven.urdf")
XACRO = os.path.join(SOURCE, "test/xacro/robot.urdf.xacro")
FLAG = {"set": "--set", "velocity": "--velocity", "effort": "--effort", "drive": "--drive"}


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def sweep(*args, **kw):
    return subprocess.Popen([SWEEP, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def simulate_row(model, row, keys, options):
    """What simulate says of the run of a sweep row: its values as simulate's options, every
    step a CSV row (--output-every 1 in `options`), peaks taken over the CSV."""
    assert SIMULATE and os.access(SIMULATE, os.X_OK), "MECHANISM_SIM_SIMULATE must name the simulate binary"
    argv = [SIMULATE, model, *options, "--reactions"]
    for k in keys:
        kind, _, name = k.partition(":")
        argv += [f"{name}:={row[k]}"] if kind == "arg" else [FLAG[kind], f"{name}={row[k]}"]
    out = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    if out.returncode != 0:
        return {"error": out.stderr.strip()}
    lines = out.stdout.splitlines()
    header = lines[0].split(",")
    data = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    col = {name: data[:, i] for i, name in enumerate(header)}
    result = {"time": col["time"][-1]}
    # the summary's largest violations (3 digits): of every equation at the start and the
    # end (the CSV's first and last rows: at least those), between them of those a step can
    # leave violated (in joint coordinates the closures', the same equations the CSV's rows
    # check with every other one, in other round-off)
    summary = re.search(r"largest violation ([^ ]+) \(position\), ([^ ;]+) \(velocity\)", out.stderr)
    for k, kind in enumerate(("position", "velocity")):
        c = col["constraint." + kind]
        result["largest_violation." + kind] = float(summary.group(k + 1))
        result["_least." + kind] = max(c[0], c[-1])
    for name in header:
        if name.endswith(".fx"):
            joint = name[:-3]
            f = np.sqrt(col[joint + ".fx"] ** 2 + col[joint + ".fy"] ** 2 + col[joint + ".fz"] ** 2)
            result[joint + ".peak_reaction"] = f.max()
        elif name.endswith(".reaction"):  # a coupling's multiplier
            result[name[:-len(".reaction")] + ".peak_coupling_reaction"] = np.abs(col[name]).max()
    for line in out.stderr.splitlines():  # the driven dofs, from the summary's "drive 'X'"
        for part in line.split("; drive '")[1:]:
            dof = part.split("'")[0]
            result[dof + ".peak_effort"] = np.abs(col[dof + ".effort"]).max()
    return result


def assert_rows_equal_simulate(model, rows, keys, options):
    with ThreadPoolExecutor(2) as pool:
        expected = list(pool.map(lambda r: simulate_row(model, r, keys, options), rows))
    for row, want in zip(rows, expected):
        assert "error" not in want, want
        assert row["status"] == "ok", row
        result_columns = [c for c in row if c not in keys and c not in ("status", "message")]
        assert sorted(result_columns) == sorted(c for c in want if not c.startswith("_")), (sorted(result_columns), sorted(want))
        for c in result_columns:
            if c.startswith("largest_violation."):  # the summary's %.2e, at least the CSV's ends
                assert float(row[c]) == pytest.approx(want[c], rel=5e-3), (c, row)
                assert float(row[c]) >= want["_least." + c.split(".")[1]] * (1 - 1e-11), (c, row)
                continue
            # simulate's CSV has 12 significant digits; the sweep's values the double's repr
            assert float(row[c]) == pytest.approx(want[c], rel=1e-11, abs=1e-300), (c, row)


def start(argv, log, env=None):
    return subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, start_new_session=True, env=env)


def stop(proc):
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def start_scheduler(tmp_path, log, env):
    """A Dask scheduler on 127.0.0.1 (a free port): its process and address."""
    info = tmp_path / "scheduler.json"
    proc = start(["dask-scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                  "--scheduler-file", str(info)], log, env)
    for _ in range(300):
        if info.exists() and info.stat().st_size > 0:
            break
        time.sleep(0.05)
    return proc, json.loads(info.read_text())["address"]


def start_worker(address, name, log, env=None):
    return start(["dask-worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                  "--host", "127.0.0.1", "--name", name], log, env)


@pytest.fixture
def cluster(tmp_path):
    """A Dask scheduler and two workers (no nanny: a killed worker stays dead) on 127.0.0.1.
    The scheduler gives up on a task at the first worker lost under it (allowed-failures 0,
    KilledWorker): the sweep submits it again itself (its own path, not the scheduler's)."""
    log = open(tmp_path / "cluster.log", "w")
    env = dict(os.environ, DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES="0")
    procs = []
    try:
        scheduler, address = start_scheduler(tmp_path, log, env)
        procs.append(scheduler)
        workers = [start_worker(address, f"w{i}", log) for i in range(2)]
        procs += workers
        from distributed import Client
        with Client(address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=60)
        yield address, workers
    finally:
        for p in reversed(procs):
            stop(p)
        log.close()


def test_a_killed_worker_loses_no_run_and_every_row_is_simulates(cluster, tmp_path):
    address, workers = cluster
    out = tmp_path / "results.csv"
    keys = ["drive:crank_joint", "effort:rocker_joint"]
    options = ["--duration", "2", "--dt", "2e-4", "--output-every", "1"]
    sw = sweep(FOUR_BAR_DRIVEN, "--vary", "drive:crank_joint=2:6:4", "--vary", "effort:rocker_joint=0,0.2,0.4,0.6",
               "--out", str(out), "--scheduler", address, "--", *options)
    # kill one worker once a few rows are in: it is in the middle of a run
    rows_at_kill = None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and sw.poll() is None:
        if out.exists() and len(read_rows(out)) >= 3:
            os.killpg(workers[0].pid, signal.SIGKILL)
            workers[0].wait()
            rows_at_kill = len(read_rows(out))
            break
        time.sleep(0.02)
    stdout, stderr = sw.communicate(timeout=120)
    assert sw.returncode == 0, stderr
    assert rows_at_kill is not None and rows_at_kill < 16, f"the worker was not killed mid-sweep ({rows_at_kill})"
    assert "submitted again" in stderr, stderr  # the killed worker's run
    rows = read_rows(out)
    assert len(rows) == 16
    assert len({tuple(r[k] for k in keys) for r in rows}) == 16  # each run once
    assert {r["drive:crank_joint"] for r in rows} == {"2.0", "3.333333333333333", "4.666666666666666", "6.0"}
    assert_rows_equal_simulate(FOUR_BAR_DRIVEN, rows, keys, options)


def test_workers_that_cannot_import_the_module_stop_the_sweep_before_any_run(tmp_path):
    # a worker started outside the sourced workspace: one line with the fix, no results file
    log = open(tmp_path / "cluster.log", "w")
    bare = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "ROS_PACKAGE_PATH", "LD_LIBRARY_PATH")}
    procs = []
    try:
        scheduler, address = start_scheduler(tmp_path, log, bare)
        procs.append(scheduler)
        procs.append(start_worker(address, "bare", log, bare))
        out = tmp_path / "results.csv"
        sw = sweep(FOUR_BAR_DRIVEN, "--vary", "drive:crank_joint=2,3", "--out", str(out), "--scheduler", address)
        _, stderr = sw.communicate(timeout=120)
        assert sw.returncode == 2, stderr
        line = stderr.strip().splitlines()[-1]
        assert line.startswith("sweep: workers that cannot run the sweep: tcp://127.0.0.1:"), stderr
        assert "ModuleNotFoundError: No module named 'mechanism_sim'" in line, stderr
        assert "Start each worker from a sourced workspace" in line, stderr
        assert not out.exists()
    finally:
        for p in reversed(procs):
            stop(p)
        log.close()


def test_an_interrupted_sweep_resumes_where_it_stopped(tmp_path):
    # xacro arguments (one value makes a negative mass: that run's row says so) and an
    # initial position, on two local worker processes
    keys = ["arg:length", "arg:tip_mass", "set:lower_joint"]
    args = [XACRO, "--vary", "arg:length=0.3,0.45", "--vary", "arg:tip_mass=0.5,-1", "--vary",
            "set:lower_joint=0:0.5:2", "--workers", "2"]
    options = ["--duration", "0.5", "--dt", "1e-3", "--output-every", "1"]
    full = tmp_path / "full.csv"
    sw = sweep(*args, "--out", str(full), "--plot", "--", *options)
    _, stderr = sw.communicate(timeout=120)
    assert sw.returncode == 1, stderr  # failed runs
    rows = read_rows(full)
    assert len(rows) == 8
    failed = [r for r in rows if r["status"] != "ok"]
    assert len(failed) == 4 and all(r["arg:tip_mass"] == "-1" and r["status"] == "LoadError" for r in failed)
    cli = subprocess.run([SIMULATE, XACRO, "tip_mass:=-1", *options], capture_output=True, text=True)
    assert cli.returncode == 1 and "simulate: " + failed[0]["message"] + "\n" == cli.stderr
    ok = [r for r in rows if r["status"] == "ok"]
    assert_rows_equal_simulate(XACRO, ok, keys, options)
    for key in keys:  # --plot: a PNG per varied key beside the CSV
        png = tmp_path / f"full.{key.replace(':', '_')}.png"
        assert png.stat().st_size > 10000

    # an interrupted sweep: the header, three rows and the start of a fourth
    part = tmp_path / "part.csv"
    text = full.read_text().splitlines(keepends=True)
    part.write_text("".join(text[:4]) + text[4][:10])
    sw = sweep(*args, "--out", str(part), "--resume", "--", *options)
    _, stderr = sw.communicate(timeout=120)
    assert "8 runs, 3 already in" in stderr and "5 to run" in stderr, stderr
    resumed = read_rows(part)
    assert len(resumed) == 8
    by_key = lambda rs: sorted(rs, key=lambda r: tuple(r[k] for k in keys))  # noqa: E731
    assert by_key(resumed) == by_key(rows)  # the same values, to the last digit, each run once

    # nothing left: a second --resume runs nothing
    sw = sweep(*args, "--out", str(part), "--resume", "--", *options)
    _, stderr = sw.communicate(timeout=120)
    assert "0 to run" in stderr and len(read_rows(part)) == 8


def test_a_reduction_sweep_finds_the_smallest_ratio_the_motor_is_enough_for(tmp_path):
    # test/urdf/geared_pendulum.urdf.xacro turned a turn a second behind N:1: the motor gives
    # at most 9.81 / N N m, RMS 9.81 / (N sqrt 2), at 2 pi N rad/s. Its 0.3 N m peak holds
    # from N = 32.7, its 0.15 N m continuous rating from N = 46.25, its 400 rad/s up to
    # N = 63.66: within its ratings for 47 <= N <= 63 of these.
    geared = os.path.join(SOURCE, "test/urdf/geared_pendulum.urdf.xacro")
    out = tmp_path / "reduction.csv"
    ratios = [30, 40, 46, 47, 50, 60, 63, 64, 70]
    sw = sweep(geared, "--vary", "arg:reduction=" + ",".join(map(str, ratios)), "--workers", "1", "--out", str(out),
               "--plot", "--", "drive:=true", "--duration", "1", "--dt", "1e-3")
    _, stderr = sw.communicate(timeout=120)
    assert sw.returncode == 0, stderr
    rows = sorted(read_rows(out), key=lambda r: float(r["arg:reduction"]))
    assert [float(r["arg:reduction"]) for r in rows] == ratios
    mgl = 2 * 9.81 * 0.5
    for r in rows:
        n = float(r["arg:reduction"])
        assert float(r["motor.peak_torque"]) == pytest.approx(mgl / n, rel=1e-9)
        assert float(r["motor.rms_torque"]) == pytest.approx(mgl / (n * math.sqrt(2)), rel=1e-9)
        assert float(r["motor.peak_speed"]) == pytest.approx(2 * math.pi * n, rel=1e-12)
        assert r["motor.within_rating"] == ("1" if 46.25 < n < 63.66 else "0"), r
    smallest = min(float(r["arg:reduction"]) for r in rows if r["motor.within_rating"] == "1")
    assert smallest == 47
    png = tmp_path / "reduction.arg_reduction.png"
    assert png.stat().st_size > 10000


def test_a_planetary_sweep_carries_each_couplings_peak_reaction(tmp_path):
    # urdf/planetary_gear.urdf, the sun driven at w: the carrier turns at w / 4 against
    # 0.05 N m s/rad, a load Willis' equation carries as 96 lambda, lambda = 0.05 w / 384
    planetary = os.path.join(SOURCE, "urdf/planetary_gear.urdf")
    out = tmp_path / "planetary.csv"
    keys = ["drive:sun_joint"]
    options = ["--duration", "0.2", "--dt", "1e-3", "--output-every", "1"]
    sw = sweep(planetary, "--vary", "drive:sun_joint=4,10", "--workers", "1", "--out", str(out), "--", *options)
    _, stderr = sw.communicate(timeout=120)
    assert sw.returncode == 0, stderr
    rows = read_rows(out)
    assert len(rows) == 2
    for r in rows:
        w = float(r["drive:sun_joint"])
        assert float(r["willis.peak_coupling_reaction"]) == pytest.approx(0.05 * w / 384, rel=1e-6), r
    assert_rows_equal_simulate(planetary, rows, keys, options)


def test_a_saturating_sweep_carries_each_actuators_largest_lag(tmp_path):
    # urdf/winch.urdf with --actuator-limits: a drive asking w of the drum within the motor's
    # reach (w = 5 rad/s: 100 rad/s at the motor, where its line gives 0.375 N m > 0.245)
    # never lags; asking 15 rad/s it lags behind (the drum settles at 10.19 rad/s)
    winch = os.path.join(SOURCE, "urdf/winch.urdf")
    out = tmp_path / "winch.csv"
    sw = sweep(winch, "--vary", "drive:drum_joint=5,15", "--workers", "1", "--out", str(out), "--",
               "--actuator-limits", "--duration", "0.5", "--dt", "1e-3")
    _, stderr = sw.communicate(timeout=120)
    assert sw.returncode == 0, stderr
    rows = {float(r["drive:drum_joint"]): r for r in read_rows(out)}
    assert float(rows[5.0]["winch_motor.largest_lag"]) == 0.0
    assert float(rows[15.0]["winch_motor.largest_lag"]) > 1.0
    assert rows[15.0]["winch_motor.within_rating"] == "1"


def test_bad_arguments_stop_before_running(tmp_path):
    out = tmp_path / "x.csv"
    for argv, message in [
        (["--vary", "bogus:x=1,2"], "KEY one of arg:NAME"),
        (["--vary", "set:crank_joint=1:2"], "not a finite number"),
        (["--vary", "set:crank_joint=0:1:0"], "NUM >= 1"),
        (["--vary", "set:crank_joint=1,1"], "given twice"),
        (["--vary", "set:crank_joint=1", "--", "--csv", "y.csv"], "a sweep writes --out"),
        (["--vary", "set:crank_joint=1", "--", "--frobnicate"], "not one a sweep passes on"),
    ]:
        sw = sweep(FOUR_BAR_DRIVEN, "--out", str(out), *argv)
        _, stderr = sw.communicate(timeout=60)
        assert sw.returncode == 2 and message in stderr, (argv, stderr)
        assert not out.exists()
    # a CSV of another sweep is not resumed
    out.write_text("a,b,status\n1,2,ok\n")
    sw = sweep(FOUR_BAR_DRIVEN, "--out", str(out), "--vary", "set:crank_joint=1", "--resume")
    _, stderr = sw.communicate(timeout=60)
    assert sw.returncode == 2 and "not this sweep's" in stderr, stderr
    sw = sweep(FOUR_BAR_DRIVEN, "--out", str(out), "--vary", "set:crank_joint=1")
    _, stderr = sw.communicate(timeout=60)
    assert sw.returncode == 2 and "--resume to continue it" in stderr, stderr
