// simulate: runs a URDF mechanism without a ROS graph and writes CSV, and with --bag a ROS
// bag of what the node would publish (doc/simulate.md).
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <string>

#include "bag_writer.h"
#include "csv_writer.h"
#include "mechanism_sim/urdf/model.h"
#include "mechanism_sim/urdf/run_loop.h"
#include "mechanism_sim/urdf/trajectory.h"

using namespace mechanism_sim;

namespace {

const char* kUsage =
    "usage: simulate MODEL.urdf|MODEL.urdf.xacro [name:=value]... (xacro arguments)\n"
    "                [--duration S] [--dt S] [--output-every N]\n"
    "                [--csv FILE] [--poses] [--integrator rk4|rk3|rk2]\n"
    "                [--formulation absolute|joint|auto]\n"
    "                [--set JOINT=POSITION]... [--velocity JOINT=VALUE]...\n"
    "                [--effort JOINT=VALUE]... [--drive JOINT=VELOCITY]...\n"
    "                [--reactions] [--bag FILE.bag] [--plot FILE.png] [--plot-columns LIST]\n"
    "                [--actuator-plot FILE.png] [--actuator-limits]\n"
    "                [--closures FILE.yaml] [--actuators FILE.yaml] [--strict-inertia] [--quiet]\n"
    "                [--trajectory FILE.csv] [--trajectory-start-tolerance X]\n";

// A command line that cannot be run throws mechanism_sim::UsageError (exit 2 with the usage).

struct BagFailure {};  // --bag FILE could not be written

double parseNumber(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const double x = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(x)) throw UsageError(what + " needs a finite number, not '" + text + "'");
  return x;
}

std::pair<std::string, double> parseAssignment(const std::string& text, const std::string& flag) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0) throw UsageError(flag + " needs JOINT=VALUE, not '" + text + "'");
  return {text.substr(0, eq), parseNumber(text.substr(eq + 1), flag + " " + text.substr(0, eq))};
}

bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

