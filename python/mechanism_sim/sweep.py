"""Design sweeps (scripts/sweep, doc/sweeps.md): one simulate run per combination of the
varied values, on local cores or a Dask cluster, one CSV row per run as it finishes.

    scripts/sweep MODEL --vary KEY=V1,V2,...|START:STOP:NUM ... --out RESULTS.csv
                  [--scheduler ADDRESS] [--workers N] [--resume] [--plot] [-- SIMULATE_OPTIONS]

A run is what `simulate MODEL SIMULATE_OPTIONS` with the run's values added would do: the
same loading, the same steps, the reactions read at the same samples (every
--output-every steps and at the end). The workers load and step the model in-process
with the Python module (run()); the client writes the rows.
"""
import argparse
import csv
import itertools
import math
import os
import sys
import time

KINDS = ("arg", "set", "velocity", "effort", "drive")
# simulate's options a sweep passes on (SIMULATE_OPTIONS); the rest of simulate's are about
# its own output
_VALUE_FLAGS = {"--duration", "--dt", "--output-every", "--integrator", "--closures", "--formulation", "--actuators"}
_ASSIGN_FLAGS = {"--set": "set", "--velocity": "velocity", "--effort": "effort", "--drive": "drive"}
_BOOL_FLAGS = {"--actuator-limits": "actuator_limits"}
_IGNORED_FLAGS = {"--reactions", "--quiet", "--poses"}
_REFUSED_FLAGS = {"--csv", "--bag", "--plot", "--plot-columns"}
RESULT_PREFIX = ("status", "time", "largest_violation.position", "largest_violation.velocity")


class SweepError(Exception):
    """A sweep that cannot start: bad arguments, a CSV of another sweep."""


# ---- the runs

def parse_vary(text):
    """KEY=V1,V2,... or KEY=START:STOP:NUM -> (KEY, [value strings])."""
    key, eq, spec = text.partition("=")
    kind, colon, name = key.partition(":")
    if not eq or not colon or not name or kind not in KINDS:
        raise SweepError(f"--vary needs KEY=VALUES with KEY one of {', '.join(k + ':NAME' for k in KINDS)}, not '{text}'")
    parts = spec.split(":")
    if len(parts) == 3:
        try:
            start, stop, num = float(parts[0]), float(parts[1]), int(parts[2])
        except ValueError:
            raise SweepError(f"--vary {key}: START:STOP:NUM needs two numbers and a count, not '{spec}'") from None
        if num < 1 or not (math.isfinite(start) and math.isfinite(stop)):
            raise SweepError(f"--vary {key}: START:STOP:NUM needs finite ends and NUM >= 1, not '{spec}'")
        # shortest repr: the string the CSV keeps reads back as the very double the run used
        values = [repr(start + (stop - start) * i / (num - 1)) if num > 1 else repr(start) for i in range(num)]
        values[-1] = repr(stop) if num > 1 else values[-1]
    else:
        values = [v.strip() for v in spec.split(",")]
    if not values or any(v == "" for v in values):
        raise SweepError(f"--vary {key}: an empty value in '{spec}'")
    if kind != "arg":
        for v in values:
            try:
                if not math.isfinite(float(v)):
                    raise ValueError
            except ValueError:
                raise SweepError(f"--vary {key}: '{v}' is not a finite number") from None
    if len(set(values)) != len(values):
        raise SweepError(f"--vary {key}: a value is given twice in '{spec}'")
    return key, values


