// The recursions over the joint-space tree (joint_space/tree.h): its kinematics, the
// articulated-body algorithm (forward dynamics; its first pass and the kinematics visit each
// link once), the recursive Newton-Euler pass (inverse dynamics), the composite rigid-body
// inertia and the body accelerations of given joint accelerations.
//
// Spatial algebra after Featherstone, "Rigid Body Dynamics Algorithms" (RBDA), Springer
// 2008, chapter 2 (joint_space/spatial.h).
#include <algorithm>
#include <cmath>

#include "core/joint_space/spatial.h"
#include "core/joint_space/tree.h"
#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/errors.h"

namespace mechanism_sim {

// ---- dynamics

namespace {

// The external force on body k in its own coordinates: gravity m g at the centre of mass
// (no moment there) and the Inputs' force (global) and torque (body components).
inline Vector6d externalForce(const System& sys, const TreeWorkspace& ws, int b, const Inputs* loads) {
  const Body& B = sys.bodies[b];
  const Matrix3d& A = ws.A[b - 1];
  Vector6d f;
  f.head<3>().setZero();
  Vector3d F = B.m * sys.gravity;
  if (loads) {
    F += loads->force[b];
    f.head<3>() = loads->torque[b];
  }
  f.tail<3>() = A.transpose() * F;
  return f;
}

// The external force on a moving body and the bodies welded to it, in its coordinates:
// gravity on the group, (mc x g'; m g') with g' = A^T g (joint_space/tree.h), and the Inputs'
// forces and torques on each member moved to it by X_{member,h}^T.
inline Vector6d groupExternalForce(const System& sys, const TreeLink& L, const TreeWorkspace& ws,
                                   const TreeModel& model, const Inputs* loads) {
  if (!L.composite) return externalForce(sys, ws, L.body, loads);
  const Vector3d gh = ws.A[L.body - 1].transpose() * sys.gravity;
  Vector6d f;
  f.head<3>() = L.mc.cross(gh);
  f.tail<3>() = L.mass * gh;
  if (loads) {
    f.head<3>() += loads->torque[L.body];
    f.tail<3>() += ws.A[L.body - 1].transpose() * loads->force[L.body];
    for (int m : L.welded) {
      const TreeLink& W = model.links[m - 1];
      Vector6d fm;
      fm.head<3>() = loads->torque[m];
      fm.tail<3>() = ws.A[m - 1].transpose() * loads->force[m];
      f += transformForceBack(W.Eh, W.rhoh, fm);
    }
  }
  return f;
}

// The Plucker transform X_{k, aparent} from a moving link's articulated parent (its parent,
// or the host its parent is welded to) to the link: ws's own (E_k, rho_k), read in place,
// or X_k X_{parent,h} composed here when the parent is welded.
struct ArticulatedTransform {
  ArticulatedTransform(const TreeModel& model, const TreeWorkspace& ws, int k) {
    const TreeLink& L = model.links[k];
    if (!L.parent_welded) {
      E = &ws.E[k], rho = &ws.rho[k];
      return;
    }
    const TreeLink& P = model.links[L.parent - 1];
    E_composed.noalias() = ws.E[k] * P.Eh;
    rho_composed.noalias() = P.rhoh + P.Eh.transpose() * ws.rho[k];
    E = &E_composed, rho = &rho_composed;
  }
  ArticulatedTransform(const ArticulatedTransform&) = delete;
  ArticulatedTransform& operator=(const ArticulatedTransform&) = delete;
  const Matrix3d* E;
  const Vector3d* rho;