// name:=value (a xacro argument, doc/xacro.md), name an identifier.
bool isXacroArgument(const std::string& arg) {
  const size_t op = arg.find(":=");
  if (op == std::string::npos || op == 0 || !(std::isalpha(static_cast<unsigned char>(arg[0])) || arg[0] == '_')) return false;
  return std::all_of(arg.begin(), arg.begin() + op, [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

struct Args {
  std::string model, csv, bag, integrator, plot, plot_columns, trajectory, actuator_plot;
  double trajectory_tolerance = kTrajectoryStartTolerance;
  double duration = 10.0, dt = 1e-3;
  long every = 10;
  bool poses = false, quiet = false, reactions = false;
  LoadOptions load;
  std::vector<std::pair<std::string, double>> efforts;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw UsageError(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--duration") a.duration = parseNumber(value(), arg);
    else if (arg == "--dt") a.dt = parseNumber(value(), arg);
    else if (arg == "--output-every") a.every = static_cast<long>(parseNumber(value(), arg));
    else if (arg == "--csv") a.csv = value();
    else if (arg == "--poses") a.poses = true;
    else if (arg == "--integrator") a.load.integrator = value();
    else if (arg == "--formulation") a.load.formulation = value();
    else if (arg == "--set") a.load.positions.push_back(parseAssignment(value(), arg));
    else if (arg == "--velocity") a.load.velocities.push_back(parseAssignment(value(), arg));
    else if (arg == "--effort") a.efforts.push_back(parseAssignment(value(), arg));
    else if (arg == "--drive") a.load.drives.push_back(parseAssignment(value(), arg));
    else if (arg == "--reactions") a.reactions = true;
    else if (arg == "--bag") a.bag = value();
    else if (arg == "--plot") a.plot = value();
    else if (arg == "--plot-columns") a.plot_columns = value();
    else if (arg == "--actuator-plot") a.actuator_plot = value();  // doc/actuators.md
    else if (arg == "--closures") a.load.closures_file = value();  // doc/loop_dialects.md
    else if (arg == "--actuators") a.load.actuators_file = value();  // doc/actuators.md
    else if (arg == "--actuator-limits") a.load.actuator_limits = true;  // doc/actuators.md (saturating mode)
    else if (arg == "--strict-inertia") a.load.strict_inertia = true;  // doc/robots.md
    else if (arg == "--quiet") a.quiet = true;
    else if (arg == "--trajectory") a.trajectory = value();  // doc/trajectories.md
    else if (arg == "--trajectory-start-tolerance") a.trajectory_tolerance = parseNumber(value(), arg);
    else if (arg == "-h" || arg == "--help") { std::cout << kUsage; std::exit(0); }
    else if (!arg.empty() && arg[0] == '-') throw UsageError("unknown option '" + arg + "'");
    else if (isXacroArgument(arg)) a.load.xacro_args.emplace_back(arg.substr(0, arg.find(":=")), arg.substr(arg.find(":=") + 2));
    else if (a.model.empty()) a.model = arg;
    else throw UsageError("more than one model file given");
  }
  if (a.model.empty()) throw UsageError("no model file given");
  if (!a.load.xacro_args.empty() && !endsWith(a.model, ".xacro"))
    throw UsageError("name:=value sets a xacro argument, but '" + a.model + "' is not a .xacro file");
  if (!a.plot_columns.empty() && a.plot.empty()) throw UsageError("--plot-columns needs --plot FILE.png");
  if (!(a.duration >= 0) || a.duration > 1e7) throw UsageError("--duration must be between 0 and 1e7 s");
  if (!(a.dt > 0) || a.dt > 1.0) throw UsageError("--dt must be in (0, 1] s");
  if (a.every < 1) throw UsageError("--output-every must be at least 1");
  if (!(a.trajectory_tolerance >= 0)) throw UsageError("--trajectory-start-tolerance must be >= 0");
  if (a.duration / a.dt > 1e10) throw UsageError("--duration / --dt is more than 1e10 steps");
  return a;
}

// Debian's python3 on a script; its exit status, or -1 if it did not start.
int runPython(std::vector<std::string> argv) {
  argv.insert(argv.begin(), "/usr/bin/python3");
  std::vector<char*> cargv;
  for (std::string& a : argv) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  std::cout.flush();
  const pid_t pid = fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    execv(cargv[0], cargv.data());
    _exit(127);
  }
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// scripts/plot (matplotlib) on the run's CSV; its exit status, or -1 if it did not start.
int plot(const std::string& csv, const Args& args, const std::string& title) {
  const char* env = std::getenv("MECHANISM_SIM_PLOT");
  const std::string script = env && *env ? env : MECHANISM_SIM_PLOT_SCRIPT;
  std::vector<std::string> argv = {script, csv, "-o", args.plot, "--title", title};
  if (!args.plot_columns.empty()) argv.insert(argv.end(), {"--columns", args.plot_columns});
  return runPython(argv);
}

// The operating points an --actuator-plot keeps per actuator (evenly spaced in steps).
constexpr size_t kActuatorPlotPoints = 20000;

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\', out += c;
    else if (static_cast<unsigned char>(c) < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", c);
      out += b;
    } else out += c;
  }
  return out + "\"";
}

std::string jsonNumber(double x) {
  if (!std::isfinite(x)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.17g", x);
  return b;
}

// --actuator-plot's data (doc/actuators.md), beside the picture as FILE.png.json so that
// scripts/actuator_plot can redraw it: per actuator its ratings (0: not given), its sizing
// and its kept operating points [t, velocity, torque].
bool writeActuatorPlotData(const std::string& path, const std::string& title, const MechanismModel& model,
                           const RunLoop& loop) {
  std::ofstream f(path);
  if (!f) return false;
  f << "{\"title\": " << jsonString(title) << ", \"actuators\": [";
  for (size_t a = 0; a < loop.actuatorSizing().size(); ++a) {
    const ActuatorSizing& s = loop.actuatorSizing()[a];
    const ActuatorRatings& r = model.actuators()[a].ratings;
    f << (a ? ",\n" : "\n") << "{\"name\": " << jsonString(s.name()) << ", \"ratings\": {";
    const std::pair<const char*, double> ratings[] = {{"rated_torque", r.rated_torque}, {"peak_torque", r.peak_torque},
                                                       {"stall_torque", r.stall_torque}, {"no_load_speed", r.no_load_speed},
                                                       {"max_speed", r.max_speed}};
    for (size_t k = 0; k < std::size(ratings); ++k)
      f << (k ? ", " : "") << jsonString(ratings[k].first) << ": " << jsonNumber(ratings[k].second);
    f << "}, \"peak_torque\": " << jsonNumber(s.peakTorque()) << ", \"rms_torque\": " << jsonNumber(s.rmsTorque())
      << ", \"peak_speed\": " << jsonNumber(s.peakSpeed())
      << ", \"within_rating\": " << (s.rated() ? (s.withinRating() ? "true" : "false") : "null")
      << ", \"exceeded\": [";
    const std::vector<ActuatorSizing::Exceeded> exceeded = s.exceeded();
    for (size_t k = 0; k < exceeded.size(); ++k) f << (k ? ", " : "") << jsonString(exceeded[k].rating);
    f << "], \"describe\": " << jsonString(s.describe()) << ", \"points\": [";
    const auto& p = s.points();
    for (size_t i = 0; i < p.size(); ++i)
      f << (i ? "," : "") << "[" << jsonNumber(p[i][0]) << "," << jsonNumber(p[i][1]) << "," << jsonNumber(p[i][2]) << "]";
    f << "]}";
  }
  f << "\n]}\n";
  return static_cast<bool>(f);
}

void progress(double fraction, double elapsed) {
  const int width = 40, filled = static_cast<int>(fraction * width);
  std::fprintf(stderr, "\r[%.*s%*s] %5.1f%%  %.1f s", filled, "========================================",
               width - filled, "", 100.0 * fraction, elapsed);
  std::fflush(stderr);
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  try {
    args = parse(argc, argv);
  } catch (const UsageError& e) {
    std::cerr << "simulate: " << e.what() << "\n" << kUsage;
    return 2;
  }
  std::unique_ptr<MechanismModel> model;
  try {
    model = loadModelFile(args.model, args.load);
    for (const auto& e : args.efforts) {
      const int d = model->dofIndex(e.first);
      if (d < 0) throw LoadError(args.model + ": --effort names no joint degree of freedom '" + e.first + "'");
      model->setEffort(d, e.second);
    }
  } catch (const std::exception& e) {
    std::cerr << "simulate: " << e.what() << "\n";
    return 1;
  }
  if (!args.actuator_plot.empty() && model->actuators().empty()) {
    std::cerr << "simulate: " << args.model << ": --actuator-plot: the model has no actuators (no simulated <transmission>)\n";
    return 2;
  }
  // --trajectory: the dofs it names follow it from t = 0; a file that cannot be followed
  // is bad input like a bad argument (exit code 2).
  if (!args.trajectory.empty()) {
    try {
      followTrajectory(*model, readTrajectoryCsv(args.trajectory), 0.0, args.trajectory_tolerance);
    } catch (const TrajectoryError& e) {
      const std::string what = e.what();
      const bool located = what.compare(0, args.trajectory.size(), args.trajectory) == 0;
      std::cerr << "simulate: trajectory rejected: " << (located ? "" : args.trajectory + ": ") << what << "\n";
      return 2;
    }
  }
  // --plot without --csv: the CSV goes to a file beside the picture (FILE.png.csv), kept
  // so that scripts/plot can redraw it.
  const std::string csv_path = !args.csv.empty() ? args.csv : !args.plot.empty() ? args.plot + ".csv" : "";
  std::ofstream file;
  std::ostream* out = &std::cout;
  if (!csv_path.empty()) {
    file.open(csv_path);
    if (!file) {
      std::cerr << "simulate: cannot write '" << csv_path << "'\n";
      return 1;
    }
    out = &file;
  }
  // --bag: the node's topics at every sample, stamped with simulation time (+1 ns); it
  // needs the reactions (the CSV has them only with --reactions).
  std::unique_ptr<BagWriter> bag;
  if (!args.bag.empty()) {
    try {
      bag = std::make_unique<BagWriter>(args.bag, *model);
    } catch (const std::exception&) {
      std::cerr << "simulate: cannot write '" << args.bag << "'\n";
      return 1;
    }
  }
  CsvWriter csv(*out, *model, args.poses, args.reactions);
  RunLoop loop(*model, args.dt, args.every);
  loop.setReactions(args.reactions || bag);
  if (!args.actuator_plot.empty()) loop.keepActuatorPoints(kActuatorPlotPoints);
  const bool write = !csv_path.empty() || !isatty(STDOUT_FILENO) || !args.quiet;
  // A bag that cannot be written (disk full) ends the run like a file that cannot be opened.
  auto sample = [&] {
    if (write) csv.row(loop.sample());
    if (bag) {
      try {
        bag->write(loop.sample());
      } catch (const rosbag::BagException&) {
        throw BagFailure();
      }
    }
  };
  if (write) csv.header();
  const long steps = std::lround(args.duration / args.dt);
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  const bool bar = !args.quiet && isatty(STDERR_FILENO);
  double last_bar = 0;
  auto tick = [&] {
    if (elapsed() > 1.0 && elapsed() - last_bar > 0.1) {
      last_bar = elapsed();
      progress(static_cast<double>(loop.steps()) / steps, last_bar);
    }
  };
  try {
    // A sample at t = 0, every N steps, and one at the end.
    sample();
    while (loop.steps() < steps) {
      loop.advance(std::min(args.every, steps - loop.steps()), bar ? std::function<void()>(tick) : nullptr);
      sample();
    }
    if (bag) {
      try {
        bag->close();
      } catch (const rosbag::BagException&) {
        throw BagFailure();
      }
    }
  } catch (const BagFailure&) {
    std::cerr << (last_bar > 0 ? "\n" : "") << "simulate: cannot write '" << args.bag << "'\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "\nsimulate: " << e.what() << "\n";  // "FILE: at t = T s: what" (MechanismModel::step)
    return 1;
  }
  out->flush();
  if (file.is_open()) file.close();
  const double wall = elapsed();
  if (bar && last_bar > 0) progress(1.0, wall), std::fputc('\n', stderr);
  const std::string summary = runSummary(*model, steps, args.dt, wall, loop.worstPositionViolation(),
                                         loop.worstVelocityViolation(), loop.drivePeaks());
  if (!args.quiet) std::fprintf(stderr, "%s: %s\n", args.model.c_str(), summary.c_str());
  // each actuator described (ratings or a rotor given) sized; the others counted
  // (doc/actuators.md)
  int undescribed = 0;
  for (size_t a = 0; a < loop.actuatorSizing().size(); ++a) {
    if (!ratingsGiven(model->actuators()[a].ratings)) ++undescribed;
    else if (!args.quiet) std::fprintf(stderr, "%s: %s\n", args.model.c_str(), loop.actuatorSizing()[a].describe().c_str());
  }
  if (undescribed && !args.quiet)
    std::fprintf(stderr, "%s: %d actuators without ratings (their motor_* columns are in the CSV)\n", args.model.c_str(),
                 undescribed);
  for (const std::string& note : model->notes())
    if (!args.quiet) std::fprintf(stderr, "%s: %s\n", args.model.c_str(), note.c_str());
  if (!args.plot.empty()) {
    char title[512];
    std::snprintf(title, sizeof title, "%s (%s): %ld steps of %g s", model->name().c_str(), args.model.c_str(), steps, args.dt);
    const int status = plot(csv_path, args, title);
    if (status != 0) {
      std::cerr << "simulate: " << args.model << ": plotting to '" << args.plot << "' failed"
                << (status < 0 ? " (could not start python3)" : "") << "\n";
      return 1;
    }
  }
  // --actuator-plot: the torque-speed plane per actuator (scripts/actuator_plot), its data
  // kept beside the picture (FILE.png.json) so that the script can redraw it
  if (!args.actuator_plot.empty()) {
    char title[512];
    std::snprintf(title, sizeof title, "%s (%s): %ld steps of %g s", model->name().c_str(), args.model.c_str(), steps, args.dt);
    const std::string data = args.actuator_plot + ".json";
    if (!writeActuatorPlotData(data, title, *model, loop)) {
      std::cerr << "simulate: cannot write '" << data << "'\n";
      return 1;
    }
    const char* env = std::getenv("MECHANISM_SIM_ACTUATOR_PLOT");
    const std::string script = env && *env ? env : MECHANISM_SIM_ACTUATOR_PLOT_SCRIPT;
    const int status = runPython({script, data, "-o", args.actuator_plot});
    if (status != 0) {
      std::cerr << "simulate: " << args.model << ": plotting to '" << args.actuator_plot << "' failed"
                << (status < 0 ? " (could not start python3)" : "") << "\n";
      return 1;
    }
  }
  return 0;
}
