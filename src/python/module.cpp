// The Python module mechanism_sim._mechanism_sim (pybind11), re-exported by the package
// mechanism_sim (python/mechanism_sim/__init__.py; doc/python.md). Conversions only: the
// run's record is Simulation's (simulation.h), the physics the core's.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <limits>

#include "simulation.h"

namespace py = pybind11;
using namespace mechanism_sim;
using mechanism_sim::python::Simulation;
using mechanism_sim::python::SimulationSnapshot;

namespace {

using Values = std::vector<std::pair<std::string, double>>;

// {name: number} (any mapping) -> pairs in the mapping's order.
Values values(const py::object& mapping, const char* what) {
  Values out;
  if (mapping.is_none()) return out;
  if (!py::isinstance<py::dict>(mapping) && !py::hasattr(mapping, "items"))
    throw py::type_error(std::string(what) + " must be a mapping {dof name: number}");
  for (const py::handle item : mapping.attr("items")()) {
    const py::tuple kv = py::reinterpret_borrow<py::tuple>(item);
    out.emplace_back(py::str(kv[0]).cast<std::string>(), kv[1].cast<double>());
  }
  return out;
}

struct LoadArgs {
  LoadOptions options;
  Values efforts;
};

LoadArgs loadArgs(const py::object& args, const py::object& positions, const py::object& velocities,
                  const py::object& efforts, const py::object& drives, const std::string& integrator,
                  const py::object& closures, const std::string& formulation, bool strict_inertia,
                  const py::object& actuators, bool actuator_limits) {
  LoadArgs a;
  if (!args.is_none())
    for (const py::handle item : args.attr("items")()) {
      const py::tuple kv = py::reinterpret_borrow<py::tuple>(item);
      a.options.xacro_args.emplace_back(py::str(kv[0]).cast<std::string>(), py::str(kv[1]).cast<std::string>());
    }
  a.options.positions = values(positions, "positions");
  a.options.velocities = values(velocities, "velocities");
  a.options.drives = values(drives, "drives");
  a.options.integrator = integrator;
  a.options.formulation = formulation;
  a.options.strict_inertia = strict_inertia;
  a.options.actuator_limits = actuator_limits;
  if (!closures.is_none()) a.options.closures_file = py::str(closures).cast<std::string>();
  if (!actuators.is_none()) a.options.actuators_file = py::str(actuators).cast<std::string>();
  a.efforts = values(efforts, "efforts");
  return a;
}

// Efforts as simulate --effort sets them: after loading, a bad name is a LoadError.
std::unique_ptr<Simulation> finish(std::unique_ptr<MechanismModel> model, const std::string& path, const Values& efforts) {
  for (const auto& e : efforts) {
    const int d = model->dofIndex(e.first);
    if (d < 0) throw LoadError(path + ": --effort names no joint degree of freedom '" + e.first + "'");
    model->setEffort(d, e.second);
  }
  return std::make_unique<Simulation>(std::move(model), path);
}

py::array_t<double> array(const std::vector<double>& v) { return py::array_t<double>(v.size(), v.data()); }

template <class F>
py::array_t<double> perDof(const Simulation& s, F f) {
  const int n = static_cast<int>(s.model().dofs().size());
  py::array_t<double> out(n);
  auto w = out.mutable_unchecked<1>();
  for (int d = 0; d < n; ++d) w(d) = f(d);
  return out;
}

py::dict solverStats(const SolverStats& st) {
  py::dict d;
  d["solves"] = st.solves, d["solve_shortfalls"] = st.solve_shortfalls;
  d["position_projections"] = st.position_projections, d["position_shortfalls"] = st.position_shortfalls;
  d["velocity_projections"] = st.velocity_projections, d["velocity_shortfalls"] = st.velocity_shortfalls;
  d["evaluations"] = st.evaluations, d["factorizations"] = st.factorizations, d["solve_passes"] = st.solve_passes;
  d["halved_steps"] = st.halved_steps;
  d["worst_solve"] = st.worst_solve, d["worst_position"] = st.worst_position, d["worst_velocity"] = st.worst_velocity;
  d["shortfalls"] = st.shortfalls();
  d["describe"] = st.describe();
  return d;
}

// MechanismModel::actuatorState of every actuator, as arrays.
py::dict actuatorStates(const Simulation& s) {
  const std::vector<Actuator>& actuators = s.model().actuators();
  const size_t n = actuators.size();
  std::vector<std::string> names;
  std::vector<double> position(n), velocity(n), torque(n), power(n), current(n), voltage(n), electrical_power(n);
  std::vector<double> lag(n), saturated(n);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (size_t a = 0; a < n; ++a) {
    const ActuatorState st = s.model().actuatorState(static_cast<int>(a));
    names.push_back(actuators[a].name);
    position[a] = st.position, velocity[a] = st.velocity, torque[a] = st.torque, power[a] = st.power;
    const bool given = electricalGiven(actuators[a].ratings);
    current[a] = given ? st.current : nan, voltage[a] = given ? st.voltage : nan;
    electrical_power[a] = given ? st.electrical_power : nan;
    lag[a] = st.lag, saturated[a] = st.saturated ? 1.0 : 0.0;
  }
  py::dict d;
  d["names"] = names;
  d["position"] = array(position), d["velocity"] = array(velocity), d["torque"] = array(torque), d["power"] = array(power);
  d["current"] = array(current), d["voltage"] = array(voltage), d["electrical_power"] = array(electrical_power);
  d["lag"] = array(lag), d["saturated"] = array(saturated);  // the saturating mode's (0 otherwise)
  return d;
}

// Each actuator's ActuatorSizing as a dict, by name.
py::dict actuatorSizing(const Simulation& s) {
  py::dict out;
  for (const ActuatorSizing& a : s.actuatorSizing()) {
    py::dict d;
    d["peak_torque"] = a.peakTorque(), d["peak_torque_time"] = a.peakTorqueTime(), d["rms_torque"] = a.rmsTorque();
    d["peak_speed"] = a.peakSpeed(), d["peak_power"] = a.peakPower();
    d["positive_work"] = a.positiveWork(), d["negative_work"] = a.negativeWork();
    if (a.electricalGiven()) {
      d["peak_current"] = a.peakCurrent(), d["peak_voltage"] = a.peakVoltage();
      d["peak_electrical_power"] = a.peakElectricalPower(), d["copper_energy"] = a.copperEnergy();
    }
    py::list exceeded;
    for (const ActuatorSizing::Exceeded& e : a.exceeded()) {
      py::dict x;
      x["rating"] = e.rating, x["limit"] = e.limit, x["worst"] = e.worst, x["worst_time"] = e.worst_time;
      x["first_time"] = e.first_time;
      exceeded.append(x);
    }
    // None: no rating to size against
    d["within_rating"] = a.rated() ? py::object(py::bool_(exceeded.size() == 0)) : py::object(py::none());
    if (a.saturating()) {  // the saturating mode's record (doc/actuators.md)
      d["bound_intervals"] = a.boundIntervals(), d["bound_time"] = a.boundTime();
      d["first_bound"] = a.firstBound(), d["last_bound"] = a.lastBound();
      d["largest_lag"] = a.largestLag(), d["largest_lag_time"] = a.largestLagTime();
      d["largest_lag_began"] = a.largestLagBegan(), d["largest_lag_ended"] = a.largestLagEnded();
      d["final_lag"] = a.finalLag();
    }
    d["exceeded"] = exceeded;
    d["describe"] = a.describe();
    out[py::str(a.name())] = d;
  }
  return out;
}

// An exception class with several bases (mechanism_sim.LoadError is also a ValueError).
py::handle exceptionType(py::module_& m, const char* name, std::initializer_list<py::handle> bases, const char* doc) {
  py::tuple b(bases.size());
  size_t i = 0;
  for (py::handle h : bases) b[i++] = py::reinterpret_borrow<py::object>(h);
  const std::string full = std::string("mechanism_sim.") + name;
  py::object type = py::reinterpret_steal<py::object>(PyErr_NewExceptionWithDoc(full.c_str(), doc, b.ptr(), nullptr));
  if (!type) throw py::error_already_set();
  m.attr(name) = type;  // the module keeps it alive
  return type;
}

}  // namespace

