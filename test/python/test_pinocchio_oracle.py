"""Pinocchio as an oracle (doc/testing.md): every robot of example-robot-data runs for 2 s or is
refused for its stated reason (test/oracle/expected.txt), each tree's forward dynamics at random
states agrees with Pinocchio's to 1e-10 of the accelerations' size, and a closed loop's
accelerations and joint-space constraint forces agree with Pinocchio's constrained dynamics.

Pinocchio and example-robot-data live in the test-only environment .venv-oracle
(scripts/install-deps; MECHANISM_SIM_ORACLE_PYTHON names another): its NumPy 2 must not meet this
module, so test/oracle/pinocchio_oracle.py runs there and the two sides exchange JSON files.
"""
import json
import os
import re
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

import mechanism_sim

REPO = Path(__file__).resolve().parents[2]
ORACLE = REPO / "test" / "oracle" / "pinocchio_oracle.py"
ORACLE_PYTHON = os.environ.get("MECHANISM_SIM_ORACLE_PYTHON", str(REPO / ".venv-oracle" / "bin" / "python"))
TOLERANCE = 1e-10  # of max(|a|, 1): the accelerations' size (rad/s^2, m/s^2)
STATES = 3         # per tree


def run_oracle(*args):
    if not os.access(ORACLE_PYTHON, os.X_OK):
        raise RuntimeError(f"no oracle environment at {ORACLE_PYTHON}: run scripts/install-deps")
    r = subprocess.run([ORACLE_PYTHON, str(ORACLE), *map(str, args)], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"pinocchio_oracle.py {args[0]} failed:\n{r.stderr[-3000:]}")


def read_expected():
    """FILE | mechanism_sim, pinocchio or defect | words of its one line (test/oracle/expected.txt)."""
    out = {}
    for line in open(REPO / "test" / "oracle" / "expected.txt"):
        line = line.strip()
        if line and not line.startswith("#"):
            file, who, words = (x.strip() for x in line.split("|", 2))
            assert who in ("mechanism_sim", "pinocchio", "defect", "projected"), line
            out[file] = (who, words)
    return out


# The oracle runs once, at collection: its robots are the parameters.
WORK = tempfile.TemporaryDirectory(prefix="pinocchio_oracle_")
run_oracle("trees", WORK.name, STATES)
TREES = json.load(open(os.path.join(WORK.name, "trees.json")))
ROBOTS = TREES["robots"]
EXPECTED = read_expected()


def test_every_robot_of_example_robot_data_is_here():
    found = sorted(str(p.relative_to(TREES["robots_dir"])) for p in Path(TREES["robots_dir"]).rglob("*.urdf"))
    assert [r["file"] for r in ROBOTS] == found
    assert len(found) >= 60, found
    # every expected refusal names a file that exists
    assert sorted(set(EXPECTED) - set(found)) == []


def relative_error(ours, theirs):
    return float(np.max(np.abs(ours - theirs), initial=0.0) / max(np.linalg.norm(theirs), 1.0))


