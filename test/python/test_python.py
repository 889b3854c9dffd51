"""The Python module (doc/python.md): physics with known answers, snapshot/restore bit for
bit, agreement with the simulate CLI on the same run, the library's errors as exceptions.

Run by scripts/test (cmake/python.cmake: pytest under the devel environment, its JUnit XML
counted with the gtests'). MECHANISM_SIM_SIMULATE names the simulate binary.
"""
import csv
import json
import math
import os
import re
import subprocess

import numpy as np
import pytest

import mechanism_sim

SOURCE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SIMULATE = os.environ.get("MECHANISM_SIM_SIMULATE", "")
PENDULUM = os.path.join(SOURCE, "test/urdf/pendulum_point_mass.urdf")
FOUR_BAR = os.path.join(SOURCE, "urdf/four_bar.urdf")
FOUR_BAR_DRIVEN = os.path.join(SOURCE, "urdf/four_bar_driven.urdf")
XACRO = os.path.join(SOURCE, "test/xacro/robot.urdf.xacro")
PLANETARY = os.path.join(SOURCE, "urdf/planetary_gear.urdf")


def simulate(*args, check=True):
    assert SIMULATE and os.access(SIMULATE, os.X_OK), "MECHANISM_SIM_SIMULATE must name the simulate binary"
    run = subprocess.run([SIMULATE, *args], capture_output=True, text=True, timeout=120)
    if check:
        assert run.returncode == 0, run.stderr
    return run


def period_of_pendulum(theta0, length, g):
    """Exact period of a simple pendulum of amplitude theta0: 4 sqrt(L/g) K(sin(theta0/2)),
    K by the arithmetic-geometric mean."""
    a, b = 1.0, math.cos(theta0 / 2)
    for _ in range(12):
        a, b = (a + b) / 2, math.sqrt(a * b)
    return 4 * math.sqrt(length / g) * math.pi / (2 * a)


# ---- physics with known answers

def test_pendulum_released_horizontally_has_the_elliptic_period_and_keeps_its_energy():
    # 1 kg point mass on a 1 m massless arm, released at rest 90 degrees from the bottom
    m = mechanism_sim.load(PENDULUM)
    g = -m.gravity()[2]
    assert g == pytest.approx(9.81)
    period = period_of_pendulum(math.pi / 2, 1.0, g)
    e0 = m.energies()["total"]
    assert e0 == pytest.approx(19.62)  # m g z with the bob at z = 2 m
    h, turns, worst_drift = 1e-3, [], 0.0
    v_prev, t_prev = m.velocities()[0], m.time()
    while len(turns) < 4:
        m.step(h)
        v, t = m.velocities()[0], m.time()
        worst_drift = max(worst_drift, abs(m.energies()["total"] - e0))
        if v_prev != 0 and v * v_prev < 0:  # a turning point, by linear interpolation of the rate
            turns.append(t_prev + h * v_prev / (v_prev - v))
        v_prev, t_prev = v, t
    # turning points every half period (RK4 at 1 ms: 2e-12 s measured)
    for k, t in enumerate(turns, start=1):
        assert t == pytest.approx(k * period / 2, abs=1e-8), (k, t, period)
    assert worst_drift < 1e-9 * e0  # 5e-11 J measured
    assert m.largest_violation()["position"] < 1e-12


def test_energies_are_kinetic_plus_potential():
    m = mechanism_sim.load(FOUR_BAR)
    m.advance(0.2, 1e-3)
    e = m.energies()
    assert e["total"] == e["kinetic"] + e["potential"]
    assert e["kinetic"] > 0


# ---- snapshot and restore

def test_restore_continues_bit_for_bit():
    m = mechanism_sim.load(FOUR_BAR_DRIVEN, efforts={"rocker_joint": 0.2})
    m.advance(0.3, 1e-3)
    snap = m.snapshot()
    assert snap.time == m.time() and snap.steps == 300

    def run():
        m.set_efforts({"coupler_joint": -0.1})
        m.advance(0.25, 1e-3)
        r = m.reactions()
        return (m.time(), m.positions(), m.velocities(), m.efforts(), r["force"], r["torque"],
                m.largest_violation(), m.drive_peaks(), m.commanded_efforts(), m.steps())

    first = run()
    m.restore(snap)
    assert m.time() == snap.time
    np.testing.assert_array_equal(m.commanded_efforts(), [0, 0, 0.2, 0])  # the effort set after is undone
    second = run()
    for a, b in zip(first, second):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)
        else:
            assert a == b


