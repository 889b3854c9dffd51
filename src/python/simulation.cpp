#include "simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace mechanism_sim {
namespace python {

Simulation::Simulation(std::unique_ptr<MechanismModel> model, std::string path)
    : model_(std::move(model)), path_(std::move(path)) {
  restartRecord();
}

// As RunLoop::restartWorst: the record starts with the state as it is.
void Simulation::restartRecord() {
  steps_ = 0;
  wall_ = 0.0;
  worst_position_ = model_->positionViolation();
  worst_velocity_ = model_->velocityViolation();
  peaks_.clear();
  for (size_t d = 0; d < model_->dofs().size(); ++d)
    if (model_->dofs()[d].drive >= 0) peaks_.push_back(DrivePeak{static_cast<int>(d), 0.0, model_->time()});
  sizing_.clear();
  for (const Actuator& a : model_->actuators()) sizing_.emplace_back(a.name, a.ratings);
  trackPeaks();
}

// As RunLoop::advance, after every step: the equations a step can leave violated (every one
// at the state now: worstPositionViolation(), as RunLoop's), then the peaks.
void Simulation::track() {
  worst_position_ = std::max(worst_position_, model_->stepPositionViolation());
  worst_velocity_ = std::max(worst_velocity_, model_->stepVelocityViolation());
  trackPeaks();
}

// As RunLoop::trackPeaks: the drives' peak efforts and the actuators' sizing.
void Simulation::trackPeaks() {
  for (DrivePeak& p : peaks_) {
    const double e = model_->effort(p.dof);
    if (std::fabs(e) > std::fabs(p.effort)) p.effort = e, p.time = model_->time();
  }
  for (size_t a = 0; a < sizing_.size(); ++a) {
    const ActuatorState st = model_->actuatorState(static_cast<int>(a));
    sizing_[a].add(model_->time(), st.velocity, st.torque);
    if (model_->actuatorLimits()) sizing_[a].addLag(model_->time(), st.lag, st.saturated);
  }
}

void Simulation::step(double h, long n) {
  if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("the step h must be a positive finite number");
  if (n < 0) throw std::invalid_argument("the number of steps must not be negative");
  const auto start = std::chrono::steady_clock::now();
  try {
    for (long s = 0; s < n; ++s) {
      model_->step(h);
      ++steps_;
      last_h_ = h;
      track();
    }
  } catch (...) {
    wall_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    throw;
  }
  wall_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

long Simulation::advance(double duration, double h) {
  if (!(duration >= 0) || !std::isfinite(duration)) throw std::invalid_argument("the duration must be a finite number >= 0");
  if (!(h > 0) || !std::isfinite(h)) throw std::invalid_argument("the step h must be a positive finite number");
  if (duration / h > 1e10) throw std::invalid_argument("duration / h is more than 1e10 steps");
  const long n = std::lround(duration / h);  // as simulate: lround(--duration / --dt)
  step(h, n);
  return n;
}

int Simulation::dof(const std::string& name, const std::string& what) const {
  const int d = model_->dofIndex(name);
  if (d < 0) throw std::invalid_argument(path_ + ": " + what + " names no joint degree of freedom '" + name + "'");
  return d;
}

void Simulation::setEffort(const std::string& name, double tau) { model_->setEffort(dof(name, "effort"), tau); }

std::vector<CoordinateTarget> Simulation::targets(const std::vector<std::pair<std::string, double>>& values,
                                                  const std::string& what) const {
  std::vector<CoordinateTarget> out;
  for (const auto& v : values) {
    const Dof& d = model_->dofs()[dof(v.first, what)];
    if (d.gimbal >= 0)
      throw std::invalid_argument(path_ + ": " + what + " of '" + v.first + "': " +
                                  model_->whyPassive(dof(v.first, what)) + " (its ball is placed at load, by its first joint's name with .x, .y, .z: doc/robots.md)");
    if (!std::isfinite(v.second)) throw std::invalid_argument(path_ + ": " + what + " of '" + v.first + "' is not finite");
    out.push_back(CoordinateTarget{d.joint_index, d.k, v.second});
  }
  return out;
}

void Simulation::setState(const std::vector<std::pair<std::string, double>>& positions,
                          const std::vector<std::pair<std::string, double>>& velocities) {
  const std::vector<CoordinateTarget> p = targets(positions, "position"), v = targets(velocities, "velocity");
  for (const auto& t : velocities)  // as the loader: a driven dof's velocity is its drive's
    if (model_->dofs()[model_->dofIndex(t.first)].drive >= 0)
      throw std::invalid_argument(path_ + ": velocity of '" + t.first + "' given, but it is driven (its velocity is the drive's)");
  const Mechanism::Snapshot before = model_->mechanism().snapshot();
  try {
    model_->mechanism().assemble(p, v);
  } catch (const ModelError& e) {
    model_->mechanism().restore(before);  // a pose that does not close leaves the state as it was
    throw ModelError(path_ + ": " + e.what());
  } catch (...) {
    model_->mechanism().restore(before);
    throw;
  }
}

SimulationSnapshot Simulation::snapshot() const {
  SimulationSnapshot s;
  s.state = model_->mechanism().snapshot();
  for (size_t d = 0; d < model_->dofs().size(); ++d) s.command.push_back(model_->commandedEffort(static_cast<int>(d)));
  s.steps = steps_;
  s.last_h = last_h_;
  s.worst_position = worst_position_;
  s.worst_velocity = worst_velocity_;
  s.peaks = peaks_;
  s.sizing = sizing_;
  return s;
}

void Simulation::restore(const SimulationSnapshot& s) {
  if (s.command.size() != model_->dofs().size()) throw std::invalid_argument("the snapshot is of another model");
  model_->mechanism().restore(s.state);  // throws std::invalid_argument for another mechanism
  // the commands were clamped when set: setting them again leaves them as they were
  for (size_t d = 0; d < s.command.size(); ++d) model_->setEffort(static_cast<int>(d), s.command[d]);
  steps_ = s.steps;
  last_h_ = s.last_h;
  worst_position_ = s.worst_position;
  worst_velocity_ = s.worst_velocity;
  peaks_ = s.peaks;
  sizing_ = s.sizing;
}

void Simulation::reset() {
  model_->reset();
  last_h_ = 0.0;
  restartRecord();
}

// simulate's summary (runSummary, run_loop.h) and the notes; test_python.py compares the two
// line by line.
std::string Simulation::summary() const {
  const std::string line = runSummary(*model_, steps_, last_h_, wall_, worstPositionViolation(), worstVelocityViolation(), peaks_);
  std::string out = path_ + ": " + line + "\n";
  // as simulate: each actuator described sized, the others counted
  int undescribed = 0;
  for (size_t a = 0; a < sizing_.size(); ++a) {
    if (!ratingsGiven(model_->actuators()[a].ratings)) ++undescribed;
    else out += path_ + ": " + sizing_[a].describe() + "\n";
  }
  if (undescribed)
    out += path_ + ": " + std::to_string(undescribed) + " actuators without ratings (their motor_* columns are in the CSV)\n";
  for (const std::string& note : model_->notes()) out += path_ + ": " + note + "\n";
  return out;
}

}  // namespace python
}  // namespace mechanism_sim