def parse_simulate_options(argv):
    """SIMULATE_OPTIONS -> (settings, fixed {KEY: value}) with KEY as --vary names them."""
    settings = {"duration": 10.0, "dt": 1e-3, "output_every": 10, "integrator": "", "closures": None, "formulation": "",
                "actuators": None, "actuator_limits": False}
    fixed = {}
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in _VALUE_FLAGS or a in _ASSIGN_FLAGS:
            if i + 1 >= len(argv):
                raise SweepError(f"simulate option {a} needs a value")
            v = argv[i + 1]
            i += 2
            if a in _ASSIGN_FLAGS:
                name, eq, value = v.partition("=")
                if not eq or not name:
                    raise SweepError(f"{a} needs JOINT=VALUE, not '{v}'")
                fixed[f"{_ASSIGN_FLAGS[a]}:{name}"] = value
            elif a == "--integrator":
                settings["integrator"] = v
            elif a == "--formulation":
                settings["formulation"] = v
            elif a in ("--closures", "--actuators"):
                settings[a[2:]] = os.path.abspath(v)
            else:
                try:
                    x = float(v)
                except ValueError:
                    raise SweepError(f"{a} needs a number, not '{v}'") from None
                settings[a[2:].replace("-", "_")] = int(x) if a == "--output-every" else x
            continue
        if a in _BOOL_FLAGS:
            settings[_BOOL_FLAGS[a]] = True
            i += 1
            continue
        if a in _IGNORED_FLAGS:
            i += 1
            continue
        if a in _REFUSED_FLAGS:
            raise SweepError(f"simulate option {a} writes simulate's own output; a sweep writes --out")
        if ":=" in a and not a.startswith("-"):
            name, _, value = a.partition(":=")
            fixed[f"arg:{name}"] = value
            i += 1
            continue
        raise SweepError(f"simulate option '{a}' is not one a sweep passes on")
    if not settings["dt"] > 0 or not settings["duration"] >= 0 or settings["output_every"] < 1:
        raise SweepError("--dt must be > 0, --duration >= 0, --output-every >= 1")
    return settings, fixed


def load_kwargs(values):
    """{KEY: value string} -> mechanism_sim.load() keyword arguments."""
    kw = {"args": {}, "positions": {}, "velocities": {}, "efforts": {}, "drives": {}}
    field = {"arg": "args", "set": "positions", "velocity": "velocities", "effort": "efforts", "drive": "drives"}
    for key, value in values.items():
        kind, _, name = key.partition(":")
        kw[field[kind]][name] = value if kind == "arg" else float(value)
    return {k: v for k, v in kw.items() if v}


def run(model, values, settings):
    """One run, in the worker's process: the row's results (status, violations, peaks).

    As simulate: load with the values, then steps of dt in samples of output_every steps,
    the reactions (joints' and couplings') read at t = 0, at every sample and at the end; the largest violations and
    the drives' peak efforts at every step."""
    import numpy as np

    import mechanism_sim

    row = {"status": "ok", "message": ""}
    m = None
    try:
        m = mechanism_sim.load(model, integrator=settings["integrator"], closures=settings["closures"],
                               formulation=settings["formulation"], actuators=settings.get("actuators"),
                               actuator_limits=settings.get("actuator_limits", False),
                               **load_kwargs(values))
        peak, peak_coupling = {}, {}

        def sample():
            r = m.reactions()
            for joint, f in zip(r["joints"], np.linalg.norm(r["force"], axis=1)):
                peak[joint] = max(peak.get(joint, 0.0), float(f))
            for name, lam in zip(r["couplings"], r["coupling"]):
                peak_coupling[name] = max(peak_coupling.get(name, 0.0), abs(float(lam)))

        sample()
        steps = round(settings["duration"] / settings["dt"])
        every = settings["output_every"]
        try:
            while m.steps() < steps:
                m.step(settings["dt"], min(every, steps - m.steps()))
                sample()
        finally:
            for joint, f in peak.items():
                row[f"{joint}.peak_reaction"] = f
            for name, lam in peak_coupling.items():
                row[f"{name}.peak_coupling_reaction"] = lam
    except mechanism_sim.Error as e:
        row["status"], row["message"] = type(e).__name__, str(e)
    if m is not None:
        row["time"] = m.time()
        worst = m.largest_violation()
        row["largest_violation.position"] = worst["position"]
        row["largest_violation.velocity"] = worst["velocity"]
        for dof, (effort, _) in m.drive_peaks().items():
            row[f"{dof}.peak_effort"] = abs(effort)
        for name, a in m.actuator_sizing().items():
            row.update(actuator_cells(name, a))
    return row


