// The closures' projections (loop_closure.h): positions onto Phi(q) = 0 by M-weighted
// least-norm Newton steps, rates onto G q_dot = nu by the M-nearest correction (RBDA 2008,
// 8.3, stabilisation), and the retraction q (+) dv they move q by.
#include <algorithm>
#include <cmath>

#include "core/joint_space/loop_closure.h"
#include "mechanism_sim/core/model/math.h"

namespace mechanism_sim {

double ClosureRows::correctionSize(const Eigen::VectorXd& dv) const {
  double size = 0.0;
  for (int k = 0; k < nv; ++k) size = std::max(size, std::fabs(dv(k)) * unit_(k));
  return size;
}

void retract(const TreeModel& model, Eigen::VectorXd& q, const Eigen::VectorXd& dv) {
  for (const TreeLink& L : model.links) {
    if (L.quaternion < 0) {
      for (int k = 0; k < L.nv; ++k) q(L.iq + k) += dv(L.iv + k);
      continue;
    }
    // a quaternion turns by exp(dv) on the side its rates are in (TreeJointModel), the
    // coordinates before it move by dv
    const int n = L.quaternion;
    for (int k = 0; k < n; ++k) q(L.iq + k) += dv(L.iv + k);
    const Eigen::Vector4d turn = quatExp(dv.segment<3>(L.iv + n));
    const Eigen::Vector4d p = L.quaternion_in_child ? quatProduct(q.segment<4>(L.iq + n), turn)
                                                    : quatProduct(turn, q.segment<4>(L.iq + n));
    q.segment<4>(L.iq + n) = p.normalized();
  }
}

ClosureProjectionReport projectClosurePositions(const TreeModel& model, const System& sys, LoopClosures& cl,
                                                Eigen::VectorXd& q, TreeWorkspace& ws, double tol, int max_iterations,
                                                const Eigen::VectorXd* rates, const ClosureSolveMode& mode) {
  ClosureProjectionReport rep;
  const Eigen::VectorXd& zero = cl.scratch_.zero_v;
  const Eigen::VectorXd& qdot = rates ? *rates : zero;
  Eigen::VectorXd &qdd = cl.scratch_.qdd_v, &dv = cl.scratch_.dv_v, &x = cl.scratch_.x_m;
  // Near a branch passage (branch_passage.cpp) the equations' residual tolerance leaves
  // the coordinate across the branch off by tol / s (s the passage's singular value), and
  // the solves at the next stages see the level set through that point: there Newton goes
  // on to round-off (while its step keeps halving) once the tolerance is met.
  double previous_step = HUGE_VAL;
  int extra = 0;
  for (;;) {
    // the kinematics the closures' equations read; the articulated factors (forwardDynamics)
    // only for a correction: the stepper's q is usually on the closures already
    forwardKinematics(model, q, qdot, ws);
    cl.evaluate(model, sys, ws, q);
    rep.at_rates = rates != nullptr;
    // in a branch passage the held directions are the integration's: not judged, not moved;
    // where they have left the round-off a crossing leaves, their closures are released
    // (branch_passage.cpp, "spells without a crossing")
    bool passage = mode.passage_ref && cl.findPassage(mode.passage_hold);
    if (passage && cl.passageDirections() > 0 && cl.heldResidual(cl.Phi, cl.scale) > tol && cl.releaseHeld())
      passage = cl.findPassage(mode.passage_hold);
    rep.residual = passage ? cl.passageResidual(cl.Phi, cl.scale) : cl.positionResidual();
    const bool near = mode.passage_ref && cl.passageNear();
    rep.converged = rep.residual <= tol;
    if (rep.converged && (!near || extra >= kPassageRoundoffSteps)) break;
    if (rep.iterations >= max_iterations) break;
    // M's factors at the same kinematics (they do not read the rates; qdd is not used)
    forwardDynamicsAtKinematics(model, sys, zero, ws, qdd);
    if (passage) {
      cl.passageFactor(model, ws);
      cl.passageRhs(cl.Phi, cl.passage_.g);
      cl.passageSolve(cl.passage_.g, cl.passage_.mu);
      cl.inverseMassRowsT(model, ws, cl.passage_.R, cl.passage_.mu, dv);
      dv = -dv;
      rep.dependent = cl.allRows() - cl.passage_.r;
    } else {
      cl.factor(model, ws, mode.form_Y);
      rep.dependent = cl.info.dependent;
      cl.solve(cl.Phi, x);
      cl.inverseMassRowsT(model, ws, cl.G, x, dv);
      dv = -dv;
    }
    if (rep.converged) {  // past the tolerance, near a passage: to round-off
      const double step = cl.correctionSize(dv);
      // (a step that is not round-off-sized is what a nearly dependent row does to a residual
      // that is round-off: not taken)
      if (!(step < 0.5 * previous_step) || step == 0.0 || step > kRoundoffStepBound * sys.length_scale) break;
      previous_step = step;
      ++extra;
    }
    retract(model, q, dv);
    ++rep.iterations;
  }
  // (the last evaluation is q's: a closure out of the band there ends its spell)
  if (mode.passage_ref) cl.endPassageSpells();
  return rep;
}

ClosureProjectionReport projectClosureVelocities(const TreeModel& model, const System& sys, LoopClosures& cl,
                                                 const Eigen::VectorXd& q, Eigen::VectorXd& qdot, TreeWorkspace& ws,
                                                 double tol, int max_iterations, bool evaluated_at_q, bool at_rates,
                                                 const ClosureSolveMode& mode) {
  ClosureProjectionReport rep;
  const Eigen::VectorXd& zero = cl.scratch_.zero_v;
  Eigen::VectorXd &qdd = cl.scratch_.qdd_v, &r = cl.scratch_.r_m, &x = cl.scratch_.x_m;
  if (!evaluated_at_q) {
    forwardKinematics(model, q, zero, ws);
    cl.evaluate(model, sys, ws, q);  // G depends on q only
  }
  Eigen::VectorXd& reference = cl.scratch_.ref_v;
  reference = qdot;
  Eigen::VectorXd& dv = cl.scratch_.dv_v;
  // in a branch passage (branch_passage.cpp) the regular directions onto their equations,
  // the held rates as the integration carried them, and near it on to round-off (as the
  // positions)
  // (evaluated_at_q: the position projection's last findPassage() was at this evaluation)
  const bool passage = mode.passage_ref && (evaluated_at_q ? cl.passageFound() : cl.findPassage(mode.passage_hold));
  // (factored at the first correction: a q_dot already on the closures, as the stepper's
  // usually is after its stages, needs no solve)
  bool factored = false;
  double previous_step = HUGE_VAL;
  int extra = 0;
  for (;;) {
    if (passage) {  // (judged as velocityResidual judges, without the held components)
      cl.velocityRows(qdot, &reference, r, cl.scratch_.vt);
      rep.residual = cl.passageResidual(r, cl.scratch_.vt);
    } else {
      rep.residual = cl.velocityResidual(qdot, &reference);
    }
    rep.converged = rep.residual <= tol;
    if (rep.converged && (!passage || !cl.passageNear() || extra >= kPassageRoundoffSteps)) break;
    if (rep.iterations >= max_iterations) break;
    if (!factored) {
      forwardDynamicsAtKinematics(model, sys, zero, ws, qdd);  // M's factors at q (the same kinematics)
      if (passage) {
        cl.passageFactor(model, ws);
        rep.dependent = cl.allRows() - cl.passage_.r;
      } else {
        cl.factor(model, ws, mode.form_Y);
        rep.dependent = cl.info.dependent;
      }
      factored = true;
    }
    if (passage) {
      cl.passageRhs(r, cl.passage_.g);
      cl.passageSolve(cl.passage_.g, cl.passage_.mu);
      cl.inverseMassRowsT(model, ws, cl.passage_.R, cl.passage_.mu, dv);
    } else {
      cl.rowsTimes(cl.G, qdot, r);
      r -= cl.nu;
      cl.solve(r, x);
      cl.inverseMassRowsT(model, ws, cl.G, x, dv);
    }
    if (rep.converged) {  // past the tolerance: a step only while it is round-off-sized and halving
      const double step = cl.correctionSize(dv), V = std::max(sys.velocity_scale, cl.correctionSize(qdot));
      if (!(step < 0.5 * previous_step) || step == 0.0 || step > kRoundoffStepBound * V) break;
      previous_step = step;
      ++extra;
    }
    qdot -= dv;
    ++rep.iterations;
  }
  rep.at_rates = evaluated_at_q && at_rates && rep.iterations == 0;  // (else q_dot moved: gamma is another's)
  if (!rep.at_rates) forwardKinematics(model, q, qdot, ws);
  return rep;
}

}  // namespace mechanism_sim
