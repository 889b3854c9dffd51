// Joint trajectories (doc/trajectories.md): the node's ~joint_trajectory
// (trajectory_msgs/JointTrajectory) and simulate --trajectory FILE.csv. The named dofs
// become drives that follow a C2 path through the points (core drive.h DrivePath),
// starting from their current position, velocity and acceleration; the others keep their
// drives or stay free. ROS-free.
#pragma once
#include <stdexcept>
#include <string>
#include <vector>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {

// A trajectory that cannot be followed; what() is the reason, naming the dof or point.
class TrajectoryError : public UsageError {
 public:
  using UsageError::UsageError;
};

struct Trajectory {
  std::vector<std::string> dofs;               // MechanismModel::dofs() names
  std::vector<double> times;                   // of the points, from the start [s]
  std::vector<std::vector<double>> positions;  // [point][dof]
  // [point][dof], or empty: not given (then for every point)
  std::vector<std::vector<double>> velocities, accelerations;
};

// Default of ~trajectory_start_tolerance and simulate --trajectory-start-tolerance:
// how far the first point may lie from the current position [rad or m].
constexpr double kTrajectoryStartTolerance = 0.1;

// What can be judged without the current state: every dof known, not a mimic follower
// (a coupler's first joint), not driven by a profile of the model, named once; arrays of
// matching sizes, velocities and accelerations given for every point or none
// (accelerations only with velocities), values finite, times >= 0 and increasing.
// Throws TrajectoryError.
void checkTrajectory(const MechanismModel& model, const Trajectory& traj);

// The trajectory from `start` (simulation time of time 0 of its points; a start before
// now means now, dropping the points already past): after checkTrajectory, every first
// point within `start_tolerance` of its dof's current position, some point after now.
// Each named dof then follows DrivePath::through from its current motion (its drive's
// target when driven, else its position, velocity and acceleration) through the points
// after now; a free dof becomes driven (MechanismModel::driveDof). All or nothing: throws
// TrajectoryError with the model unchanged.
void followTrajectory(MechanismModel& model, const Trajectory& traj, double start, double start_tolerance);

// simulate --trajectory: a CSV with a `time` column and `<dof>.position` columns, and
// `<dof>.velocity` columns for all of them or none, as simulate --csv writes it (other
// columns, simulate's constraint.position and constraint.velocity included, are ignored).
// Throws TrajectoryError "FILE:LINE: what".
Trajectory readTrajectoryCsv(const std::string& path);

}  // namespace mechanism_sim
