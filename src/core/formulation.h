// The two formulations as the facade sees them: one stepper interface, and the choice of
// which one runs a System.
#pragma once
#include <memory>
#include <string>

#include <Eigen/Core>

#include "mechanism_sim/core/model/system.h"
#include "mechanism_sim/core/model/tableau.h"
#include "mechanism_sim/core/reports.h"

namespace mechanism_sim {

struct Evaluation;
struct TreeReactionWorkspace;

// What the Mechanism asks of the formulation that runs: the absolute one
// (absolute/stepper.h, the seed's method on every body) or the joint one
// (joint_space/joint_stepper.h, the tree in joint coordinates, its loops closed by the same
// equations).
class FormulationStepper {
 public:
  virtual ~FormulationStepper() = default;
  // The integrator from here on.
  virtual void setMethod(Method m) = 0;
  // Brings the formulation's own state in s to s's absolute state (an assembled or restored
  // State) and solves the accelerations there.
  virtual void settle(const System& sys, State& s, const Inputs& in) = 0;
  // Advances s by h under the inputs. Throws StepFailure or SimulationError when the run
  // cannot go on, UsageError for an h that is not positive and finite; s is then as it was.
  virtual void step(const System& sys, State& s, const Inputs& in, double h) = 0;
  // Solves the accelerations and multipliers of s again at its positions and velocities
  // (a drive's reference changed: its DriveLag), s's evaluation and factorization kept
  // where they describe it. After step() or settle().
  virtual void resolve(const System& sys, State& s, const Inputs& in) = 0;
  virtual const SolverStats& stats() const = 0;
  // Makes a State of either formulation (a snapshot restored) this one's: the joint
  // formulation settles its joint state from the absolute one where it has none; the
  // absolute one drops the joint state.
  virtual void adopt(const System& sys, State& s, const Inputs& in) = 0;
  // The inputs or the System changed: what the stepper keeps of s is not reused.
  virtual void invalidate() {}
  // The largest |Phi| and |Phi_q v| of the equations a step can leave violated at s, when
  // the stepper knows them cheaply for s (else false: the caller evaluates every equation).
  virtual bool stepViolation(const State& s, double& position, double& velocity) const {
    (void)s, (void)position, (void)velocity;
    return false;
  }
  // Writes what a step left pending in s (State::bodies_pending) from s's own state; a
  // formulation that leaves nothing pending has nothing to do.
  virtual void completeState(State& s) { (void)s; }
  // The System's damping changed (its layout did not).
  virtual void dampingChanged(const System& sys) { (void)sys; }
  // Where the State keeps joint `joint`'s coordinates as its own (its rates with `rate`):
  // their first index in s.q (s.qdot), or -1 where they are only the joint's equations'
  // values at s's poses.
  virtual int stateCoordinate(const State& s, int joint, bool rate) const {
    (void)s, (void)joint, (void)rate;
    return -1;
  }
  // The multipliers of every System row at s for the reactions, in the absolute
  // formulation's rows and sign, with the evaluation whose Jacobian goes with them, in
  // `lambda` and `*with` (scratch: the caller's query workspace, made when first needed).
  // False where the multipliers are the absolute formulation's at s (the caller's).
  virtual bool reactionMultipliers(const System& sys, const State& s, const Inputs& in,
                                   std::unique_ptr<TreeReactionWorkspace>& scratch, Eigen::VectorXd& lambda,
                                   const Evaluation** with) const {
    (void)sys, (void)s, (void)in, (void)scratch, (void)lambda, (void)with;
    return false;
  }
};

// The formulation that runs sys when `asked` is requested, and why (one sentence). kJoint
// for a System the joint formulation cannot run throws ModelError with the reason; kAuto
// takes the joint formulation where it runs and its drives are at most one per 2 tree
// coordinates (each is a closure row through its absolute equations), else absolute.
Formulation chooseFormulation(const System& sys, Formulation asked, std::string* why);

}  // namespace mechanism_sim
