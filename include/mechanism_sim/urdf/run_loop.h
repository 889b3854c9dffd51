// The run loop that the simulate CLI and the node share: it advances a model by output
// samples of N steps of h and keeps what both report, the sample of the state (written as
// a CSV row, published as joint_states, tf and markers), the largest violations so far
// and the wall time per step. The node adds wall-clock pacing on top (src/node/pacer.h).
// ROS-free.
#pragma once
#include <algorithm>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "mechanism_sim/core/model/actuator_sizing.h"
#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {

// The state at one output time.
struct Sample {
  double time = 0.0;
  std::vector<double> position, velocity, effort;  // by dof, as MechanismModel::dofs()
  std::vector<Eigen::Isometry3d> link_poses;        // by link, as MechanismModel::links(); world frame
  double position_violation = 0.0, velocity_violation = 0.0;  // largest |Phi|, |Phi_q v|
  std::vector<JointReaction> reactions;  // when RunLoop::setReactions(true)
  std::vector<double> coupling_reactions;  // the same: per coupling, its multiplier
  std::vector<ActuatorState> actuators;  // by actuator, as MechanismModel::actuators()
};

// The largest |effort| a driven dof needed, and when.
struct DrivePeak {
  int dof = -1;
  double effort = 0.0, time = 0.0;
};

// The one-line summary of a run that simulate prints and the Python module's summary()
// returns (without the file name and the notes): assembly, steps, wall time, the largest
// violations, dependent equations, drives' peak efforts, the formulation and the solver.
std::string runSummary(const MechanismModel& model, long steps, double h, double wall, double worst_position,
                       double worst_velocity, const std::vector<DrivePeak>& peaks);

class RunLoop {
 public:
  // A sample every steps_per_sample steps of h seconds. Takes the first sample now.
  RunLoop(MechanismModel& model, double h, long steps_per_sample);

  // Advances one sample (steps_per_sample steps, or `steps` when given) and takes the
  // sample. `tick`, when given, is called whenever steps() reaches a multiple of 64 (for
  // a progress bar). Throws what MechanismModel::step throws; the model is
  // then at the last accepted step and the sample is not updated.
  void advance() { advance(steps_per_sample_); }
  void advance(long steps, const std::function<void()>& tick = {});
  // Back to the model's initial state; the step count and the largest violations start
  // again.
  void reset();

  const Sample& sample() const { return sample_; }
  double h() const { return h_; }
  long stepsPerSample() const { return steps_per_sample_; }
  long steps() const { return steps_; }  // since construction or reset()
  // Largest violations at any step since construction or reset() (the start included).
  // The largest violations since the start (or reset()): of every equation at the start
  // and at the latest sample, and after every step of those a step can leave violated
  // (MechanismModel::stepPositionViolation: every one in absolute coordinates, the
  // closures' in joint coordinates, where the tree's hold by construction).
  double worstPositionViolation() const { return std::max(worst_position_, sample_.position_violation); }
  double worstVelocityViolation() const { return std::max(worst_velocity_, sample_.velocity_violation); }
  double stepWallTime() const { return step_wall_; }  // seconds per step in the last advance
  // Joint reactions in every sample (off by default: they cost a solve where equations
  // are dependent).
  void setReactions(bool on);
  // Per driven dof, the largest |effort| at any step since construction or reset().
  const std::vector<DrivePeak>& drivePeaks() const { return peaks_; }
  // Per actuator (MechanismModel::actuators()), its operating points at every step since
  // construction or reset() against its ratings.
  const std::vector<ActuatorSizing>& actuatorSizing() const { return sizing_; }
  // Keep each actuator's operating points (ActuatorSizing::keepPoints), at most max_points
  // each, for --actuator-plot. Restarts the record: call it before the first advance.
  void keepActuatorPoints(size_t max_points) {
    keep_points_ = max_points;
    restartWorst();
  }
  MechanismModel& model() { return model_; }
  const MechanismModel& model() const { return model_; }

 private:
  void takeSample();
  void restartWorst();
  void trackPeaks();

  MechanismModel& model_;
  double h_;
  long steps_per_sample_;
  long steps_ = 0;
  double worst_position_ = 0.0, worst_velocity_ = 0.0, step_wall_ = 0.0;
  Sample sample_;
  bool reactions_ = false;
  std::vector<DrivePeak> peaks_;
  std::vector<ActuatorSizing> sizing_;
  size_t keep_points_ = 0;
};

}  // namespace mechanism_sim
