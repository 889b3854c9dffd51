// What the Python module (doc/python.md) holds per loaded model: the MechanismModel, plus
// what the simulate CLI reports about a run (src/cli/simulate.cpp): steps taken, wall
// time, the largest violations at any step, each drive's peak effort and each actuator's
// sizing (as RunLoop tracks them), so that summary() prints the CLI's line. ROS-free and Python-free: the
// bindings (module.cpp) only convert.
#pragma once
#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "mechanism_sim/urdf/model.h"
#include "mechanism_sim/urdf/run_loop.h"

namespace mechanism_sim {
namespace python {

// Everything a Simulation is at one instant: the core's State, the commanded efforts and
// the run's record. restore() of it continues bit-identically.
struct SimulationSnapshot {
  Mechanism::Snapshot state;
  std::vector<double> command;
  long steps = 0;
  double last_h = 0.0, worst_position = 0.0, worst_velocity = 0.0;
  std::vector<DrivePeak> peaks;
  std::vector<ActuatorSizing> sizing;
};

class Simulation {
 public:
  // path: the file as given (the summary's prefix, as simulate prints it).
  Simulation(std::unique_ptr<MechanismModel> model, std::string path);

  // The saturating mode on or off from now (MechanismModel::setActuatorLimits; the sizing
  // record goes on, and records the lags while it is on).
  std::string setActuatorLimits(bool on) { return model_->setActuatorLimits(on); }
  MechanismModel& model() { return *model_; }
  const MechanismModel& model() const { return *model_; }
  const std::string& path() const { return path_; }

  // ---- running (the GIL is released around these by the bindings)
  // n steps of h; each updates the largest violations and the drives' peaks.
  void step(double h, long n);
  // round(duration / h) steps of h, as simulate --duration --dt takes them.
  long advance(double duration, double h);

  // Dof by name, or std::invalid_argument naming it (`what`: the caller's word for it).
  int dof(const std::string& name, const std::string& what) const;
  void setEffort(const std::string& dof, double tau);
  // Assembly onto the constraints holding the given dof positions and velocities, as the
  // loader does for simulate --set and --velocity: the other dofs' positions move as little
  // as the loops allow (tracked angles keep their turns), and the velocities not given are
  // the mass-orthogonal projection of the bodies' own. The run's record carries on. Throws
  // ModelError from the core (the state is then as it was).
  void setState(const std::vector<std::pair<std::string, double>>& positions,
                const std::vector<std::pair<std::string, double>>& velocities);

  SimulationSnapshot snapshot() const;
  void restore(const SimulationSnapshot& s);
  void reset();  // the model's initial state, commands zeroed, the record restarted

  long steps() const { return steps_; }
  double wallTime() const { return wall_; }
  // as RunLoop's: every equation at the start and now, those a step can leave violated
  // after every step
  double worstPositionViolation() const { return std::max(worst_position_, model_->positionViolation()); }
  double worstVelocityViolation() const { return std::max(worst_velocity_, model_->velocityViolation()); }
  const std::vector<DrivePeak>& drivePeaks() const { return peaks_; }
  // Per actuator (MechanismModel::actuators()), its operating points at every step since
  // loading or reset() against its ratings, as RunLoop's.
  const std::vector<ActuatorSizing>& actuatorSizing() const { return sizing_; }
  // The lines simulate prints on stderr after a run of these steps: "PATH: assembled to
  // ...; solver: ...", the actuators' sizing lines and "PATH: NOTE" per note
  // (newline-terminated).
  std::string summary() const;

 private:
  void restartRecord();
  void track();
  void trackPeaks();
  std::vector<CoordinateTarget> targets(const std::vector<std::pair<std::string, double>>& values,
                                        const std::string& what) const;

  std::unique_ptr<MechanismModel> model_;
  std::string path_;
  long steps_ = 0;
  double last_h_ = 0.0, wall_ = 0.0, worst_position_ = 0.0, worst_velocity_ = 0.0;
  std::vector<DrivePeak> peaks_;
  std::vector<ActuatorSizing> sizing_;
};

}  // namespace python
}  // namespace mechanism_sim