 private:
  Matrix3d E_composed;
  Vector3d rho_composed;
};

// A joint's articulated inertia S^T I^A S that is not positive definite: a subtree without
// inertia along the joint, or a state that is no longer finite (an explicit step taken
// beyond its stability: a whipping chain's rates grow by orders of magnitude a step).
[[noreturn]] void notPositive(const System& sys, const TreeLink& L, double D) {
  if (!std::isfinite(D))
    throw SimulationError("joint-space dynamics: the state is no longer finite at body '" + sys.bodies[L.body].name +
                          "' (the integration diverged: try a smaller step)");
  throw SimulationError("joint-space dynamics: the subtree at body '" + sys.bodies[L.body].name +
                        "' has no inertia along its joint");
}

// Pass 2 of forwardDynamicsAtKinematics at a tied link (TreeLink::tie): its motion is
// X v_parent + s q_dot_m with s = r S, so nothing is eliminated here; with
// [a; q_ddot_m] -> [f; (m's equation)] through [I^A W; W^T dd] and the bias (p^A; beta),
// the parent receives (T = [X s; 0 1])
//   I^A_p += X^T I^A X,  W_p += X^T (I^A s + W),  dd_p += s^T (I^A s + W) + s^T W + dd,
//   p^A_p += X^T (p^A + I^A c),  beta_p += (I^A s + W)^T c + s^T p^A + beta - r tau_s.
// (Jain, "Robot and Multibody Dynamics" ch. 11: constraint embedding.)
[[gnu::noinline]] void tiedLinkInward(const TreeModel& model, TreeWorkspace& ws, int k, double tau_s, Vector6d pa) {
  const TreeLink& L = model.links[k];
  const Matrix6d& IA = ws.IA[k];
  const Vector6d s = L.tie_mult * ws.S[k].col(0);
  const Vector6d Us = IA * s + ws.W[k];
  ws.Dinv[k](0, 0) = 0.0;
  ws.U[k].col(0) = Us;
  const int p = L.aparent - 1;
  const ArticulatedTransform X(model, ws, k);
  ws.W[p] += transformForceBack(*X.E, *X.rho, Us);
  ws.dd[p] += s.dot(Us) + s.dot(ws.W[k]) + ws.dd[k];
  ws.beta[p] += Us.dot(ws.c[k]) + s.dot(pa) + ws.beta[k] - L.tie_mult * tau_s;
  pa += IA * ws.c[k];
  addTransformedInertia(*X.E, *X.rho, IA, ws.IA[p]);
  ws.pA[p] += transformForceBack(*X.E, *X.rho, pa);
}

// Pass 2 at the common ancestor of a master's link and its sibling slaves (TreeLink::pivot),
// before its own joint: the tied coordinate is eliminated first, as a child's joint with
// U = W, D = dd, u = -beta would be: I^A -= W D^-1 W^T, p^A += W D^-1 u (no c_J of its own).
[[gnu::noinline]] void pivotInward(const System& sys, const TreeLink& L, int k, TreeWorkspace& ws, Vector6d& pa) {
  const double D = ws.dd[k];
  if (!(D > 0.0)) notPositive(sys, L, D);
  ws.tie_Dinv[k] = 1.0 / D, ws.tie_u[k] = -ws.beta[k];
  const Vector6d WD = ws.W[k] * ws.tie_Dinv[k];
  ws.IA[k].noalias() -= WD * ws.W[k].transpose();
  pa += WD * ws.tie_u[k];
}

// Rotors that couple coordinates (TreeModel::rotor_couplings): the joint-space inertia is
// M = M_a + U C U^T, M_a the articulated-body pass's (the armature on its diagonal), U a
// unit column e_i, e_j per coupling and C its block [0 B_01; B_01 0]. From q_ddot_a =
// M_a^-1 r the Woodbury identity gives q_ddot = M^-1 r exactly:
//   q_ddot = q_ddot_a - Y z,   (I + C U^T Y) z = C U^T q_ddot_a,   Y = M_a^-1 U,
// Y by inverse-mass passes on the factors in ws (as LoopClosures::applyInverseMass); then
// the bodies' accelerations a_i again from q_ddot (bodyAccelerations' pass).
[[gnu::noinline]] void coupleRotors(const TreeModel& model, TreeWorkspace& ws, Eigen::VectorXd& qddot) {
  const int m = static_cast<int>(ws.rotor_Y.cols());
  for (int col = 0; col < m; ++col) {
    const TreeModel::RotorCoupling& C = model.rotor_couplings[col / 2];
    double* y = ws.rotor_Y.col(col).data();
    std::fill(y, y + model.nv, 0.0);
    y[col % 2 == 0 ? C.i : C.j] = 1.0;
    for (int k = 0; k < model.nb; ++k) ws.rotor_p[k].setZero();
    for (int n = model.nb - 1; n >= 0; --n) inverseMassInward(model, ws, model.order[n] - 1, y, y, ws.rotor_p);
    articulatedOutward<false>(
        model, ws, [&](int k) { return Eigen::Map<const SmallVector>(y + model.links[k].iv, model.links[k].nv); },
        [&](int k) { return y[model.links[k].pivot]; }, y, ws.rotor_a);
  }
  // K = I + C U^T Y, r = C U^T q_ddot_a (row 2c of C U^T is B_01 e_j^T, row 2c + 1 B_01 e_i^T)
  for (int row = 0; row < m; ++row) {
    const TreeModel::RotorCoupling& C = model.rotor_couplings[row / 2];
    const int other = row % 2 == 0 ? C.j : C.i;
    for (int col = 0; col < m; ++col) ws.rotor_K(row, col) = (row == col ? 1.0 : 0.0) + C.inertia * ws.rotor_Y(other, col);
    ws.rotor_r(row) = C.inertia * qddot(other);
  }
  ws.rotor_lu.compute(ws.rotor_K);
  ws.rotor_z = ws.rotor_lu.solve(ws.rotor_r);
  qddot.noalias() -= ws.rotor_Y * ws.rotor_z;
  spatialAccelerations(model, ws, qddot);
}

// forwardDynamics with rotors that couple coordinates: the motors' coupled damping as the
// efforts -D_01 q_dot across (transmission.h), the articulated-body pass with the armature,
// then the coupling's inertia (coupleRotors).
[[gnu::noinline]] void coupledForwardDynamics(const TreeModel& model, const System& sys, const Eigen::VectorXd& q,
                                              const Eigen::VectorXd& qdot, const Eigen::VectorXd& tau, TreeWorkspace& ws,
                                              Eigen::VectorXd& qddot, const Inputs* loads) {
  forwardKinematics(model, q, qdot, ws);
  ws.rotor_tau = tau;
  for (const TreeModel::RotorCoupling& C : model.rotor_couplings) {
    ws.rotor_tau(C.i) -= C.damping * qdot(C.j);
    ws.rotor_tau(C.j) -= C.damping * qdot(C.i);
  }
  forwardDynamicsAtKinematics(model, sys, ws.rotor_tau, ws, qddot, loads);
  coupleRotors(model, ws, qddot);
}

// Pass 1 of the articulated-body algorithm at link k, its kinematics (RBDA 7.3, table 7.1's
// first loop): the pose of the child relative to its parent (E, rho) and in the world (A,
// r), its velocity v and the bias c (its parent's done first).
inline void linkKinematics(const TreeModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qdot,
                           TreeWorkspace& ws, int k) {
  const TreeLink& L = model.links[k];
  Vector6d vJ, cJ;
  // Child body axes in parent body axes (Rrel = Rp R Rc^T), and the child's centre
  // relative to the parent's (rho = sp + Rp t - Rrel sc).
  Matrix3d Rrel;
  if (L.welds()) {  // the constant pose (TreeModel); no joint motion
    Rrel = L.E0.transpose();
    ws.rho[k] = L.rho0;
    cJ.setZero();
    vJ.setZero();
  } else if (L.constant_S) {  // the common case: S constant in the child's frame (set once in ws), c_J = 0
    // R = Rz(+-q) (turning, helix) or 1 (sliding), t along z (jointTransform; reversed,
    // the inverse pose):
    // Rp Rz mixes two columns of Rp, the product's first factor done in 12 products
    // (TreeLink::Kc, Ks, K0: the pose's constant parts)
    const double qk = q(L.iq);
    double tz = 0.0;
    if (L.axis == AxisMotion::kSlide) {
      Rrel = L.Kc + L.K0;
      tz = L.reversed ? -qk : qk;  // (the inverse pose: -R^T t, and R^T z = z)
      ws.rho[k] = L.k0 - L.kc + tz * L.Rp.col(2);
    } else {
      const double angle = L.reversed ? -qk : qk, ca = std::cos(angle), sa = std::sin(angle);
      Rrel = ca * L.Kc + sa * L.Ks + L.K0;
      ws.rho[k] = L.k0 - ca * L.kc - sa * L.ks;
      if (L.axis == AxisMotion::kHelix) {
        tz = L.params.alpha * (qk - L.params.phi0);
        ws.rho[k] += (L.reversed ? -tz : tz) * L.Rp.col(2);
      }
    }
    cJ.setZero();
    vJ = ws.S[k].col(0) * qdot(L.iv);  // (S0, the workspace's since its construction)
  } else {
    MotionSubspace& S = ws.S[k];
    Matrix3d R;
    Vector3d t;
    jointTransform(L, q.data() + L.iq, qdot.data() + L.iv, R, t, S, cJ);
    // From the child's joint frame to its centre of mass: E = Rc, rho = -Rc^T sc, i.e.
    // (omega; v) -> (Rc omega; Rc v + sc x Rc omega).
    for (int col = 0; col < L.nv; ++col) {
      const Vector3d w = L.Rc * S.col(col).head<3>();
      S.col(col).tail<3>() = L.Rc * S.col(col).tail<3>() + L.sc.cross(w);
      S.col(col).head<3>() = w;
    }
    const Vector3d w = L.Rc * cJ.head<3>();
    cJ.tail<3>() = L.Rc * cJ.tail<3>() + L.sc.cross(w);
    cJ.head<3>() = w;
    vJ = S * qdot.segment(L.iv, L.nv);
    Rrel.noalias() = L.Rp * R * L.Rc.transpose();
    ws.rho[k] = L.sp + L.Rp * t - Rrel * L.sc;
  }
  ws.E[k] = Rrel.transpose();
  if (L.parent == 0) {
    ws.A[k] = Rrel;
    ws.r[k] = ws.rho[k];
    ws.v[k] = vJ;
  } else {
    const int p = L.parent - 1;
    ws.A[k].noalias() = ws.A[p] * Rrel;
    ws.r[k].noalias() = ws.r[p] + ws.A[p] * ws.rho[k];
    ws.v[k] = transformMotion(ws.E[k], ws.rho[k], ws.v[p]) + vJ;
  }
  // c_i = c_J + v_i x v_J (RBDA table 7.1)
  ws.c[k] = cJ + crossMotion(ws.v[k], vJ);
}

// Pass 1 of the articulated-body algorithm at link k, continued (after its kinematics):
// I^A_k = I_k, p^A_k = v_k x* I_k v_k - f^x_k (as table 7.1 starts them). Welded bodies are
// in their hosts' I_k and f^x_k (joint_space/tree.h): the passes skip them.
inline void articulatedStart(const TreeModel& model, const System& sys, TreeWorkspace& ws, int k,
                             const Inputs* loads) {
  const TreeLink& L = model.links[k];
  if (L.welds()) return;
  if (L.tie >= 0 || L.tie_master || L.pivot >= 0) ws.W[k].setZero(), ws.dd[k] = 0.0, ws.beta[k] = 0.0;
  if (L.composite) {
    ws.IA[k] = L.Ic0;
    ws.pA[k] = crossForce(ws.v[k], L.Ic0 * ws.v[k]) - groupExternalForce(sys, L, ws, model, loads);
    return;
  }
  const Body& B = sys.bodies[L.body];
  ws.IA[k].setZero();
  ws.IA[k].topLeftCorner<3, 3>() = B.Jp;
  ws.IA[k].bottomRightCorner<3, 3>().diagonal().setConstant(B.m);
  ws.pA[k] = crossForce(ws.v[k], inertiaTimes(B, ws.v[k])) - externalForce(sys, ws, L.body, loads);
}

// Passes 2 and 3 of the articulated-body algorithm, after pass 1 (linkKinematics,
// articulatedStart) at every link.
void articulatedPasses(const TreeModel& model, const System& sys, const Eigen::VectorXd& tau, TreeWorkspace& ws,
                       Eigen::VectorXd& qddot) {
  // Pass 2 (inward): U_i = I^A_i S_i, D_i = S_i^T U_i, u_i = tau_i - S_i^T p^A_i, and the
  // articulated inertia and bias the parent sees through the joint (RBDA 7.2-7.3, table
  // 7.1): I^a = I^A - U D^-1 U^T, p^a = p^A + I^a c + U D^-1 u.
  for (int n = model.nb - 1; n >= 0; --n) {
    const int k = model.order[n] - 1;
    const TreeLink& L = model.links[k];
    if (L.welds()) continue;
    Matrix6d& IA = ws.IA[k];
    Vector6d pa = ws.pA[k];
    if (L.tie >= 0) {  // (out of line, so that the common loop stays short)
      tiedLinkInward(model, ws, k, tau(L.iv), pa);
      continue;
    }
    if (L.pivot >= 0) pivotInward(sys, L, k, ws, pa);
    if (L.nv == 1) {  // the common case without the small-matrix machinery
      Vector6d U = IA * ws.S[k].col(0);
      double D = ws.S[k].col(0).dot(U) + model.armature[L.iv], u = tau(L.iv) - ws.S[k].col(0).dot(pa);
      if (L.tie_master) {  // the tied links' terms (above): U = I^A S + W, D, u
        U += ws.W[k];
        D = ws.S[k].col(0).dot(U) + ws.S[k].col(0).dot(ws.W[k]) + ws.dd[k] + model.armature[L.iv];
        u -= ws.beta[k];
      }
      if (!(D > 0.0)) notPositive(sys, L, D);
      const double Dinv = 1.0 / D;
      ws.U[k].col(0) = U;
      ws.Dinv[k](0, 0) = Dinv;
      ws.u[k](0) = u;
      if (L.aparent == 0) continue;
      IA.noalias() -= (U * Dinv) * U.transpose();
      pa += IA * ws.c[k] + U * (Dinv * u);
    } else {
      MotionSubspace& U = ws.U[k];
      U.noalias() = IA * ws.S[k];
      if (L.nv > 0) {
        SmallMatrix D = ws.S[k].transpose() * U;
        for (int i = 0; i < L.nv; ++i) D(i, i) += model.armature[L.iv + i];
        // D is symmetric positive definite when the subtree has mass along every joint
        // direction; LLT on at most 6 x 6 in place (no heap).
        Eigen::LLT<SmallMatrix> llt(D);
        if (llt.info() != Eigen::Success) notPositive(sys, L, D.sum());
        ws.Dinv[k] = llt.solve(SmallMatrix::Identity(L.nv, L.nv));
        // (element by element: the expression with tau.segment() would evaluate through a
        // heap temporary)
        for (int i = 0; i < L.nv; ++i) ws.u[k](i) = tau(L.iv + i) - ws.S[k].col(i).dot(pa);
      }
      if (L.aparent == 0) continue;
      if (L.nv > 0) {
        const MotionSubspace UD = U * ws.Dinv[k];
        IA.noalias() -= UD * U.transpose();
        pa += IA * ws.c[k] + UD * ws.u[k];
      } else {
        pa += IA * ws.c[k];
      }
    }
    // The parent accumulates X^T I^a X and X^T p^a (table 7.1, with X = i_X_lambda(i)).
    const int p = L.aparent - 1;
    const ArticulatedTransform X(model, ws, k);
    addTransformedInertia(*X.E, *X.rho, IA, ws.IA[p]);
    ws.pA[p] += transformForceBack(*X.E, *X.rho, pa);
  }
  // Pass 3 (outward): a'_i = X a_parent + c_i, q_ddot_i = D^-1 (u_i - U_i^T a'_i),
  // a_i = a'_i + S_i q_ddot_i (ground does not accelerate: gravity is a force here).
  qddot.resize(model.nv);
  articulatedOutward<true>(
      model, ws, [&](int k) -> const SmallVector& { return ws.u[k]; }, [&](int k) { return ws.tie_u[k]; },
      qddot.data(), ws.a);
}

}  // namespace

// Articulated-body algorithm, RBDA 7.3, table 7.1, in body coordinates: gravity enters as
// a force on each body (not as the base acceleration -a_g of the table), so the spatial
// accelerations a_i left in ws are the bodies' true ones.
void forwardDynamics(const TreeModel& model, const System& sys, const Eigen::VectorXd& q,
                     const Eigen::VectorXd& qdot, const Eigen::VectorXd& tau, TreeWorkspace& ws,
                     Eigen::VectorXd& qddot, const Inputs* loads) {
  if (model.rotors_coupled) {  // (out of line: the common path stays as short)
    coupledForwardDynamics(model, sys, q, qdot, tau, ws, qddot, loads);
    return;
  }
  // Pass 1 (outward), each link's kinematics and its start in one visit, then the rest
  ws.generation = nextWorkspaceGeneration();
  for (int b : model.order) {
    linkKinematics(model, q, qdot, ws, b - 1);
    articulatedStart(model, sys, ws, b - 1, loads);
  }
  articulatedPasses(model, sys, tau, ws, qddot);
}

void forwardKinematics(const TreeModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qdot,
                       TreeWorkspace& ws) {
  ws.generation = nextWorkspaceGeneration();
  for (int b : model.order) linkKinematics(model, q, qdot, ws, b - 1);
}

void forwardDynamicsAtKinematics(const TreeModel& model, const System& sys, const Eigen::VectorXd& tau,
                                 TreeWorkspace& ws, Eigen::VectorXd& qddot, const Inputs* loads) {
  ws.generation = nextWorkspaceGeneration();
  for (int b : model.order) articulatedStart(model, sys, ws, b - 1, loads);
  articulatedPasses(model, sys, tau, ws, qddot);
}

// Recursive Newton-Euler, RBDA 5.3, table 5.1 (gravity as a body force as above):
// a_i = X a_parent + S_i q_ddot_i + c_i, f_i = I_i a_i + v_i x* I_i v_i - f^x_i outward;
// tau_i = S_i^T f_i, f_parent += X^T f_i inward.
void inverseDynamics(const TreeModel& model, const System& sys, const Eigen::VectorXd& q,
                     const Eigen::VectorXd& qdot, const Eigen::VectorXd& qddot, TreeWorkspace& ws,
                     Eigen::VectorXd& tau, const Inputs* loads) {
  forwardKinematics(model, q, qdot, ws);
  for (int b : model.order) {
    const int k = b - 1;
    const TreeLink& L = model.links[k];
    const Body& B = sys.bodies[b];
    Vector6d a = ws.c[k] + ws.S[k] * qddot.segment(L.iv, L.nv);
    if (L.parent != 0) a += transformMotion(ws.E[k], ws.rho[k], ws.a[L.parent - 1]);
    ws.a[k] = a;
    ws.f[k] = inertiaTimes(B, a) + crossForce(ws.v[k], inertiaTimes(B, ws.v[k])) - externalForce(sys, ws, b, loads);
  }
  tau.resize(model.nv);
  for (int n = model.nb - 1; n >= 0; --n) {
    const int k = model.order[n] - 1;
    const TreeLink& L = model.links[k];
    tau.segment(L.iv, L.nv) = ws.S[k].transpose() * ws.f[k];
    if (L.parent != 0) ws.f[L.parent - 1] += transformForceBack(ws.E[k], ws.rho[k], ws.f[k]);
  }
}

// Composite-rigid-body algorithm, RBDA 6.2, table 6.2, in body coordinates: I^c_i = I_i +
// sum over children X^T I^c X; F = I^c_i S_i, H_ii = S_i^T F, then F moves to each ancestor
// j (F = X^T F) for H_ij = F^T S_j.
void jointSpaceInertia(const TreeModel& model, const TreeWorkspace& ws, AlignedVector<Matrix6d>& Ic,
                       Eigen::MatrixXd& H) {
  // (welded bodies are in their hosts' Ic0: the composites skip them, joint_space/tree.h; F
  // still moves through their transforms on the way to an ancestor)
  Ic.resize(model.nb);
  for (int b : model.order)
    if (!model.links[b - 1].welds()) Ic[b - 1] = model.links[b - 1].Ic0;
  for (int n = model.nb - 1; n >= 0; --n) {
    const int k = model.order[n] - 1;
    const TreeLink& L = model.links[k];
    if (L.welds() || L.aparent == 0) continue;
    const ArticulatedTransform X(model, ws, k);
    addTransformedInertia(*X.E, *X.rho, Ic[k], Ic[L.aparent - 1]);
  }
  for (int n = 0; n < model.nb; ++n) {
    const int k = model.order[n] - 1;
    const TreeLink& L = model.links[k];
    if (L.nv == 0) continue;
    MotionSubspace F = Ic[k] * ws.S[k];
    H.block(L.iv, L.iv, L.nv, L.nv).noalias() = ws.S[k].transpose() * F;
    for (int i = 0; i < L.nv; ++i) H(L.iv + i, L.iv + i) += model.armature[L.iv + i];
    for (int j = k; model.links[j].parent != 0;) {
      for (int c = 0; c < L.nv; ++c) F.col(c) = transformForceBack(ws.E[j], ws.rho[j], F.col(c));
      j = model.links[j].parent - 1;
      const TreeLink& P = model.links[j];
      for (int a = 0; a < L.nv; ++a)
        for (int c = 0; c < P.nv; ++c) H(L.iv + a, P.iv + c) = H(P.iv + c, L.iv + a) = F.col(a).dot(ws.S[j].col(c));
    }
  }
}

void jointEfforts(const TreeModel& model, const Inputs& in, Eigen::VectorXd& tau) {
  tau.setZero(model.nv);
  for (size_t j = 0; j < model.joint_link.size(); ++j) {
    if (model.joint_link[j] < 0) continue;  // a cut joint: its effort acts through the closure
    const TreeLink& L = model.links[model.joint_link[j]];
    for (int k = 0; k < L.nv; ++k) tau(L.iv + k) = in.effort[j][k];
  }
}

// The seed's absolute accelerations from the spatial ones: omega'_dot is the angular part
// (omega_dot = A_Oi omega'_dot, the omega' x omega' term vanishing); the centre of mass
// accelerates by v_O_dot + omega x v_O in body components (the spatial acceleration is
// not the classical one: RBDA ch. 2, spatial acceleration), rotated to global.
void spatialAccelerations(const TreeModel& model, TreeWorkspace& ws, const Eigen::VectorXd& qddot) {
  for (int b : model.order) {  // a_i = X a_parent + c_i + S_i q_ddot_i (RBDA table 7.1)
    const int k = b - 1;
    const TreeLink& L = model.links[k];
    Vector6d a = ws.c[k] + ws.S[k] * qddot.segment(L.iv, L.nv);
    if (L.parent != 0) a += transformMotion(ws.E[k], ws.rho[k], ws.a[L.parent - 1]);
    ws.a[k] = a;
  }
}

void bodyAccelerations(const TreeModel& model, TreeWorkspace& ws, const Eigen::VectorXd& qddot,
                       Eigen::VectorXd& acc) {
  acc.resize(6 * model.nb);
  spatialAccelerations(model, ws, qddot);
  for (int k = 0; k < model.nb; ++k) {
    const Vector6d& a = ws.a[k];
    acc.segment<3>(6 * k) = ws.A[k] * (a.tail<3>() + ws.v[k].head<3>().cross(ws.v[k].tail<3>()));
    acc.segment<3>(6 * k + 3) = a.head<3>();
  }
}

void positionRates(const TreeModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qdot,
                   Eigen::VectorXd& qrate) {
  if (model.nq == model.nv) {  // (no quaternion: q_dot itself)
    qrate = qdot;
    return;
  }
  qrate.resize(model.nq);
  for (const TreeLink& L : model.links) {
    if (L.quaternion < 0) {
      qrate.segment(L.iq, L.nq) = qdot.segment(L.iv, L.nv);
      continue;
    }
    // the coordinates before the quaternion are their own rates; the quaternion's rates are
    // an angular velocity w: in frame i d/dt q = 1/2 (0, w) (x) q, in the child's
    // d/dt q = 1/2 q (x) (0, w)
    const int n = L.quaternion;
    qrate.segment(L.iq, n) = qdot.segment(L.iv, n);
    Eigen::Vector4d w(0, qdot(L.iv + n), qdot(L.iv + n + 1), qdot(L.iv + n + 2));
    qrate.segment<4>(L.iq + n) = 0.5 * (L.quaternion_in_child ? quatProduct(q.segment<4>(L.iq + n), w)
                                                               : quatProduct(w, q.segment<4>(L.iq + n)));
  }
}

void normalizeQuaternions(const TreeModel& model, Eigen::VectorXd& q) {
  for (int iq : model.quaternions) q.segment<4>(iq).normalize();
}

}  // namespace mechanism_sim
