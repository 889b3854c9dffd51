// Joint trajectories: checks, the paths of the named dofs, and the CSV reader (trajectory.h).
#include "mechanism_sim/urdf/trajectory.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

#include "mechanism_sim/core/model/couplers.h"

namespace mechanism_sim {
namespace {

// times and positions with six digits
std::string fmt6(double x) { return fmt(x, 6); }

// Whether coordinate k of joint j is the first (follower) coordinate of a coupler.
bool isFollower(const Mechanism& mech, int j, int k) {
  for (int c = 0; c < mech.numConstraints(); ++c)
    if (const auto* cp = dynamic_cast<const CoordinateCoupler*>(&mech.constraint(c)))
      if (&cp->jointA() == &mech.joint(j) && cp->coordinateA() == k) return true;
  return false;
}

void checkTable(const std::vector<std::vector<double>>& table, size_t points, size_t dofs, const char* what) {
  if (table.empty()) return;
  if (table.size() != points) throw TrajectoryError(std::string(what) + " are given for some points, not all");
  for (size_t i = 0; i < points; ++i) {
    if (table[i].size() != dofs)
      throw TrajectoryError("point " + std::to_string(i + 1) + " has " + std::to_string(table[i].size()) + " " + what +
                            " for " + std::to_string(dofs) + " joints");
    for (size_t j = 0; j < dofs; ++j)
      if (!std::isfinite(table[i][j]))
        throw TrajectoryError("point " + std::to_string(i + 1) + ": " + what + " " + std::to_string(j + 1) + " is not finite");
  }
}

}  // namespace

void checkTrajectory(const MechanismModel& model, const Trajectory& traj) {
  if (traj.dofs.empty()) throw TrajectoryError("it names no joint");
  const Mechanism& mech = model.mechanism();
  std::set<std::string> seen;
  for (const std::string& name : traj.dofs) {
    const int d = model.dofIndex(name);
    if (d < 0) throw TrajectoryError("unknown joint '" + name + "'");
    if (!seen.insert(name).second) throw TrajectoryError("joint '" + name + "' is named twice");
    const Dof& dof = model.dofs()[d];
    if (!dof.actuated) throw TrajectoryError(model.whyPassive(d));
    if (isFollower(mech, dof.joint_index, dof.k))
      throw TrajectoryError("joint '" + name + "' is coupled (a mimic follower): it moves with the joint it follows");
    if (dof.drive >= 0 && mech.system().drives[dof.drive].profile.kind() != DriveProfile::Kind::kVelocity)
      throw TrajectoryError("joint '" + name + "' follows a profile drive of the model");
  }
  const size_t n = traj.times.size(), m = traj.dofs.size();
  if (n == 0) throw TrajectoryError("it has no point");
  if (traj.positions.size() != n) throw TrajectoryError("it has positions for " + std::to_string(traj.positions.size()) + " of " + std::to_string(n) + " points");
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(traj.times[i])) throw TrajectoryError("point " + std::to_string(i + 1) + ": time is not finite");
    if (traj.times[i] < 0) throw TrajectoryError("point " + std::to_string(i + 1) + ": time_from_start is negative");
    if (i > 0 && !(traj.times[i] > traj.times[i - 1]))
      throw TrajectoryError("times must increase: point " + std::to_string(i + 1) + " at " + fmt6(traj.times[i]) +
                            " s does not come after point " + std::to_string(i) + " at " + fmt6(traj.times[i - 1]) + " s");
  }
  checkTable(traj.positions, n, m, "positions");
  checkTable(traj.velocities, n, m, "velocities");
  checkTable(traj.accelerations, n, m, "accelerations");
  if (!traj.accelerations.empty() && traj.velocities.empty())
    throw TrajectoryError("accelerations are given without velocities");
}