def test_reset_goes_back_to_the_assembled_start():
    m = mechanism_sim.load(FOUR_BAR)
    p0, v0 = m.positions(), m.velocities()
    m.set_efforts([1.0, 0, 0, 0])
    m.advance(0.1, 1e-3)
    m.reset()
    assert m.time() == 0 and m.steps() == 0
    np.testing.assert_array_equal(m.positions(), p0)
    np.testing.assert_array_equal(m.velocities(), v0)
    np.testing.assert_array_equal(m.commanded_efforts(), np.zeros(4))


def test_restore_of_another_models_snapshot_is_an_error():
    a, b = mechanism_sim.load(FOUR_BAR), mechanism_sim.load(PENDULUM)
    with pytest.raises(ValueError, match="another"):
        b.restore(a.snapshot())


# ---- the same run as simulate

def csv_values(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], rows[-1]


RUNS = [
    # (file, simulate options, load() keyword arguments)
    (FOUR_BAR, ["--set", "crank_joint=0.3", "--velocity", "crank_joint=2", "--effort", "rocker_joint=0.4"],
     dict(positions={"crank_joint": 0.3}, velocities={"crank_joint": 2}, efforts={"rocker_joint": 0.4})),
    (FOUR_BAR_DRIVEN, ["--drive", "crank_joint=5", "--integrator", "rk3"],
     dict(drives={"crank_joint": 5}, integrator="rk3")),
    (XACRO, ["length:=0.45", "tip_mass:=0.8"], dict(args={"length": 0.45, "tip_mass": "0.8"})),
    (PENDULUM, ["--formulation", "joint"], dict(formulation="joint")),
    (PLANETARY, [], {}),
]


def csv_row(m):
    """The model's state now as simulate --reactions' CSV columns."""
    mine = {"time": m.time()}
    for name, p, v, e in zip(m.dof_names(), m.positions(), m.velocities(), m.efforts()):
        mine[name + ".position"], mine[name + ".velocity"], mine[name + ".effort"] = p, v, e
    mine["constraint.position"] = m.violation()["position"]
    mine["constraint.velocity"] = m.violation()["velocity"]
    r = m.reactions()
    for j, joint in enumerate(r["joints"]):
        for c, comp in enumerate("xyz"):
            mine[f"{joint}.f{comp}"], mine[f"{joint}.t{comp}"] = r["force"][j, c], r["torque"][j, c]
    assert r["couplings"] == m.reaction_couplings() and len(r["coupling"]) == len(r["couplings"])
    for name, lam in zip(r["couplings"], r["coupling"]):
        mine[f"{name}.reaction"] = lam
    return mine


@pytest.mark.parametrize("path,options,kwargs", RUNS,
                         ids=["set-velocity-effort", "drive-rk3", "xacro-args", "joint-formulation", "couplings"])
def test_a_run_prints_what_simulate_prints(tmp_path, path, options, kwargs):
    out = tmp_path / "run.csv"
    simulate(path, *options, "--duration", "0.4", "--dt", "1e-3", "--reactions", "--csv", str(out))
    header, last = csv_values(out)

    m = mechanism_sim.load(path, **kwargs)
    m.advance(0.4, 1e-3)
    mine = csv_row(m)
    assert sorted(mine) == sorted(header)
    # the CSV's 12 significant digits, character for character: the same steps, the same bits
    for name, text in zip(header, last):
        assert "%.12g" % mine[name] == text, name

    # the summary and notes, but for the wall time, of a run without reactions (their
    # least-norm solves count in the solver's statistics)
    run = simulate(path, *options, "--duration", "0.4", "--dt", "1e-3", "--csv", str(out))
    m = mechanism_sim.load(path, **kwargs)
    m.advance(0.4, 1e-3)

    def steady(text):
        return re.sub(r"in [0-9.]+ s wall \(real-time factor [0-9.inf]+\)", "in W s wall", text)
    assert steady(m.summary()) == steady(run.stderr)