@pytest.mark.parametrize("robot", ROBOTS, ids=[r["file"] for r in ROBOTS])
def test_robot(robot):
    who, words = EXPECTED.get(robot["file"], (None, None))
    # ---- runs for 2 s, or is refused for its stated reason (or fails as a known defect does)
    try:
        m = mechanism_sim.load(robot["path"])
    except mechanism_sim.ModelError as e:
        assert who == "mechanism_sim", f"refused: {e}"
        assert words in str(e), f"refused for another reason than '{words}': {e}"
        return
    assert who != "mechanism_sim", f"expected to be refused ({words}), but it loads"
    try:
        m.advance(2.0, 1e-3)
    except mechanism_sim.SimulationError as e:
        assert who == "defect", f"fails: {e}"
        assert words in str(e), f"fails otherwise than the known defect '{words}': {e}"
        return
    assert who != "defect", f"the known defect '{words}' is gone: it runs (update test/oracle/expected.txt)"
    assert m.steps() == 2000
    assert np.all(np.isfinite(m.positions())) and np.all(np.isfinite(m.velocities()))
    # ---- a non-physical inertia runs as its nearest physical one, with a note, and
    # strict_inertia refuses it for the stated reason; not compared: Pinocchio takes the
    # file's own inertia, which no physical body has
    if who == "projected":
        assert any("the nearest physical inertia" in n for n in m.notes()), m.notes()
        with pytest.raises(mechanism_sim.ModelError, match=re.escape(words)):
            mechanism_sim.load(robot["path"], strict_inertia=True)
        return
    # ---- forward dynamics against Pinocchio's (or Pinocchio's stated reason not to)
    if "pin_error" in robot:
        assert who == "pinocchio", f"Pinocchio: {robot['pin_error']}"
        assert words in robot["pin_error"], robot["pin_error"]
        return
    assert who is None, f"expected '{words}' from {who}, but both run"
    worst = 0.0
    for state in robot["states"]:
        # each state assembled at load from the file's pose, as simulate --set and --velocity do
        d = mechanism_sim.load(robot["dynamics_file"], positions=state["positions"], velocities=state["velocities"])
        assert list(d.gravity()) == TREES["gravity"]
        names = d.dof_names()
        assert sorted(names) == sorted(robot["dofs"])
        index = [names.index(n) for n in robot["dofs"]]
        for n, q in state["positions"].items():
            assert d.positions()[names.index(n)] == pytest.approx(q, abs=1e-12), n
        theirs = np.array([state["accelerations"][n] for n in robot["dofs"]])
        ours = d.accelerations()[index]
        err = relative_error(ours, theirs)
        worst = max(worst, err)
        assert err <= TOLERANCE, (f"accelerations differ by {err:.3g} of their size at {state}: worst dof "
                                  f"{robot['dofs'][int(np.argmax(np.abs(ours - theirs)))]}")
    print(f"{robot['file']}: {len(robot['dofs'])} dofs, worst relative difference {worst:.2g}")


FLOATING = [r for r in ROBOTS if "floating_file" in r and r["file"] not in EXPECTED]


@pytest.fixture(scope="module")
def floating_answers():
    """mechanism_sim's state of every tree on a free base (state 0's joints, the base at rest at
    the origin before the rates are projected: its velocity is whatever the projection gives),
    and Pinocchio's accelerations at it, in one oracle run."""
    ours, requests = {}, []
    for robot in FLOATING:
        state = robot["states"][0]
        try:
            m = mechanism_sim.load(robot["floating_file"], positions=state["positions"], velocities=state["velocities"])
        except mechanism_sim.Error as e:
            ours[robot["file"]] = e
            continue
        names = m.dof_names()
        ours[robot["file"]] = (np.array([m.accelerations()[names.index(n)] for n in robot["dofs"]]), m.link_velocity(robot["root_link"]))
        requests.append({"urdf": robot["floating_file"], "positions": state["positions"], "velocities": state["velocities"],
                         "root_pose": m.link_pose(robot["root_link"]).tolist(),
                         "root_velocity": m.link_velocity(robot["root_link"]).tolist()})
    json.dump(requests, open(os.path.join(WORK.name, "floating_request.json"), "w"))
    run_oracle("floating", os.path.join(WORK.name, "floating_request.json"), os.path.join(WORK.name, "floating.json"))
    return ours, json.load(open(os.path.join(WORK.name, "floating.json")))


@pytest.mark.parametrize("robot", FLOATING, ids=[r["file"] for r in FLOATING])
def test_robot_on_a_free_base(robot, floating_answers):
    """The same tree on a `floating` joint: Pinocchio's free-flyer (its q's quaternion, its v in
    the root's axes) at mechanism_sim's base pose and velocity."""
    ours, theirs = floating_answers
    assert not isinstance(ours[robot["file"]], Exception), f"fails on a free base: {ours[robot['file']]}"
    a, root_velocity = ours[robot["file"]]
    assert np.linalg.norm(root_velocity) > 0.0  # the base moves: the projection gave it the joints' reaction
    expected = np.array([theirs[robot["floating_file"]][n] for n in robot["dofs"]])
    err = relative_error(a, expected)
    assert err <= TOLERANCE, f"accelerations differ by {err:.3g} of their size"
    print(f"{robot['file']} on a free base: worst relative difference {err:.2g}")