void followTrajectory(MechanismModel& model, const Trajectory& traj, double start, double start_tolerance) {
  checkTrajectory(model, traj);
  Mechanism& mech = model.mechanism();
  const double now = model.time();
  // Points at or before now (to 1 ns: a start on the step grid up to round-off) are past.
  size_t first = 0;
  while (first < traj.times.size() && start + traj.times[first] <= now + 1e-9) ++first;
  if (first == traj.times.size())
    throw TrajectoryError("it ends at t = " + fmt6(start + traj.times.back()) + " s, not after the current time " + fmt6(now) + " s");
  const size_t m = traj.dofs.size();
  std::vector<int> dofs(m);
  std::vector<PathKnot> from(m);
  for (size_t j = 0; j < m; ++j) {
    const int d = dofs[j] = model.dofIndex(traj.dofs[j]);
    const Dof& dof = model.dofs()[d];
    const double q = model.position(d), off = traj.positions[0][j] - q;
    if (!(std::fabs(off) <= start_tolerance))
      throw TrajectoryError("joint '" + dof.name + "': the first point " + fmt6(traj.positions[0][j]) + " is " +
                            fmt6(std::fabs(off)) + " from its position " + fmt6(q) + " (start tolerance " +
                            fmt6(start_tolerance) + ")");
    from[j].t = now;
    if (dof.drive >= 0) mech.driveTarget(dof.drive, &from[j].q, &from[j].v, &from[j].a);
    else from[j] = PathKnot{now, q, model.velocity(d), mech.jointAcceleration(dof.joint_index, dof.k)};
  }
  std::vector<std::shared_ptr<const DrivePath>> paths;
  for (size_t j = 0; j < m; ++j) {
    std::vector<double> t, q, v, a;
    for (size_t i = first; i < traj.times.size(); ++i) {
      t.push_back(start + traj.times[i]);
      q.push_back(traj.positions[i][j]);
      if (!traj.velocities.empty()) v.push_back(traj.velocities[i][j]);
      if (!traj.accelerations.empty()) a.push_back(traj.accelerations[i][j]);
    }
    try {
      paths.push_back(std::make_shared<const DrivePath>(DrivePath::through(from[j], t, q, v, a)));
    } catch (const UsageError& e) {
      throw TrajectoryError("joint '" + traj.dofs[j] + "': " + e.what());
    }
  }
  // Free dofs become driven; if one cannot be, those driven here are freed again (the
  // last added first, so that the others keep their indices).
  std::vector<int> added;
  for (int d : dofs) {
    if (model.dofs()[d].drive >= 0) continue;
    try {
      model.driveDof(d);
      added.push_back(d);
    } catch (const UsageError& e) {
      for (auto it = added.rbegin(); it != added.rend(); ++it) model.undriveDof(*it);
      throw TrajectoryError(e.what());
    }
  }
  for (size_t j = 0; j < m; ++j) mech.commandDrivePath(model.dofs()[dofs[j]].drive, paths[j]);
}

Trajectory readTrajectoryCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw TrajectoryError(path + ": cannot be read");
  auto split = [](const std::string& line) {
    std::vector<std::string> cells;
    std::string cell;
    std::istringstream ss(line);
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.push_back("");
    for (std::string& c : cells)  // trims blanks and a Windows line end
      while (!c.empty() && (c.back() == '\r' || c.back() == ' ')) c.pop_back();
    return cells;
  };
  std::string line;
  if (!std::getline(in, line)) throw TrajectoryError(path + ": empty file (a header with 'time' and '<joint>.position' columns is needed)");
  const std::vector<std::string> header = split(line);
  int time_col = -1;
  std::vector<int> pos_col, vel_col;
  Trajectory traj;
  auto column = [&](const std::string& name) {
    for (size_t c = 0; c < header.size(); ++c)
      if (header[c] == name) return static_cast<int>(c);
    return -1;
  };
  const std::string kPos = ".position";
  for (size_t c = 0; c < header.size(); ++c) {
    const std::string& h = header[c];
    if (h == "time") time_col = static_cast<int>(c);
    if (h.size() > kPos.size() && h.compare(h.size() - kPos.size(), kPos.size(), kPos) == 0 && h != "constraint.position") {
      traj.dofs.push_back(h.substr(0, h.size() - kPos.size()));
      pos_col.push_back(static_cast<int>(c));
      const int v = column(traj.dofs.back() + ".velocity");
      if (v >= 0) vel_col.push_back(v);
    }
  }
  if (time_col < 0) throw TrajectoryError(path + ":1: no 'time' column");
  if (traj.dofs.empty()) throw TrajectoryError(path + ":1: no '<joint>.position' column");
  if (!vel_col.empty() && vel_col.size() != pos_col.size())
    throw TrajectoryError(path + ":1: '<joint>.velocity' columns for some joints, not all");
  int number = 1;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty() || line == "\r") continue;
    const std::vector<std::string> cells = split(line);
    const std::string where = path + ":" + std::to_string(number) + ": ";
    if (cells.size() != header.size())
      throw TrajectoryError(where + std::to_string(cells.size()) + " values for " + std::to_string(header.size()) + " columns");
    auto value = [&](int c) {
      char* end = nullptr;
      const double x = std::strtod(cells[c].c_str(), &end);
      if (cells[c].empty() || *end != '\0') throw TrajectoryError(where + "'" + header[c] + "': '" + cells[c] + "' is not a number");
      if (!std::isfinite(x)) throw TrajectoryError(where + "'" + header[c] + "' is not finite");
      return x;
    };
    traj.times.push_back(value(time_col));
    traj.positions.emplace_back();
    for (int c : pos_col) traj.positions.back().push_back(value(c));
    if (!vel_col.empty()) {
      traj.velocities.emplace_back();
      for (int c : vel_col) traj.velocities.back().push_back(value(c));
    }
    if (traj.times.size() > 1 && !(traj.times.back() > traj.times[traj.times.size() - 2]))
      throw TrajectoryError(where + "times must increase (" + fmt6(traj.times.back()) + " s after " +
                            fmt6(traj.times[traj.times.size() - 2]) + " s)");
  }
  if (traj.times.empty()) throw TrajectoryError(path + ": no point (only a header)");
  return traj;
}

}  // namespace mechanism_sim
