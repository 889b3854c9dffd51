#!/usr/bin/python3
"""Work-precision picture (issue 20, item 6): error against CPU time per simulated second.

usage: bench/work_precision.py [-o FILE.png] [--harness PATH] [--peers RUN.txt] [--table FILE.md]
                               [--steps 4e-3,2e-3,1e-3,5e-4] [--quick]

For the pendulum (position error against its exact motion), the 50-link chain (tip error
against the same formulation at dt 1e-4, bench_harness's metric) and the ten-loop four-bar
(crank tip against its exact motion), runs bench_harness at each step for every
integrator (rk4, rk3, rk2) and formulation (absolute and joint; the four-bar's loops in
joint coordinates since its branch passages, 2026-11-26) and draws one panel a mechanism, log-log: CPU seconds per simulated
second (us/step CPU / dt) across, error up. With --peers, a run file of
../shared/peers/run_all.sh (bench/peer_runs/*.txt), MuJoCo's Euler and RK4 rows of the same
mechanisms are drawn as well, marked with the run they come from (a different run: compare
shapes and orders of magnitude, not ratios to a percent). --table writes the points as a
Markdown table. Errors: one line on stderr, exit status 2.
"""
import argparse
import os
import re
import subprocess
import sys

CASES = [  # (title, harness case, N, metric label)
    ("pendulum", "pendulum", 1, "position error vs exact [m]"),
    ("chain, 50 links", "chain", 50, "tip error vs dt 1e-4 [m]"),
    ("four-bar, 10 loops", "fourbar", 10, "crank tip error vs exact [m]"),
]
METHODS = ["rk4", "rk3", "rk2"]
FORMULATIONS = ["absolute", "joint"]


def fail(msg):
    print("work_precision: " + msg, file=sys.stderr)
    sys.exit(2)


def harness_row(harness, case, n, dt, method, formulation, quick):
    """(us/step CPU, error) of one harness run, or None when the formulation refuses it."""
    cmd = [harness, "--cases", case, "--dt", repr(dt), "--integrator", method, "--formulation", formulation,
           "--repeats", "1", "--budget", "2"]
    if case == "chain":
        cmd += ["--chain-n", str(n)]
    if case == "fourbar":
        cmd += ["--fourbar-n", str(n)]
    if quick:
        cmd.append("--quick")
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        if "joint formulation cannot run" in run.stdout + run.stderr:
            return None
        fail("%s: %s" % (" ".join(cmd), (run.stderr or run.stdout).strip().splitlines()[-1:]))
    for line in run.stdout.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) > 10 and cells[0] == case and cells[1] == str(n):
            try:
                return float(cells[6]), float(cells[8])
            except ValueError:
                return None
    return None


def peer_rows(path):
    """MuJoCo rows of a peers run file: {(case, n, integrator): [(dt, us/step, error)]}."""
    rows = {}
    with open(path) as f:
        for line in f:
            cells = line.split()
            if len(cells) < 12 or cells[1] not in ("mujoco", "mujoco-stiffeq") or not re.match(r"^\d+$", cells[0]):
                continue
            case, n, dt = cells[2], int(cells[3]), float(cells[4])
            integ = ("stiff eq. " if cells[1] == "mujoco-stiffeq" else "") + cells[5]
            us = cells[7]
            err = cells[-3]
            try:
                rows.setdefault((case, n, integ), []).append((dt, float(us), float(err)))
            except ValueError:
                continue
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ws = os.environ.get("MECHANISM_SIM_WS", os.path.join(here, ".catkin_ws"))
    ap.add_argument("-o", "--output", default="work_precision.png")
    ap.add_argument("--harness", default=os.path.join(ws, "devel/lib/mechanism_sim/bench_harness"))
    ap.add_argument("--peers")
    ap.add_argument("--table")
    ap.add_argument("--steps", default="4e-3,2e-3,1e-3,5e-4")
    ap.add_argument("--quick", action="store_true", help="the harness's short horizons (a smoke test)")
    a = ap.parse_args()
    if not os.access(a.harness, os.X_OK):
        fail("no bench_harness at %s (scripts/build first)" % a.harness)
    try:
        steps = [float(x) for x in a.steps.split(",")]
    except ValueError:
        fail("--steps: comma-separated step sizes in seconds")
    peers = peer_rows(a.peers) if a.peers else {}

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(CASES), figsize=(5.2 * len(CASES), 4.6))
    table = ["| mechanism | formulation | integrator | dt [s] | CPU s / simulated s | error |", "|---|---|---|---|---|---|"]
    colours = {"rk4": "C0", "rk3": "C1", "rk2": "C2"}
    for ax, (title, case, n, metric) in zip(axes, CASES):
        for formulation in FORMULATIONS:
            for method in METHODS:
                pts = []
                for dt in steps:
                    r = harness_row(a.harness, case, n, dt, method, formulation, a.quick)
                    if r is None:
                        continue
                    us, err = r
                    pts.append((us * 1e-6 / dt, err))
                    table.append("| %s | %s | %s | %g | %.3g | %.3g |" % (title, formulation, method, dt, us * 1e-6 / dt, err))
                if pts:
                    ax.loglog([p[0] for p in pts], [max(p[1], 1e-16) for p in pts],
                              ("-" if formulation == "joint" else "--"), marker="o" if formulation == "joint" else "s",
                              color=colours[method], label="%s %s" % (method, formulation))
        for integ, style in (("Euler", "v"), ("RK4", "^"), ("stiff eq. Euler", "<"), ("stiff eq. RK4", ">")):
            for dt, us, err in peers.get((case, n, integ), []):
                ax.loglog([us * 1e-6 / dt], [err], style, color="k", markersize=8,
                          label="MuJoCo %s (peer run)" % integ)
                table.append("| %s | MuJoCo (peer run) | %s | %g | %.3g | %.3g |" % (title, integ, dt, us * 1e-6 / dt, err))
        ax.set_title(title)
        ax.set_xlabel("CPU seconds per simulated second")
        ax.set_ylabel(metric)
        ax.grid(True, which="both", alpha=0.3)
        handles, labels = ax.get_legend_handles_labels()
        seen = {}
        for h, l in zip(handles, labels):
            seen.setdefault(l, h)
        ax.legend(seen.values(), seen.keys(), fontsize=7)
    fig.tight_layout()
    fig.savefig(a.output, dpi=110)
    if a.table:
        with open(a.table, "w") as f:
            f.write("\n".join(table) + "\n")
    print("work_precision: wrote %s (%d points)" % (a.output, len(table) - 2))


if __name__ == "__main__":
    main()
