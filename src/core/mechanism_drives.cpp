// Mechanism: drives added, removed and given paths after build() (mechanism.h). A new or
// removed drive changes the System's layout (one equation more or less), so the System is
// rebuilt from a copy (the one a snapshot or a Stepper refers to never changes), the
// State is carried over row by row, and a new Stepper evaluates it.
#include <cmath>

#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/mechanism.h"
#include "core/absolute/stepper.h"
#include "core/assembly/assembly.h"
#include "core/formulation.h"
#include "core/reaction_solve.h"
#include "core/joint_space/joint_stepper.h"

namespace mechanism_sim {

int Mechanism::addDriveAfterBuild(int joint, int k, const DriveProfile& profile) {
  checkCoordinate(joint, k);
  const Joint& j = *sys_->joints[joint];
  if (!j.holonomicCoordinates())
    throw ModelError("joint '" + j.name() + "': a drive needs a position coordinate");
  if (driveOf(joint, k) >= 0) throw ModelError("joint '" + j.name() + "': the coordinate is already driven");
  if (profile.kind() != DriveProfile::Kind::kVelocity)
    throw ModelError("joint '" + j.name() + "': only a velocity drive can be added after build()");
  std::vector<DriveSpec> drives = sys_->drives;
  std::vector<int> from;
  for (int d = 0; d < numDrives(); ++d) from.push_back(d);
  from.push_back(-1);
  drives.push_back(DriveSpec{joint, k, profile, 0.0, 0});
  std::vector<DriveRamp> refs = state_.drive;
  // the coordinate goes on as it moves now: f = q + v (t - t_now)
  const double q = jointPosition(joint, k), v = jointVelocity(joint, k);
  refs.push_back(DriveRamp{state_.t, q, v, v, 0.0, nullptr});
  if (!replaceDrives(std::move(drives), from, std::move(refs)).empty())
    throw ModelError("joint '" + j.name() + "': cannot be driven: its motion follows from the other joints, "
                     "couplers and drives (the drive's equation depends on theirs)");
  return numDrives() - 1;
}

void Mechanism::removeDrive(int drive) {
  if (!built_) throw UsageError("Mechanism::removeDrive before build()");
  if (drive < 0 || drive >= numDrives()) throw UsageError("no such drive");
  std::vector<DriveSpec> drives;
  std::vector<int> from;
  std::vector<DriveRamp> refs;
  for (int d = 0; d < numDrives(); ++d)
    if (d != drive) drives.push_back(sys_->drives[d]), from.push_back(d), refs.push_back(state_.drive[d]);
  replaceDrives(std::move(drives), from, std::move(refs));
}

std::vector<int> Mechanism::replaceDrives(std::vector<DriveSpec> drives, const std::vector<int>& from,
                                          std::vector<DriveRamp> references) {
  completeState();  // (the copy below is solved again from its accelerations)
  const System& old = *sys_;
  auto sys = std::make_shared<System>(old);
  sys->drives = std::move(drives);
  sys->finalize();  // joints and couplers keep their places; drives and limits are laid out again
  // The State, row by row: each constraint of the new System from its old one (-1: new).
  State s = state_;
  s.tracked.clear();
  s.lambda = Eigen::VectorXd::Zero(sys->m);
  s.dropped.assign(sys->m, 0);
  for (int c = 0; c < sys->numConstraints(); ++c) {
    const Constraint& con = *sys->constraints[c];
    int was = c;
    if (con.drive() >= 0)
      was = from[con.drive()] >= 0 ? old.drives[from[con.drive()]].constraint : -1;
    else if (con.limit() >= 0)
      was = old.limits[con.limit()].constraint;
    s.tracked.push_back(was >= 0 ? state_.tracked[was] : con.initialTracked());
    if (was < 0) continue;
    const ConstraintLayout &L = sys->layout[c], &L0 = old.layout[was];
    s.lambda.segment(L.row, L.size) = state_.lambda.segment(L0.row, L0.size);
  }
  s.drive = std::move(references);
  // Assembly finds the dependent equations at this pose (it moves nothing that already
  // satisfies the equations: the new drives start where their coordinates are); then the
  // accelerations and multipliers are solved with the new equations.
  // the formulation asked for must run the new System ("joint" refuses one it cannot run
  // here, the mechanism unchanged; "auto" turns to absolute)
  chooseFormulation(*sys, parseFormulation(sys->options.formulation), nullptr);
  auto stepper = std::make_unique<Stepper>(*sys);
  DependencyReport deps;
  mechanism_sim::assemble(*sys, s, *stepper, {}, {}, &deps);
  std::vector<int> dependent;
  for (size_t d = 0; d < sys->drives.size(); ++d)
    if (from[d] < 0 && s.dropped[sys->layout[sys->drives[d].constraint].row]) dependent.push_back(static_cast<int>(d));
  if (!dependent.empty()) return dependent;
  stepper->settle(*sys, s, inputs_);
  stateChanged();
  sys_ = std::move(sys);
  state_ = std::move(s);
  stepper_ = std::move(stepper);
  reactions_.reset();
  query_eval_.reset();
  dependencies_ = deps;
  joint_.reset();  // (a JointStepper is of one System)
  running_ = nullptr;
  useFormulation(true);
  return {};
}

void Mechanism::commandDrivePath(int drive, std::shared_ptr<const DrivePath> path) {
  if (!built_) throw UsageError("Mechanism::commandDrivePath before build()");
  const DriveSpec& D = sys_->drives.at(drive);
  if (D.profile.kind() != DriveProfile::Kind::kVelocity)
    throw UsageError("joint '" + sys_->joints[D.joint]->name() +
                                "': its drive follows a profile; only a velocity drive takes a path");
  if (!path) throw UsageError("commandDrivePath: no path");
  stateChanged();
  const DriveLag lag = state_.drive[drive].lag;  // (a drive held back stays behind the path)
  state_.drive[drive] = DriveRamp{state_.t, 0.0, 0.0, 0.0, 0.0, std::move(path)};
  state_.drive[drive].lag = lag;
  // the accelerations and the driving effort of the new reference, now (queries read them)
  stepper_->settle(*sys_, state_, inputs_);
}

// q_ddot_k = q_x,k a - gamma_k: the coordinate's row (joint.h) on the bodies' accelerations
// (State::acc: per moving body r_ddot, w_dot').
double Mechanism::jointAcceleration(int joint, int k) const {
  checkCoordinate(joint, k);
  const int i = treeCoordinate(joint, true);  // (the joint formulation's own q_ddot)
  if (i >= 0) return state_.qddot[i + k];
  const Row& row = coordinateRows(joint)[k];
  completeState();
  return rowDot(*sys_, joint, row, state_.acc.data()) - row.gamma;
}

}  // namespace mechanism_sim