PYBIND11_MODULE(_mechanism_sim, m) {
  m.doc() = "mechanism_sim: URDF mechanisms with closed loops (doc/python.md)";

  // ---- errors: the library's hierarchy (core/errors.h), its message unchanged
  static py::handle error = exceptionType(m, "Error", {PyExc_Exception}, "Everything mechanism_sim raises on purpose.");
  static py::handle model_error =
      exceptionType(m, "ModelError", {error, PyExc_ValueError}, "A model or state that cannot be simulated.");
  static py::handle load_error =
      exceptionType(m, "LoadError", {model_error}, "A file that cannot be simulated: 'FILE:LINE: element: what'.");
  static py::handle simulation_error =
      exceptionType(m, "SimulationError", {error, PyExc_RuntimeError}, "A run that cannot go on: 'FILE: at t = T s: what'.");
  static py::handle step_failure =
      exceptionType(m, "StepFailure", {simulation_error}, "A step that left the constraints beyond repair.");
  static py::handle usage_error =
      exceptionType(m, "UsageError", {error, PyExc_ValueError}, "A call with an argument the library does not take.");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const LoadError& e) {
      PyErr_SetString(load_error.ptr(), e.what());
    } catch (const ModelError& e) {
      PyErr_SetString(model_error.ptr(), e.what());
    } catch (const StepFailure& e) {
      PyErr_SetString(step_failure.ptr(), e.what());
    } catch (const SimulationError& e) {
      PyErr_SetString(simulation_error.ptr(), e.what());
    } catch (const UsageError& e) {
      PyErr_SetString(usage_error.ptr(), e.what());
    } catch (const Error& e) {  // InternalError: says it is a bug
      PyErr_SetString(error.ptr(), e.what());
    }
  });

  py::class_<SimulationSnapshot>(m, "Snapshot", "The complete state of a Model; Model.restore() continues bit-identically.")
      .def_property_readonly("time", [](const SimulationSnapshot& s) { return s.state.t; })
      .def_property_readonly("steps", [](const SimulationSnapshot& s) { return s.steps; });

  py::class_<Simulation>(m, "Model", "A loaded mechanism: load() or load_string() make one.")
      // ---- what the model is
      .def_property_readonly("name", [](const Simulation& s) { return s.model().name(); })
      .def_property_readonly("source", [](const Simulation& s) { return s.model().source(); })
      .def("dof_names", [](const Simulation& s) {
        std::vector<std::string> n;
        for (const Dof& d : s.model().dofs()) n.push_back(d.name);
        return n;
      }, "Degree-of-freedom names ('joint', or 'joint.dof' for multi-dof joints), the order of every per-dof array.")
      .def("driven_dofs", [](const Simulation& s) {
        std::vector<std::string> n;
        for (const Dof& d : s.model().dofs()) if (d.drive >= 0) n.push_back(d.name);
        return n;
      })
      .def("link_names", [](const Simulation& s) {
        std::vector<std::string> n;
        for (const Link& l : s.model().links()) n.push_back(l.name);
        return n;
      })
      .def("reaction_joints", [](const Simulation& s) {
        std::vector<std::string> n;
        for (const JointReaction& r : s.model().jointReactions()) n.push_back(r.joint);
        return n;
      }, "The joints reactions() reports, in its order.")
      .def("reaction_couplings", [](const Simulation& s) {
        std::vector<std::string> n;
        for (const CouplingInfo& c : s.model().couplings()) n.push_back(c.name);
        return n;
      }, "The <mechanism_sim:coupling>s reactions() reports, in its order.")
      .def("num_equations", [](const Simulation& s) { return s.model().numEquations(); })
      .def("dependencies", [](const Simulation& s) { return s.model().dependencies().describe(); })
      .def("formulation", [](const Simulation& s) { return std::string(s.model().mechanism().formulation()); },
           "The formulation that runs: 'joint' or 'absolute' (formulation_reason() says why).")
      .def("formulation_reason", [](const Simulation& s) { return s.model().formulationReason(); })
      .def("notes", [](const Simulation& s) { return s.model().notes(); },
           "What loading changed or left out, one line each (simulate prints them after its summary).")
      .def("gravity", [](const Simulation& s) {
        const Eigen::Vector3d g = s.model().gravity();
        return array({g.x(), g.y(), g.z()});
      })
      .def("set_gravity", [](Simulation& s, const std::array<double, 3>& g) {
        s.model().setGravity(Eigen::Vector3d(g[0], g[1], g[2]));
      })
      // ---- where it is now
      .def("time", [](const Simulation& s) { return s.model().time(); })
      .def("steps", &Simulation::steps, "Steps taken since loading or reset() (a restore() brings back its count).")
      .def("positions", [](const Simulation& s) { return perDof(s, [&](int d) { return s.model().position(d); }); })
      .def("velocities", [](const Simulation& s) { return perDof(s, [&](int d) { return s.model().velocity(d); }); })
      .def("accelerations", [](const Simulation& s) {
        return perDof(s, [&](int d) { return s.model().acceleration(d); });
      }, "The accelerations solved with the state when it was reached (a step, load, set_state), "
         "under the efforts commanded then.")
      .def("efforts", [](const Simulation& s) { return perDof(s, [&](int d) { return s.model().effort(d); }); },
           "The effort each joint applies along each dof (command, damping, friction, limit, drive).")
      .def("commanded_efforts", [](const Simulation& s) {
        return perDof(s, [&](int d) { return s.model().commandedEffort(d); });
      })
      .def("reactions", [](const Simulation& s) {
        const std::vector<JointReaction> r = s.model().jointReactions();
        py::array_t<double> f({static_cast<py::ssize_t>(r.size()), py::ssize_t(3)});
        py::array_t<double> t({static_cast<py::ssize_t>(r.size()), py::ssize_t(3)});
        auto fw = f.mutable_unchecked<2>();
        auto tw = t.mutable_unchecked<2>();
        std::vector<std::string> names;
        for (size_t j = 0; j < r.size(); ++j) {
          names.push_back(r[j].joint);
          for (int c = 0; c < 3; ++c) fw(j, c) = r[j].force[c], tw(j, c) = r[j].torque[c];
        }
        const std::vector<double> lambda = s.model().couplingReactions();
        std::vector<std::string> couplings;
        for (const CouplingInfo& c : s.model().couplings()) couplings.push_back(c.name);
        py::dict d;
        d["joints"] = names, d["force"] = f, d["torque"] = t;
        d["couplings"] = couplings, d["coupling"] = array(lambda);
        return d;
      }, "{'joints': names, 'force': (n, 3), 'torque': (n, 3), 'couplings': names, 'coupling': (m,)}: what "
         "each joint exerts on its child link, in the joint frame on the child, and each coupling's "
         "multiplier lambda (coordinate i carries -c_i lambda) (simulate --reactions).")
      .def("link_pose", [](const Simulation& s, const std::string& link) {
        const int l = s.model().linkIndex(link);
        if (l < 0) throw std::invalid_argument(s.path() + ": no link '" + link + "'");
        const Eigen::Matrix4d T = s.model().linkPose(l).matrix();
        py::array_t<double> out({4, 4});
        auto w = out.mutable_unchecked<2>();
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 4; ++j) w(i, j) = T(i, j);
        return out;
      }, "World pose of a link, a 4x4 homogeneous matrix.")
      .def("link_velocity", [](const Simulation& s, const std::string& link) {
        const int l = s.model().linkIndex(link);
        if (l < 0) throw std::invalid_argument(s.path() + ": no link '" + link + "'");
        const auto vw = s.model().linkVelocity(l);
        return array({vw.first.x(), vw.first.y(), vw.first.z(), vw.second.x(), vw.second.y(), vw.second.z()});
      }, "Velocity of a link's frame origin and its angular velocity, [vx, vy, vz, wx, wy, wz] in world axes.")
      .def("violation", [](const Simulation& s) {
        py::dict d;
        d["position"] = s.model().positionViolation(), d["velocity"] = s.model().velocityViolation();
        d["relative_position"] = s.model().relativePositionViolation();
        d["relative_velocity"] = s.model().relativeVelocityViolation();
        return d;
      }, "Now: largest |Phi| and |Phi_q v|, and both relative to each equation's terms.")
      .def("largest_violation", [](const Simulation& s) {
        py::dict d;
        d["position"] = s.worstPositionViolation(), d["velocity"] = s.worstVelocityViolation();
        return d;
      }, "Largest |Phi| and |Phi_q v| at any step since loading or reset() (simulate's summary).")
      .def("energies", [](const Simulation& s) {
        py::dict d;
        const double T = s.model().kineticEnergy(), V = s.model().potentialEnergy();
        d["kinetic"] = T, d["potential"] = V, d["total"] = T + V;
        return d;
      }, "Kinetic, potential (gravity and springs) and total energy.")
      .def("drive_peaks", [](const Simulation& s) {
        py::dict d;
        for (const DrivePeak& p : s.drivePeaks()) d[py::str(s.model().dofs()[p.dof].name)] = py::make_tuple(p.effort, p.time);
        return d;
      }, "{driven dof: (largest |effort| signed, its time)} since loading or reset().")
      .def("actuator_names", [](const Simulation& s) {
        std::vector<std::string> names;
        for (const Actuator& a : s.model().actuators()) names.push_back(a.name);
        return names;
      }, "The actuators the simulated <transmission>s name (doc/actuators.md).")
      .def("set_actuator_limits", [](Simulation& s, bool on) { return s.setActuatorLimits(on); }, py::arg("on"),
           "The saturating mode on or off from now (simulate --actuator-limits; doc/actuators.md); returns "
           "the note on actuators it cannot bound ('' if none).")
      .def("actuator_states", [](const Simulation& s) { return actuatorStates(s); },
           "Each actuator's operating point now: {'names', 'position', 'velocity', 'torque', 'power', 'current', "
           "'voltage', 'electrical_power'} (arrays in actuator_names() order; the electrical ones NaN without a "
           "torque_constant).")
      .def("actuator_sizing", [](const Simulation& s) { return actuatorSizing(s); },
           "{actuator: its peaks, RMS torque, work and ratings exceeded} since loading or reset() (simulate's "
           "sizing lines).")
      .def("solver_stats", [](const Simulation& s) { return solverStats(s.model().solverStats()); })
      .def("summary", &Simulation::summary, "The lines simulate prints after a run of these steps.")
      .def("wall_time", &Simulation::wallTime, "Seconds spent stepping since loading or reset().")
      // ---- running
      .def("step", [](Simulation& s, double h, long n) {
        py::gil_scoped_release release;
        s.step(h, n);
      }, py::arg("h"), py::arg("n") = 1, "n steps of h seconds.")
      .def("advance", [](Simulation& s, double duration, double h) {
        py::gil_scoped_release release;
        return s.advance(duration, h);
      }, py::arg("duration"), py::arg("h"), "round(duration / h) steps of h (simulate --duration --dt); returns the count.")
      .def("set_efforts", [](Simulation& s, const py::object& efforts) {
        if (py::isinstance<py::dict>(efforts) || py::hasattr(efforts, "items")) {
          for (const auto& e : values(efforts, "efforts")) s.setEffort(e.first, e.second);
          return;
        }
        const py::array_t<double, py::array::c_style | py::array::forcecast> a(efforts);
        const size_t n = s.model().dofs().size();
        if (a.ndim() != 1 || static_cast<size_t>(a.shape(0)) != n)
          throw std::invalid_argument("efforts: a mapping {dof: effort} or an array of " + std::to_string(n) + " (one per dof)");
        for (size_t d = 0; d < n; ++d) s.model().setEffort(static_cast<int>(d), a.at(d));
      }, "Commanded efforts: {dof: effort} or one per dof (simulate --effort); clamped to the effort limits.")
      .def("set_state", [](Simulation& s, const py::object& p, const py::object& v) {
        s.setState(values(p, "positions"), values(v, "velocities"));
      }, py::kw_only(), py::arg("positions") = py::none(), py::arg("velocities") = py::none(),
         "Assembles holding these dof positions and velocities ({dof: value}; simulate --set, --velocity): "
         "the other positions move as little as the loops allow, the other velocities are projected from the "
         "bodies' own. Raises mechanism_sim.ModelError (state unchanged) if they cannot be met.")
      .def("set_positions", [](Simulation& s, const py::object& p) { s.setState(values(p, "positions"), {}); },
           "set_state(positions=...)")
      .def("set_velocities", [](Simulation& s, const py::object& v) { s.setState({}, values(v, "velocities")); },
           "set_state(velocities=...)")
      .def("command_drive", [](Simulation& s, const std::string& dof, double v, double acc) {
        s.model().commandDriveVelocity(s.dof(dof, "drive"), v, acc);
      }, py::arg("dof"), py::arg("velocity"), py::arg("acceleration") = std::numeric_limits<double>::infinity(),
         "A velocity-driven dof moves to this velocity from now, at most this acceleration.")
      .def("snapshot", &Simulation::snapshot)
      .def("restore", &Simulation::restore)
      .def("reset", &Simulation::reset, "The assembled initial state, commands zeroed, the record restarted.")
      .def("__repr__", [](const Simulation& s) {
        return "<mechanism_sim.Model '" + s.model().name() + "' from '" + s.path() + "', " +
               std::to_string(s.model().dofs().size()) + " dofs, t = " + std::to_string(s.model().time()) + " s>";
      });

  const char* load_doc =
      "Loads, builds and assembles a model (simulate's options): args {name: value} for a .xacro file, "
      "positions/velocities {dof: value} (--set/--velocity), efforts (--effort), drives {dof: velocity} "
      "(--drive), integrator 'rk4'|'rk3'|'rk2', closures: an Extended URDF YAML (--closures), "
      "formulation 'absolute'|'joint'|'auto' (--formulation), strict_inertia: refuse a body whose inertia "
      "is not physical (--strict-inertia; by default it runs with the nearest physical one and a note), "
      "actuators: a YAML file of actuator properties (--actuators), actuator_limits: the saturating mode "
      "(--actuator-limits: actuators bound their drives; set_actuator_limits() switches it later). "
      "Raises mechanism_sim.LoadError.";
  m.def("load", [](const std::string& path, const py::object& args, const py::object& positions,
                   const py::object& velocities, const py::object& efforts, const py::object& drives,
                   const std::string& integrator, const py::object& closures, const std::string& formulation,
                   bool strict_inertia, const py::object& actuators, bool actuator_limits) {
    const LoadArgs a = loadArgs(args, positions, velocities, efforts, drives, integrator, closures, formulation,
                                strict_inertia, actuators, actuator_limits);
    std::unique_ptr<MechanismModel> model;
    {
      py::gil_scoped_release release;  // xacro runs Node.js
      model = loadModelFile(path, a.options);
    }
    return finish(std::move(model), path, a.efforts);
  }, py::arg("path"), py::kw_only(), py::arg("args") = py::none(), py::arg("positions") = py::none(),
     py::arg("velocities") = py::none(), py::arg("efforts") = py::none(), py::arg("drives") = py::none(),
     py::arg("integrator") = "", py::arg("closures") = py::none(), py::arg("formulation") = "",
     py::arg("strict_inertia") = false, py::arg("actuators") = py::none(),
     py::arg("actuator_limits") = false, load_doc);
  m.def("load_string", [](const std::string& xml, const std::string& source, const py::object& positions,
                          const py::object& velocities, const py::object& efforts, const py::object& drives,
                          const std::string& integrator, const py::object& closures, const std::string& formulation,
                          bool strict_inertia, const py::object& actuators, bool actuator_limits) {
    const LoadArgs a = loadArgs(py::none(), positions, velocities, efforts, drives, integrator, closures, formulation,
                                strict_inertia, actuators, actuator_limits);
    std::unique_ptr<MechanismModel> model;
    {
      py::gil_scoped_release release;
      model = loadModelString(xml, source, a.options);
    }
    return finish(std::move(model), source, a.efforts);
  }, py::arg("xml"), py::arg("source") = "<string>", py::kw_only(), py::arg("positions") = py::none(),
     py::arg("velocities") = py::none(), py::arg("efforts") = py::none(), py::arg("drives") = py::none(),
     py::arg("integrator") = "", py::arg("closures") = py::none(), py::arg("formulation") = "",
     py::arg("strict_inertia") = false, py::arg("actuators") = py::none(),
     py::arg("actuator_limits") = false, "As load(), from URDF text (no xacro).");
}