ACTUATOR_COLUMNS = ("peak_torque", "rms_torque", "peak_speed", "within_rating")


def actuator_cells(name, sizing):
    """An actuator's sizing cells (doc/actuators.md): peak and RMS torque and peak speed at
    the motor, and 1 within its ratings, 0 not, empty without ratings; in the saturating mode
    its drive's largest lag."""
    flag = sizing["within_rating"]
    cells = {f"{name}.peak_torque": sizing["peak_torque"], f"{name}.rms_torque": sizing["rms_torque"],
             f"{name}.peak_speed": sizing["peak_speed"], f"{name}.within_rating": "" if flag is None else int(flag)}
    if "largest_lag" in sizing:  # --actuator-limits: how far its drive fell behind
        cells[f"{name}.largest_lag"] = sizing["largest_lag"]
    return cells


def result_columns(model, values, settings):
    """The CSV's result columns, from the model as the first run loads it."""
    import mechanism_sim

    try:
        m = mechanism_sim.load(model, integrator=settings["integrator"], closures=settings["closures"],
                               formulation=settings["formulation"], actuators=settings.get("actuators"),
                               actuator_limits=settings.get("actuator_limits", False),
                               **load_kwargs(values))
    except mechanism_sim.Error:
        return list(RESULT_PREFIX) + ["message"]
    return (list(RESULT_PREFIX) + [f"{d}.peak_effort" for d in m.driven_dofs()] +
            [f"{j}.peak_reaction" for j in m.reaction_joints()] +
            [f"{c}.peak_coupling_reaction" for c in m.reaction_couplings()] +
            [f"{a}.{c}" for a in m.actuator_names()
             for c in ACTUATOR_COLUMNS + (("largest_lag",) if settings.get("actuator_limits") else ())] + ["message"])


# ---- the CSV

def read_done(path, header):
    """Runs already in the CSV (by their varied values) for --resume; a last line cut short
    (an interrupted write) is dropped from the file."""
    with open(path, "rb+") as f:
        data = f.read()
        cut = data.rfind(b"\n") + 1
        if cut < len(data):
            f.truncate(cut)
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return set()
    if rows[0] != header:
        raise SweepError(f"{path}: its columns are not this sweep's (another model or other --vary keys); "
                         f"--resume continues the same sweep")
    n = len(header) - len(header_results(header))
    return {tuple(r[:n]) for r in rows[1:] if len(r) == len(header)}


def header_results(header):
    return header[header.index("status"):]


def format_value(v):
    return repr(v) if isinstance(v, float) else str(v)


# ---- the sweep

def sweep(model, vary, out, settings, fixed, scheduler=None, workers=None, resume=False, plot=False,
          log=sys.stderr):
    keys = [k for k, _ in vary]
    if len(set(keys)) != len(keys):
        raise SweepError("a key is varied twice")
    model = os.path.abspath(model)
    combos = [dict(zip(keys, c)) for c in itertools.product(*(v for _, v in vary))]

    def values_of(combo):
        v = dict(fixed)
        v.update(combo)
        return v

    header = keys + result_columns(model, values_of(combos[0]), settings)
    done = set()
    if resume and os.path.exists(out) and os.path.getsize(out) > 0:
        done = read_done(out, header)
    elif os.path.exists(out) and os.path.getsize(out) > 0 and not resume:
        raise SweepError(f"{out} exists: --resume to continue it, or remove it")
    todo = [c for c in combos if tuple(c[k] for k in keys) not in done]
    print(f"sweep: {len(combos)} runs, {len(combos) - len(todo)} already in {out}, {len(todo)} to run", file=log)

    new_file = not (os.path.exists(out) and os.path.getsize(out) > 0)
    f = open(out, "a", newline="")
    writer = csv.writer(f)
    if new_file:
        writer.writerow(header)
        f.flush()
    written, failed = set(done), 0
    extra_warned = False

    def write(combo, row):
        nonlocal failed, extra_warned
        key = tuple(combo[k] for k in keys)
        if key in written:  # a run retried after its first result arrived: once only
            return False
        written.add(key)
        extra = set(row) - set(header)
        if extra and not extra_warned:
            extra_warned = True
            print(f"sweep: columns of this run not in the header (the model differs between runs): "
                  f"{', '.join(sorted(extra))}; left out", file=log)
        writer.writerow([combo[k] for k in keys] + [format_value(row.get(c, "")) for c in header_results(header)])
        f.flush()
        os.fsync(f.fileno())
        if row["status"] != "ok":
            failed += 1
        return True

    started = time.monotonic()
    try:
        if todo:
            _run_all(model, todo, values_of, settings, scheduler, workers, write, log, lambda: failed)
    except SweepError:
        if new_file and len(written) == len(done):
            f.close()
            os.remove(out)  # nothing ran: no file, so the same command works once fixed
        raise
    finally:
        f.close()
    elapsed = time.monotonic() - started
    ran = len(written) - len(done)
    print(f"sweep: {ran} runs in {elapsed:.1f} s ({ran / elapsed if elapsed > 0 else 0:.2f} runs/s), "
          f"{failed} failed; {out}", file=log)
    if plot:
        for png in plot_results(out, keys):
            print(f"sweep: {png}", file=log)
    return ran, failed