LOOPS = {
    # four revolute joints on skew axes closed by a ball joint: 3 independent equations
    "spatial_loop": dict(file=REPO / "test" / "oracle" / "spatial_loop.urdf", tree=["j1", "j2", "j3", "j4"],
                         held=("j1", 0.4, 1.5), child=("l4", [0.2, -0.1, 0.0]), parent=("base", [0.6, 0.15, -0.05]),
                         mu=0.0),
    # the bundled planar four-bar, closed by a revolute joint (3 of its equations dependent);
    # Pinocchio closes it by the point (its out-of-plane row dependent too)
    "four_bar": dict(file=REPO / "urdf" / "four_bar.urdf", tree=["crank_joint", "coupler_joint", "rocker_joint"],
                     held=("crank_joint", 0.7, 4.0), child=("rocker", [0.066925664, 0.0, -0.292439661]),
                     parent=("base", [0.4, 0.0, 0.0]), mu=1e-6),
}


@pytest.mark.parametrize("name", sorted(LOOPS))
def test_closed_loop_against_constraint_dynamics(name, tmp_path):
    """A closed loop at one state: the accelerations, and the joint-space constraint forces
    (what the closure's reaction on its child link does to the tree's dofs, J^T [f; t]),
    against Pinocchio's constraintDynamics with one CONTACT_3D constraint between the same
    two points."""
    c = LOOPS[name]
    dof, q0, v0 = c["held"]
    m = mechanism_sim.load(str(c["file"]), positions={dof: q0}, velocities={dof: v0})
    m.advance(2.0, 1e-3)  # it runs
    assert m.violation()["relative_position"] < 1e-8
    m.set_state(positions={dof: q0}, velocities={dof: v0})
    names = m.dof_names()
    tree = c["tree"]
    q = {n: float(m.positions()[names.index(n)]) for n in tree}
    v = {n: float(m.velocities()[names.index(n)]) for n in tree}
    assert q[dof] == pytest.approx(q0, abs=1e-12) and q[tree[1]] != 0.0  # the loop moved the others
    a = {n: float(m.accelerations()[names.index(n)]) for n in tree}
    r = m.reactions()
    k = r["joints"].index("loop")
    # in the closure's frame on its child (child_origin, no rotation: the link's axes), about its origin
    R = m.link_pose(c["child"][0])[:3, :3]
    request = {"urdf": str(c["file"]), "positions": q, "velocities": v, "mu": c["mu"],
               "child_link": c["child"][0], "child_point": c["child"][1],
               "parent_link": c["parent"][0], "parent_point": c["parent"][1],
               "reaction_force": list(R @ r["force"][k]), "reaction_torque": list(R @ r["torque"][k])}
    json.dump(request, open(tmp_path / "request.json", "w"))
    run_oracle("loop", tmp_path / "request.json", tmp_path / "answer.json")
    answer = json.load(open(tmp_path / "answer.json"))
    theirs = np.array([answer["accelerations"][n] for n in tree])
    ours = np.array([a[n] for n in tree])
    assert relative_error(ours, theirs) <= TOLERANCE, (ours, theirs)
    # Pinocchio's own two readings of its constraint forces agree: M q_ddot + b - tau = J^T lambda
    tau_c = np.array([answer["constraint_forces"][n] for n in tree])
    jt_lambda = np.array([answer["jt_lambda"][n] for n in tree])
    assert relative_error(jt_lambda, tau_c) <= TOLERANCE, (jt_lambda, tau_c)
    ours_c = np.array([answer["ours_constraint_forces"][n] for n in tree])
    assert np.linalg.norm(tau_c) > 0.1  # the loop carries load at this state
    print(f"{name}: accelerations {ours} (relative difference {relative_error(ours, theirs):.2g}), "
          f"joint-space constraint forces {ours_c} (relative difference {relative_error(ours_c, tau_c):.2g}), "
          f"{answer['iterations']} proximal iterations")
    assert relative_error(ours_c, tau_c) <= TOLERANCE, (ours_c, tau_c)