def test_the_planetary_trains_willis_multiplier_carries_the_carriers_load():
    # ring held, sun at 10 rad/s: the carrier at 2.5 rad/s against 0.05 N m s/rad, a load of
    # 0.125 N m it receives as -c_carrier lambda = 96 lambda through Willis' equation (the
    # run's CSV columns: test_a_run_prints_what_simulate_prints[couplings])
    m = mechanism_sim.load(PLANETARY)
    m.advance(0.4, 1e-3)
    r = m.reactions()
    assert r["couplings"] == ["willis", "sun_planet0", "sun_planet1", "sun_planet2"]
    assert r["coupling"][0] == pytest.approx(0.125 / 96, rel=1e-6)


# A pinion (20 teeth, 1e-3 kg m^2) in mesh with a wheel (40 teeth, 4e-3 kg m^2), both about
# vertical axes: 20 q_pinion + 40 q_wheel = 0.
GEAR_PAIR = """<?xml version="1.0"?>
<robot name="gear_pair" xmlns:mechanism_sim="https://mechanism-sim.github.io/urdf-extension">
  <link name="base"/>
  <link name="pinion">
    <inertial><mass value="0.1"/><inertia ixx="5e-4" iyy="5e-4" izz="1e-3" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="wheel">
    <inertial><mass value="0.4"/><inertia ixx="2e-3" iyy="2e-3" izz="4e-3" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="pinion_joint" type="continuous">
    <parent link="base"/><child link="pinion"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
  </joint>
  <joint name="wheel_joint" type="continuous">
    <parent link="base"/><child link="wheel"/><origin xyz="0.06 0 0.1"/><axis xyz="0 0 1"/>
  </joint>
  <mechanism_sim:coupling name="mesh">
    <joint name="pinion_joint" coefficient="20"/>
    <joint name="wheel_joint" coefficient="40"/>
  </mechanism_sim:coupling>
</robot>
"""


@pytest.mark.parametrize("formulation", ["absolute", "joint"])
def test_a_gear_pairs_multiplier_is_the_mesh_torque_that_accelerates_the_wheel(formulation):
    # 0.02 N m on the pinion: a = 0.02 / (I_p + I_w (20/40)^2) = 10 rad/s^2 on the pinion,
    # -5 on the wheel; the wheel receives -40 lambda = I_w (-5) = -0.02 N m, so
    # lambda = 5e-4 N m per tooth, and the pinion -20 lambda = -0.01 N m (its 0.02 less I_p a)
    m = mechanism_sim.load_string(GEAR_PAIR, efforts={"pinion_joint": 0.02}, formulation=formulation)
    m.advance(0.1, 1e-3)
    r = m.reactions()
    assert r["couplings"] == ["mesh"] == m.reaction_couplings()
    assert r["coupling"][0] == pytest.approx(5e-4, rel=1e-9)
    assert m.accelerations() == pytest.approx([10, -5], rel=1e-9)
    assert m.velocities() == pytest.approx([1, -0.5], rel=1e-9)


GEARED = os.path.join(SOURCE, "test/urdf/geared_pendulum.urdf.xacro")