def _run_all(model, todo, values_of, settings, scheduler, workers, write, log, failed):
    import logging

    from dask.distributed import Client, LocalCluster, as_completed
    from concurrent.futures import CancelledError
    from distributed.scheduler import KilledWorker
    from tqdm import tqdm

    cluster = None
    if scheduler:
        client = Client(scheduler, timeout="30s")
    else:
        cluster = LocalCluster(n_workers=workers or os.cpu_count(), threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
    try:
        _check_workers(client, model)
        bar = tqdm(total=len(todo), unit="run", file=log, disable=None, dynamic_ncols=True)
        # a worker lost while running a task: the scheduler gives the task to another worker
        # (up to distributed.scheduler.allowed-failures); past that, or when the connection
        # breaks, the run is submitted again here, at most `resubmits` times
        resubmits = 3
        futures = {}  # key -> (combo, resubmissions so far)
        submitted = []
        for c in todo:
            fut = client.submit(run, model, values_of(c), settings, pure=False)
            futures[fut.key] = (c, 0)
            submitted.append(fut)
        pending = as_completed(submitted)
        for fut in pending:
            combo, tries = futures.pop(fut.key)
            try:
                row = fut.result()
            except (KilledWorker, CancelledError, OSError) as e:
                if tries >= resubmits:
                    row = {"status": "lost", "message": f"the run's worker was lost {tries + 1} times ({e})"}
                else:
                    print(f"\nsweep: {_describe(combo)}: its worker was lost ({type(e).__name__}); submitted again",
                          file=log)
                    again = client.submit(run, model, values_of(combo), settings, pure=False)
                    futures[again.key] = (combo, tries + 1)
                    pending.add(again)
                    continue
            except Exception as e:  # a bug in run(): reported in its row, the sweep goes on
                row = {"status": "error", "message": f"{type(e).__name__}: {e}"}
            fut.release()
            if write(combo, row):
                bar.update(1)
                bar.set_postfix(failed=failed())
        bar.close()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# What a worker lacks to run the sweep: "" when it imports the module and reads the model.
# Defined from source, outside any module, so that it travels to the worker by value: a
# function of this module would need the very import it checks.
_PROBE = """
def probe(model):
    import os
    try:
        import mechanism_sim
    except Exception as e:
        return type(e).__name__ + ": " + str(e)
    return "" if os.access(model, os.R_OK) else "cannot read " + model
"""


def _probe():
    scope = {"__name__": "__main__"}
    exec(_PROBE, scope)
    return scope["probe"]


def _check_workers(client, model, timeout=60):
    """Every worker of the cluster imports mechanism_sim and reads the model, asked once
    before any run is submitted; else SweepError with the fix."""
    try:
        client.wait_for_workers(1, timeout=timeout)
    except Exception:
        raise SweepError(f"no worker joined the scheduler within {timeout} s")
    bad = []
    for address in sorted(client.scheduler_info()["workers"]):
        try:
            lacks = client.run(_probe(), model, workers=[address]).get(address, "no answer")
        except Exception as e:
            lacks = f"{type(e).__name__}: {e}"
        if lacks:
            bad.append(f"{address}: {lacks}")
    if bad:
        raise SweepError("workers that cannot run the sweep: " + "; ".join(bad) +
                         ". Start each worker from a sourced workspace (source .catkin_ws/devel/setup.bash, "
                         "then dask-worker ...) on a machine that has the model at the same path")


def _describe(combo):
    return " ".join(f"{k}={v}" for k, v in combo.items())


# ---- plots

def plot_results(path, keys):
    """One PNG per varied key beside the CSV: every result column against it."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return []
    results = [c for c in rows[0] if c not in keys and c not in ("status", "message", "time")]
    ok = [r for r in rows if r["status"] == "ok"]
    pngs = []
    for key in keys:
        xs_text = [r[key] for r in ok]
        try:
            xs = [float(x) for x in xs_text]
            ticks = None
        except ValueError:
            order = sorted(set(xs_text))
            xs = [order.index(x) for x in xs_text]
            ticks = order
        n = len(results)
        cols = min(3, n) or 1
        nrows = max(1, math.ceil(n / cols))
        fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.2 * nrows), squeeze=False)
        for ax, col in zip(axes.flat, results):
            ys = [float(r[col]) if r.get(col, "") != "" else math.nan for r in ok]
            ax.plot(xs, ys, "o", markersize=4)
            ax.set_xlabel(key)
            ax.set_title(col, fontsize=9)
            if ticks:
                ax.set_xticks(range(len(ticks)), ticks)
            if col.startswith("largest_violation") and all(y > 0 for y in ys if not math.isnan(y)) and ys:
                ax.set_yscale("log")
        for ax in list(axes.flat)[n:]:
            ax.axis("off")
        failed = len(rows) - len(ok)
        fig.suptitle(f"{os.path.basename(path)}: {len(ok)} runs" + (f" ({failed} failed, not shown)" if failed else ""))
        fig.tight_layout()
        png = os.path.splitext(path)[0] + "." + key.replace(":", "_") + ".png"
        fig.savefig(png, dpi=90)
        plt.close(fig)
        pngs.append(png)
    return pngs


# ---- command line

def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    sim = []
    if "--" in argv:
        cut = argv.index("--")
        argv, sim = argv[:cut], argv[cut + 1:]
    p = argparse.ArgumentParser(prog="sweep", description=__doc__.split("\n\n")[0],
                                epilog="KEY: arg:NAME (a xacro argument), set:JOINT, velocity:JOINT, effort:JOINT, "
                                       "drive:JOINT (simulate's options of those names). doc/sweeps.md")
    p.add_argument("model")
    p.add_argument("--vary", action="append", required=True, metavar="KEY=V1,V2,...|START:STOP:NUM")
    p.add_argument("--out", required=True, metavar="RESULTS.csv")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler (tcp://HOST:PORT); default: local cores")
    p.add_argument("--workers", type=int, help="local worker processes (default: every core)")
    p.add_argument("--resume", action="store_true", help="skip the runs already in --out")
    p.add_argument("--plot", action="store_true", help="PNG per varied key beside the CSV")
    a = p.parse_args(argv)
    try:
        settings, fixed = parse_simulate_options(sim)
        vary = [parse_vary(v) for v in a.vary]
        if not os.path.isfile(a.model):
            raise SweepError(f"{a.model}: no such file")
        _, failed = sweep(a.model, vary, a.out, settings, fixed, a.scheduler, a.workers, a.resume, a.plot)
    except SweepError as e:
        print(f"sweep: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\nsweep: interrupted; the rows written stay in {a.out} (--resume continues)", file=sys.stderr)
        return 130
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
