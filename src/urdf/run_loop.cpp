#include "mechanism_sim/urdf/run_loop.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

namespace mechanism_sim {

RunLoop::RunLoop(MechanismModel& model, double h, long steps_per_sample)
    : model_(model), h_(h), steps_per_sample_(steps_per_sample) {
  if (!(h > 0)) throw UsageError("the step must be positive");
  if (steps_per_sample < 1) throw UsageError("a sample needs at least one step");
  const size_t dofs = model.dofs().size();
  sample_.position.resize(dofs);
  sample_.velocity.resize(dofs);
  sample_.effort.resize(dofs);
  sample_.link_poses.resize(model.links().size());
  sample_.actuators.resize(model.actuators().size());
  restartWorst();
  takeSample();
}

void RunLoop::advance(long steps, const std::function<void()>& tick) {
  const auto start = std::chrono::steady_clock::now();
  for (long s = 1; s <= steps; ++s) {
    model_.step(h_);
    ++steps_;
    // (the equations a step can leave violated; every equation: worstPositionViolation())
    worst_position_ = std::max(worst_position_, model_.stepPositionViolation());
    worst_velocity_ = std::max(worst_velocity_, model_.stepVelocityViolation());
    trackPeaks();
    if (tick && (steps_ & 63) == 0) tick();
  }
  if (steps > 0)
    step_wall_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / steps;
  takeSample();
}

void RunLoop::reset() {
  model_.reset();
  steps_ = 0;
  restartWorst();
  takeSample();
}

void RunLoop::restartWorst() {
  worst_position_ = model_.positionViolation();
  worst_velocity_ = model_.velocityViolation();
  peaks_.clear();
  for (size_t d = 0; d < model_.dofs().size(); ++d)
    if (model_.dofs()[d].drive >= 0) peaks_.push_back(DrivePeak{static_cast<int>(d), 0.0, model_.time()});
  sizing_.clear();
  for (const Actuator& a : model_.actuators()) {
    sizing_.emplace_back(a.name, a.ratings);
    sizing_.back().keepPoints(keep_points_);
  }
  trackPeaks();
}

void RunLoop::trackPeaks() {
  for (DrivePeak& p : peaks_) {
    const double e = model_.effort(p.dof);
    if (std::fabs(e) > std::fabs(p.effort)) p.effort = e, p.time = model_.time();
  }
  for (size_t a = 0; a < sizing_.size(); ++a) {
    const ActuatorState s = model_.actuatorState(static_cast<int>(a));
    sizing_[a].add(model_.time(), s.velocity, s.torque);
    if (model_.actuatorLimits()) sizing_[a].addLag(model_.time(), s.lag, s.saturated);
  }
}

void RunLoop::setReactions(bool on) {
  reactions_ = on;
  takeSample();
}

void RunLoop::takeSample() {
  sample_.time = model_.time();
  for (size_t d = 0; d < sample_.position.size(); ++d) {
    const int i = static_cast<int>(d);
    sample_.position[d] = model_.position(i);
    sample_.velocity[d] = model_.velocity(i);
    sample_.effort[d] = model_.effort(i);
  }
  for (size_t l = 0; l < sample_.link_poses.size(); ++l) sample_.link_poses[l] = model_.linkPose(static_cast<int>(l));
  sample_.position_violation = model_.positionViolation();
  sample_.velocity_violation = model_.velocityViolation();
  for (size_t a = 0; a < sample_.actuators.size(); ++a) sample_.actuators[a] = model_.actuatorState(static_cast<int>(a));
  if (reactions_) sample_.reactions = model_.jointReactions(), sample_.coupling_reactions = model_.couplingReactions();
  else sample_.reactions.clear(), sample_.coupling_reactions.clear();
}

std::string runSummary(const MechanismModel& model, long steps, double h, double wall, double worst_position,
                       double worst_velocity, const std::vector<DrivePeak>& peaks) {
  std::string drives;
  for (const DrivePeak& p : peaks) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "; drive '%s': peak effort %.4g at t = %.4g s", model.dofs()[p.dof].name.c_str(),
                  p.effort, p.time);
    drives += buf;
  }
  char line[1024];
  std::snprintf(line, sizeof line,
                "assembled to %.1e; %ld steps of %g s in %.3f s wall (real-time factor %.1f); largest "
                "violation %.2e (position), %.2e (velocity); %s%s; formulation: %s; solver: %s",
                model.assembly().position_residual, steps, h, wall, wall > 0 ? steps * h / wall : 0.0, worst_position,
                worst_velocity, model.dependencies().describe().c_str(), drives.c_str(),
                model.formulationReason().c_str(),
                model.solverStats().describe().c_str());
  return line;
}

}  // namespace mechanism_sim