def test_actuators_states_and_sizing_have_the_known_answers(tmp_path):
    # The geared pendulum (m g L = 9.81 N m) turned one turn a second by a velocity drive
    # behind N:1: the motor turns at 2 pi N, gives -m g L cos(q) / N (the drive holds the
    # rate against gravity), peaks at 9.81 / N and has the RMS 9.81 / (N sqrt 2) over the
    # turn. The motor (0.3 N m peak, 0.15 N m continuous, 400 rad/s) is enough at N = 50
    # (RMS 0.1387), not at N = 40 (RMS 0.1734 above its continuous rating).
    mgl = 2 * 9.81 * 0.5
    for n, within in ((50, True), (40, False)):
        m = mechanism_sim.load(GEARED, args={"reduction": n, "drive": "true"})
        assert m.actuator_names() == ["motor"]
        m.advance(0.3, 1e-3)
        q = m.positions()[0]
        a = m.actuator_states()
        assert a["names"] == ["motor"]
        assert a["position"][0] == pytest.approx(n * q, rel=1e-12)
        assert a["velocity"][0] == pytest.approx(2 * math.pi * n, rel=1e-12)
        assert a["torque"][0] == pytest.approx(-mgl * math.cos(q) / n, abs=1e-9 * mgl / n)
        assert a["power"][0] == a["torque"][0] * a["velocity"][0]
        assert math.isnan(a["current"][0])  # no torque_constant
        m.advance(0.7, 1e-3)  # one full turn in all
        s = m.actuator_sizing()["motor"]
        assert s["peak_torque"] == pytest.approx(mgl / n, rel=1e-9)
        assert s["rms_torque"] == pytest.approx(mgl / (n * math.sqrt(2)), rel=1e-9)
        assert s["peak_speed"] == pytest.approx(2 * math.pi * n, rel=1e-12)
        assert s["positive_work"] + s["negative_work"] == pytest.approx(0.0, abs=1e-9 * s["positive_work"])
        assert s["within_rating"] is within
        assert [e["rating"] for e in s["exceeded"]] == ([] if within else ["rated_torque"])
        assert "peak_current" not in s
    # a reset restarts the record; a snapshot restores it
    snap = m.snapshot()
    m.reset()
    assert m.actuator_sizing()["motor"]["peak_speed"] == pytest.approx(2 * math.pi * 40, rel=1e-12)
    assert m.actuator_sizing()["motor"]["rms_torque"] == pytest.approx(mgl / 40, rel=1e-12)  # the start alone
    m.restore(snap)
    assert m.actuator_sizing()["motor"]["within_rating"] is False
    # without a rating to size against there is no flag
    bare = mechanism_sim.load_string(open(os.path.join(SOURCE, "urdf/harmonic_drive_joint.urdf")).read().replace(
        'rated_torque="0.3" peak_torque="1.2"\n                          stall_torque="2.0" no_load_speed="650" max_speed="600"',
        ""))
    assert bare.actuator_sizing()["shoulder_motor"]["within_rating"] is None

    # what simulate writes and prints for the same run: the motor columns, the sizing line
    out = tmp_path / "geared.csv"
    run = simulate(GEARED, "reduction:=40", "drive:=true", "--duration", "1", "--dt", "1e-3", "--csv", str(out))
    header, last = csv_values(out)
    row = dict(zip(header, last))
    for column, key in (("position", "position"), ("velocity", "velocity"), ("torque", "torque"), ("power", "power")):
        assert "%.12g" % m.actuator_states()[key][0] == row["motor.motor_" + column], column
    m = mechanism_sim.load(GEARED, args={"reduction": 40, "drive": "true"})
    m.advance(1.0, 1e-3)

    def steady(text):
        return re.sub(r"in [0-9.]+ s wall \(real-time factor [0-9.inf]+\)", "in W s wall", text)
    assert steady(m.summary()) == steady(run.stderr)
    assert m.actuator_sizing()["motor"]["describe"] in m.summary()


def test_actuator_limits_hold_the_winch_to_its_motors_line(tmp_path):
    # urdf/winch.urdf (doc/actuators.md, "Saturating mode"): 10 kg on a drum of radius 0.05 m
    # behind 20:1, the motor's line 0.5 N m / 400 rad/s; the drive asks 15 rad/s. Saturating,
    # the drum settles where 0.5 (1 - 20 w / 400) = m g r / 20; the sizing record and the
    # sweep's column carry the lag; switched off, the drive is followed again.
    winch = os.path.join(SOURCE, "urdf/winch.urdf")
    settled = 400 / 20 * (1 - 10 * 9.81 * 0.05 / 20 / 0.5)
    m = mechanism_sim.load(winch, actuator_limits=True)
    m.advance(3.0, 1e-3)
    drum = m.dof_names().index("drum_joint")
    assert m.velocities()[drum] == pytest.approx(settled, rel=1e-9)
    a = m.actuator_states()
    assert a["saturated"][0] == 1.0
    assert a["torque"][0] == pytest.approx(10 * 9.81 * 0.05 / 20, rel=1e-9)
    s = m.actuator_sizing()["winch_motor"]
    assert s["bound_intervals"] == 1 and s["largest_lag_ended"] == -1.0
    assert s["largest_lag"] == pytest.approx(a["lag"][0], rel=1e-12)
    assert s["within_rating"] is True
    assert "at its bounds 1 time" in s["describe"] and s["describe"] in m.summary()
    # simulate's line for the same run
    run = simulate(winch, "--actuator-limits", "--duration", "3", "--dt", "1e-3", "--output-every", "3000")
    assert s["describe"] in run.stderr
    # off again: the drive takes the drum back onto its profile at once (sizing)
    assert m.set_actuator_limits(False) == ""
    m.advance(0.01, 1e-3)
    assert m.velocities()[drum] == pytest.approx(15.0, rel=1e-9)
    sized = mechanism_sim.load(winch)
    assert "largest_lag" not in sized.actuator_sizing()["winch_motor"]


HARMONIC = os.path.join(SOURCE, "urdf/harmonic_drive_joint.urdf")
ACTUATOR_PLOT = os.path.join(SOURCE, "scripts/actuator_plot")


def test_actuator_plot_draws_the_run_against_the_ratings(tmp_path):
    # simulate --actuator-plot keeps the data beside the picture: the harmonic-drive example's
    # motor at every step, theta_dot = N A w cos(w t) (N = 100, A = 0.8, w = 2 pi), and its
    # ratings; scripts/actuator_plot draws the line through (0, 2 N m) and (650 rad/s, 0)
    png = tmp_path / "motor.png"
    simulate(HARMONIC, "--duration", "1", "--quiet", "--actuator-plot", str(png))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20000
    with open(str(png) + ".json") as f:
        data = json.load(f)
    [a] = data["actuators"]
    assert a["name"] == "shoulder_motor"
    assert a["ratings"] == {"rated_torque": 0.3, "peak_torque": 1.2, "stall_torque": 2.0, "no_load_speed": 650.0,
                            "max_speed": 600.0}
    assert len(a["points"]) == 1001  # t = 0 and every step
    w = 2 * math.pi
    for t, speed, torque in a["points"]:
        assert speed == pytest.approx(100 * 0.8 * w * math.cos(w * t), abs=1e-9 * 100 * 0.8 * w)
    m = mechanism_sim.load(HARMONIC)
    m.advance(1.0, 1e-3)
    s = m.actuator_sizing()["shoulder_motor"]
    assert a["points"][-1][2] == m.actuator_states()["torque"][0]
    assert a["rms_torque"] == s["rms_torque"] and a["within_rating"] is True and a["exceeded"] == []
    run = subprocess.run([ACTUATOR_PLOT, str(png) + ".json", "-o", str(tmp_path / "again.png"), "--summary"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    [drawn] = json.loads(run.stdout)["actuators"]
    assert drawn["points"] == 1001 and drawn["verdict"] == "within rating"
    assert drawn["lines"]["envelope"] == {"upper": [[0.0, 2.0], [650.0, 0.0]], "lower": [[-650.0, 0.0], [0.0, -2.0]]}
    assert drawn["lines"]["peak_torque"] == 1.2 and drawn["lines"]["rated_torque"] == 0.3
    assert drawn["lines"]["max_speed"] == 600 and drawn["lines"]["rms_torque"] == s["rms_torque"]
    assert drawn["speed"] == pytest.approx([-100 * 0.8 * w, 100 * 0.8 * w], rel=1e-9)

    # twice as fast: the ratings it exceeds name the panel
    fast = tmp_path / "fast.urdf"
    fast.write_text(open(HARMONIC).read().replace('frequency="1"', 'frequency="2"'))
    simulate(str(fast), "--duration", "1", "--quiet", "--actuator-plot", str(tmp_path / "fast.png"))
    run = subprocess.run([ACTUATOR_PLOT, str(tmp_path / "fast.png.json"), "--summary"], capture_output=True, text=True,
                         timeout=120)
    assert json.loads(run.stdout)["actuators"][0]["verdict"] == "EXCEEDS max_speed, torque-speed line, rated_torque"

    # a model without actuators has nothing to plot; a file that is not the data is one line
    run = simulate(PENDULUM, "--duration", "0.1", "--actuator-plot", str(tmp_path / "none.png"), check=False)
    assert run.returncode == 2
    assert run.stderr == f"simulate: {PENDULUM}: --actuator-plot: the model has no actuators (no simulated <transmission>)\n"
    (tmp_path / "bad.json").write_text("{}")
    run = subprocess.run([ACTUATOR_PLOT, str(tmp_path / "bad.json")], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and run.stderr == f"actuator_plot: {tmp_path / 'bad.json'}: no actuators in it\n"


def test_set_state_holds_what_load_holds():
    # the file starts the crank at 4 rad/s: set_state with the same targets as load() lands
    # on the same state (within the assembly's tolerance: it starts from another pose)
    loaded = mechanism_sim.load(FOUR_BAR, positions={"crank_joint": 0.5})
    m = mechanism_sim.load(FOUR_BAR)
    m.set_state(positions={"crank_joint": 0.5}, velocities={"crank_joint": 4.0})
    np.testing.assert_allclose(m.positions(), loaded.positions(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(m.velocities(), loaded.velocities(), rtol=0, atol=1e-8)
    assert m.violation()["relative_position"] < 1e-12
    m.set_velocities({"crank_joint": -1.0})
    assert m.velocities()[0] == pytest.approx(-1.0, abs=1e-9)
    np.testing.assert_allclose(m.positions(), loaded.positions(), rtol=0, atol=1e-9)


# ---- errors

def test_a_file_that_cannot_be_loaded_raises_load_error_with_the_library_message():
    bad = os.path.join(SOURCE, "test/invalid/negative_mass.urdf")
    run = simulate(bad, "--duration", "0", check=False)
    assert run.returncode == 1
    with pytest.raises(mechanism_sim.LoadError) as e:
        mechanism_sim.load(bad)
    assert isinstance(e.value, ValueError) and isinstance(e.value, mechanism_sim.Error)
    assert "simulate: " + str(e.value) + "\n" == run.stderr
    # a call the library does not take (core/errors.h UsageError) is a ValueError too
    assert issubclass(mechanism_sim.UsageError, ValueError) and issubclass(mechanism_sim.UsageError, mechanism_sim.Error)
    with pytest.raises(mechanism_sim.LoadError, match="cannot open the file"):
        mechanism_sim.load("/nonexistent/model.urdf")
    with pytest.raises(mechanism_sim.LoadError, match="not a .xacro file"):
        mechanism_sim.load(FOUR_BAR, args={"length": 1})
    with pytest.raises(mechanism_sim.LoadError, match="names no joint degree of freedom 'nope'"):
        mechanism_sim.load(FOUR_BAR, efforts={"nope": 1})
    with pytest.raises(mechanism_sim.LoadError, match="<string>"):
        mechanism_sim.load_string("<robot name='x'>")


def locked_four_bar(tmp_path):
    # the four-bar's rocker driven at 3 rad/s: it cannot turn past its dead point
    text = open(FOUR_BAR_DRIVEN).read().replace('drive joint="crank_joint"', 'drive joint="rocker_joint"')
    path = tmp_path / "locked_four_bar.urdf"
    path.write_text(text)
    return str(path)


def test_a_step_that_fails_raises_step_failure_and_leaves_the_last_state(tmp_path):
    path = locked_four_bar(tmp_path)
    run = simulate(path, "--duration", "1", "--quiet", check=False)
    assert run.returncode == 1
    m = mechanism_sim.load(path)
    with pytest.raises(mechanism_sim.StepFailure) as e:
        m.advance(1.0, 1e-3)
    assert isinstance(e.value, RuntimeError) and isinstance(e.value, mechanism_sim.SimulationError)
    assert "simulate: " + str(e.value) in run.stderr
    # (absolute coordinates: "the velocities cannot be brought onto the constraints"; joint
    # coordinates, the default: "the step left the constraints on the joint coordinates")
    assert "the constraints" in str(e.value)
    t = m.time()
    assert 0 < t < 1 and m.steps() == round(t / 1e-3)
    assert np.isfinite(m.positions()).all()
    assert m.violation()["relative_position"] < 1e-6  # the last accepted step


def test_bad_arguments_raise_value_errors():
    m = mechanism_sim.load(FOUR_BAR)
    for bad in (0.0, -1e-3, math.nan, math.inf):
        with pytest.raises(ValueError):
            m.step(bad)
    with pytest.raises(ValueError):
        m.advance(-1, 1e-3)
    with pytest.raises(ValueError, match="names no joint degree of freedom 'nope'"):
        m.set_efforts({"nope": 1.0})
    with pytest.raises(ValueError, match="not finite"):
        m.set_efforts({"crank_joint": math.nan})
    with pytest.raises(ValueError, match="one per dof"):
        m.set_efforts([1.0, 2.0])
    with pytest.raises(ValueError, match="is not driven"):
        m.command_drive("crank_joint", 1.0)
    with pytest.raises(ValueError, match="no link"):
        m.link_pose("nope")
    with pytest.raises(TypeError):
        m.set_positions(3.0)
    assert m.time() == 0


def test_a_pose_that_does_not_close_raises_model_error_and_changes_nothing():
    m = mechanism_sim.load(FOUR_BAR)
    m.advance(0.05, 1e-3)
    p, v = m.positions(), m.velocities()
    with pytest.raises(mechanism_sim.ModelError, match="four_bar.urdf: the mechanism does not close"):
        m.set_positions({"crank_joint": 0.5, "rocker_joint": 2.0})
    np.testing.assert_array_equal(m.positions(), p)
    np.testing.assert_array_equal(m.velocities(), v)
    driven = mechanism_sim.load(FOUR_BAR_DRIVEN)
    with pytest.raises(ValueError, match="driven"):
        driven.set_velocities({"crank_joint": 1.0})


def test_the_model_answers_its_description():
    m = mechanism_sim.load(FOUR_BAR_DRIVEN)
    assert m.name == "four_bar_driven" and m.source == FOUR_BAR_DRIVEN
    assert m.dof_names() == ["crank_joint", "coupler_joint", "rocker_joint", "loop"]
    assert m.driven_dofs() == ["crank_joint"]
    assert m.reaction_joints() == m.reactions()["joints"]
    assert m.num_equations() == 21  # 20 and the drive's
    assert "'loop' 3" in m.dependencies()
    assert m.notes() == []
    stats = m.solver_stats()
    assert stats["shortfalls"] == 0 and "met its tolerance" in stats["describe"]
    m.advance(0.1, 1e-3)
    assert m.velocities()[0] == pytest.approx(3.0)  # the file's drive
    assert set(m.drive_peaks()) == {"crank_joint"}
    T = m.link_pose("crank")
    assert T.shape == (4, 4)
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    m.command_drive("crank_joint", 0.0)
    m.advance(0.01, 1e-3)
    assert m.velocities()[0] == pytest.approx(0.0, abs=1e-12)


def test_the_formulation_is_reported():
    assert mechanism_sim.load(PENDULUM, formulation="joint").formulation() == "joint"
    assert mechanism_sim.load(PENDULUM).formulation() == "joint"  # the default: auto
    assert mechanism_sim.load(PENDULUM, formulation="absolute").formulation() == "absolute"
    m = mechanism_sim.load(FOUR_BAR, formulation="auto")
    assert m.formulation() == "joint" and "closes a loop" in m.formulation_reason()
    assert mechanism_sim.load(FOUR_BAR, formulation="joint").formulation() == "joint"


@pytest.mark.parametrize("formulation", ["joint", "absolute"])
def test_the_time_is_the_start_plus_the_steps_times_the_step(formulation):
    # 2000 steps of 1 ms are 2 s to the last bit (a running sum t += h reads 1.9999999999998905);
    # a step of another size goes on from where the time stands.
    m = mechanism_sim.load(FOUR_BAR, formulation=formulation)
    m.advance(2.0, 1e-3)
    assert m.steps() == 2000
    assert m.time() == 2.0
    m.step(0.1, 3)
    assert m.time() == 2.0 + 3 * 0.1
    s = m.snapshot()
    m.step(1e-3, 7)
    m.restore(s)
    m.step(1e-3, 1000)
    assert m.time() == 2.3 + 1000 * 1e-3


def test_a_non_physical_inertia_runs_with_a_note_and_strict_inertia_refuses_it():
    finger = os.path.join(SOURCE, "test/urdf/finger_zero_moments.urdf")
    m = mechanism_sim.load(finger)
    assert any("principal moments (0, 0, 3e-05) -> (1e-05, 1e-05, 2e-05)" in n for n in m.notes())
    with pytest.raises(mechanism_sim.LoadError, match="inertia violates the triangle inequality"):
        mechanism_sim.load(finger, strict_inertia=True)


def test_a_model_without_mass_runs_kinematically():
    m = mechanism_sim.load(os.path.join(SOURCE, "test/urdf/kinematic_four_bar.urdf"), drives={"crank_joint": 2.0})
    assert m.formulation_reason().startswith("kinematic")
    assert "kinematic: no moving body has mass; 0 dofs held, 1 driven, 2 solved from the loops and couplers" in m.notes()
