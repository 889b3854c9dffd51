// The joint-space tree (joint_space/tree.h): its model (links, joint kinds, welded groups,
// embedded couplers), its workspace and the joints' transforms (jcalc); the recursions over
// it are in tree_dynamics.cpp.
//
// Spatial algebra after Featherstone, "Rigid Body Dynamics Algorithms" (RBDA), Springer
// 2008, chapter 2: motion vectors m = (omega; v_O), force vectors f = (n_O; f), both in
// Plucker coordinates of a frame. Every body's frame here is its centre-of-mass frame with
// the body's axes (the seed lecture's r_i and A_Oi), so a body's spatial velocity is
// (omega'_i; A_Oi^T r_dot_i) and its spatial inertia the block-diagonal diag(J'_i, m_i 1)
// (RBDA ch. 2, spatial inertia, with c = 0).
#include "core/joint_space/tree.h"
#include "core/joint_space/spatial.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>

#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/errors.h"

namespace mechanism_sim {
namespace {

// The free body's link (q = (r, p), q_dot = (v global, omega' body)): the body's spatial
// velocity is (omega'; A^T v), so S = [0 1; A^T 0] and c = (0; d(A^T)/dt v) =
// (0; -omega' x A^T v).
void freeBodyCalc(const JointParams&, const double* q, const double* qd, Matrix3d& R, Vector3d& t, MotionSubspace& S,
                  Vector6d& c) {
  R = Quaterniond(q[3], q[4], q[5], q[6]).normalized().toRotationMatrix();
  t = Vector3d(q[0], q[1], q[2]);
  S.bottomLeftCorner<3, 3>() = R.transpose();
  S.topRightCorner<3, 3>().setIdentity();
  const Vector3d w(qd[3], qd[4], qd[5]);
  c.tail<3>() = -w.cross(R.transpose() * Vector3d(qd[0], qd[1], qd[2]));
}

constexpr TreeJointModel freeBodyModel() {
  TreeJointModel m;
  m.kind = TreeJointKind::kFree;
  m.nq = 7, m.nv = 6;
  m.quaternion = 3;
  m.quaternion_in_child = true;
  m.lengths = 7;
  m.calc = &freeBodyCalc;
  return m;
}
constexpr TreeJointModel kFreeBody = freeBodyModel();

// The link's copy of its type's tree model.
void setModel(TreeLink& L, const TreeJointModel& m) {
  L.jmodel = &m;
  L.kind = m.kind;
  L.axis = m.axis;
  L.nq = m.nq, L.nv = m.nv;
  L.quaternion = static_cast<signed char>(m.quaternion);
  L.quaternion_in_child = m.quaternion_in_child;
}

// S in the child's centre-of-mass coordinates (forwardKinematics' transform of
// jointTransform's S, which for these does not depend on q).
void setConstantSubspace(TreeLink& L) {
  L.constant_S = L.nv == 1 && L.axis != AxisMotion::kNone;
  if (!L.constant_S) return;
  Matrix3d R;
  Vector3d t;
  MotionSubspace S;
  Vector6d c;
  const double q = L.params.phi0, qd = 0.0;
  jointTransform(L, &q, &qd, R, t, S, c);
  const Vector3d w = L.Rc * S.col(0).head<3>();
  L.S0.tail<3>() = L.Rc * S.col(0).tail<3>() + L.sc.cross(w);
  L.S0.head<3>() = w;
  // Rp Rz(a) Rc^T = sum_j (Rp Rz).col(j) Rc.col(j)^T with (Rp Rz).col(0) = cos Rp0 + sin Rp1,
  // (Rp Rz).col(1) = cos Rp1 - sin Rp0, (Rp Rz).col(2) = Rp2
  const Matrix3d& P = L.Rp;
  const Matrix3d& C = L.Rc;
  L.Kc = P.col(0) * C.col(0).transpose() + P.col(1) * C.col(1).transpose();
  L.Ks = P.col(1) * C.col(0).transpose() - P.col(0) * C.col(1).transpose();
  L.K0 = P.col(2) * C.col(2).transpose();
  L.kc = L.Kc * L.sc, L.ks = L.Ks * L.sc, L.k0 = L.sp - L.K0 * L.sc;
}

}  // namespace

// ---- the tree

std::string jointSpaceUnsupported(const System& sys, bool loops_as_closures) {
  if (sys.nb != sys.numBodies() - 1 || sys.nb < 1) return "the System is not finalized or has no moving body";
  std::vector<char> is_joint(sys.numConstraints(), 0);
  for (int c : sys.joint_constraint)
    if (c >= 0 && c < sys.numConstraints()) is_joint[c] = 1;
  // Couplers, drives and limits are closures (loop_closure.h) for a caller that takes them;
  // other constraint types are not known to the formulation.
  for (int c = 0; c < sys.numConstraints(); ++c) {
    if (is_joint[c]) continue;
    const std::string type = sys.constraints[c]->type();
    const bool closure_type = type == "coupler" || type == "coupling" || type == "drive" || type == "limit";
    if (!closure_type)
      return "constraint '" + sys.constraints[c]->name() + "' (" + type +
             "): the joint-space formulation has no model of this constraint type";
    if (!loops_as_closures)
      return "constraint '" + sys.constraints[c]->name() + "' (" + type +
             "): the caller does not take closures (couplers, couplings, drives and limits are closures, loop_closure.h)";
  }
  for (const Joint* J : sys.joints) {
    if (!treeJointModel(J->type()))
      return "joint '" + J->name() + "': the joint-space tree has no model of joint type '" + J->type() + "'";
    if (J->bodyI() == J->bodyJ()) return "joint '" + J->name() + "': joins a body to itself";
  }
  // Rotor inertias: on tree coordinates that no embedded coupler ties; one that couples two
  // coordinates (TreeModel::rotor_couplings) in a tree whose dynamics is forwardDynamics
  // alone: no closures, no Coulomb friction (their solves take the factors of M without the
  // coupling)
  if (!sys.rotors.empty()) {
    const TreeModel model(sys, true);
    for (const RotorInertia& R : sys.rotors) {
      if (R.coupled()) {
        const std::string what = "rotor inertia '" + R.name + "' couples two joints (" +
                                 sys.joints[R.coords[0].first]->name() + ", " + sys.joints[R.coords[1].first]->name() + ")";
        for (int c = 0; c < sys.numConstraints(); ++c)
          if (!is_joint[c])
            return what + " and constraint '" + sys.constraints[c]->name() + "' (" + sys.constraints[c]->type() +
                   ") is a closure: the joint-space closures take a diagonal rotor inertia and motor damping";
        if (!model.cut_joints.empty())
          return what + " and joint '" + sys.joints[model.cut_joints[0]]->name() +
                 "' closes a loop: the joint-space closures take a diagonal rotor inertia and motor damping";
        bool friction = !sys.sum_friction.empty();
        for (const auto& f : sys.friction) friction = friction || f[0] != 0.0 || f[1] != 0.0 || f[2] != 0.0;
        if (friction)
          return what + " and the mechanism has Coulomb friction: the joint-space friction takes a diagonal rotor "
                        "inertia and motor damping";
      }
      for (const auto& c : R.coords) {
        const int link = model.joint_link[c.first];
        if (link < 0 || model.links[link].tie >= 0 || model.links[link].tie_master)
          return "rotor inertia '" + R.name + "' on joint '" + sys.joints[c.first]->name() +
                 "', which closes a loop or is coupled: the joint-space recursions take rotors on free tree joints";
      }
    }
  }
  // Joints that close loops are cut joints, constraints on the tree (loop_closure.h), for
  // a caller that integrates them as such.
  if (!loops_as_closures) {
    const TreeModel model(sys);
    if (!model.cut_joints.empty())
      return "joint '" + sys.joints[model.cut_joints[0]]->name() +
             "' closes a loop: the caller does not take loop closures (loop_closure.h)";
  }
  return std::string();
}

// Couplers the recursions hold (TreeModel's embed_couplers, TreeLink::tie): links visited
// parents first, so a master's own tie (it may have none) and the ties of the links between
// it and a slave are settled when the slave is.
namespace {
void embedCouplers(const System& sys, TreeModel& model) {
  std::vector<std::vector<int>> as_slave(model.nb);  // per link: the couplers whose slave it carries
  auto linkOf = [&](const Joint& J) {
    for (int j = 0; j < sys.numJoints(); ++j)
      if (&*sys.joints[j] == &J) return model.joint_link[j];
    return -1;
  };
  for (int c = 0; c < sys.numConstraints(); ++c) {
    const auto* cc = dynamic_cast<const CoordinateCoupler*>(&*sys.constraints[c]);
    if (!cc || cc->coordinateA() != 0 || cc->coordinateB() != 0) continue;
    const int a = linkOf(cc->jointA()), b = linkOf(cc->jointB());
    if (a < 0 || b < 0 || a == b) continue;
    if (!model.links[a].constant_S || !model.links[b].constant_S) continue;  // (one coordinate, a constant axis)
    as_slave[a].push_back(c);
  }
  // the first moving link above k that is neither welded nor tied to master m
  auto above = [&](int k, int m) {
    k = model.links[k].parent - 1;
    while (k >= 0 && (model.links[k].welds() || model.links[k].tie == m))
      k = model.links[k].parent - 1;
    return k;
  };
  // a link that carries no group's terms and eliminates none: free to be a group's top
  auto unclaimed = [&](int k) {
    const TreeLink& T = model.links[k];
    return T.tie < 0 && !T.tie_master && T.pivot < 0;
  };
  for (int body : model.order) {
    const int a = body - 1;
    TreeLink& L = model.links[a];
    for (int c : as_slave[a]) {
      if (L.tie >= 0 || L.tie_master || L.pivot >= 0) break;  // (already a master's, or a top)
      const auto& cc = static_cast<const CoordinateCoupler&>(*sys.constraints[c]);
      const int m = linkOf(cc.jointB());
      TreeLink& M = model.links[m];
      if (M.tie >= 0 && M.tie != m) continue;  // (a master that is itself tied: a closure row)
      const int k = above(a, m);
      if (k == m && M.tie < 0 && M.pivot < 0) {  // the master's link is the slave's ancestor
        M.tie_master = true;
      } else {
        // siblings: both reach their common ancestor through welded or tied links only,
        // and it carries no other group (a master's own group eliminated at its link, or
        // another top's: those stay rows)
        if (k < 0 || M.tie_master || M.pivot >= 0 || above(m, m) != k) continue;  // (M a top already: a row)
        TreeLink& T = model.links[k];
        if (M.tie == m ? T.pivot_link != m : !unclaimed(k)) continue;
        if (M.tie < 0) M.tie = m, M.tie_mult = 1.0, M.tie_offset = 0.0;
        T.pivot = M.iv, T.pivot_link = m;
      }
      L.tie = m, L.tie_coupler = c, L.tie_mult = cc.multiplier(), L.tie_offset = cc.offset();
      model.ties.push_back(a);
      break;
    }
  }
}
}  // namespace

TreeModel::TreeModel(const System& sys, bool embed_couplers) {
  nb = sys.numBodies() - 1;
  if (sys.nb != nb || nb < 1)
    throw UsageError("TreeModel: the System must be finalized and have a moving body");
  // Constraints other than joints (couplers, drives, limits), springs, joint damping and
  // friction are not the recursion's business: jointSpaceUnsupported() says which of them
  // the formulation runs, the caller applies the rest (damping as efforts, springs as
  // loads). Joints the spanning tree does not use are cut joints (cut_joints).

  // Spanning tree by breadth-first search from ground; the bodies ground does not reach
  // are free-floating (each group rooted at its lowest-numbered body by a 6-dof link).
  links.assign(nb, TreeLink());
  joint_link.assign(sys.numJoints(), -1);
  std::vector<char> reached(nb + 1, 0), used(sys.numJoints(), 0);
  std::vector<std::vector<int>> incident(nb + 1);
  for (int j = 0; j < sys.numJoints(); ++j) {
    const Joint& J = *sys.joints[j];
    if (J.bodyI() == J.bodyJ())
      throw ModelError("joint '" + J.name() + "': joins a body to itself");
    incident[J.bodyI()].push_back(j);
    incident[J.bodyJ()].push_back(j);
  }
  order.clear();
  order.reserve(nb);
  reached[0] = 1;
  auto grow = [&](int root) {  // breadth-first from root, appending to order
    std::vector<int> queue{root};
    for (size_t k = 0; k < queue.size(); ++k) {
      const int b = queue[k];
      for (int j : incident[b]) {
        if (used[j]) continue;
        used[j] = 1;
        const Joint& J = *sys.joints[j];
        const int child = J.bodyI() == b ? J.bodyJ() : J.bodyI();
        if (reached[child]) {  // closes a loop: a cut joint, left to the closures
          cut_joints.push_back(j);
          continue;
        }
        reached[child] = 1;
        TreeLink& L = links[child - 1];
        L.body = child;
        L.parent = b;
        L.joint = j;
        L.ptr = &J;
        const TreeJointModel* jm = treeJointModel(J.type());
        if (!jm)
          throw ModelError("joint '" + J.name() + "': the joint-space tree has no model of joint type '" + J.type() +
                           "'");
        if (jm->nv > 6 || jm->nq > 7 || jm->nv > jm->nq)
          throw ModelError("joint '" + J.name() + "': joint type '" + J.type() + "' has a tree model of " +
                           std::to_string(jm->nq) + "/" + std::to_string(jm->nv) +
                           " coordinates (at most 7 positions and 6 rates, no more rates than positions)");
        setModel(L, *jm);
        L.reversed = child == J.bodyI();
        const JointFrame& fp = L.reversed ? J.frameJ() : J.frameI();
        const JointFrame& fc = L.reversed ? J.frameI() : J.frameJ();
        L.Rp = fp.Rp, L.sp = fp.sp_B, L.Rc = fc.Rp, L.sc = fc.sp_B;
        L.params = J.params();
        setConstantSubspace(L);
        joint_link[j] = child - 1;
        order.push_back(child);
        queue.push_back(child);
      }
    }
  };
  grow(0);
  for (int b = 1; b <= nb; ++b) {
    if (reached[b]) continue;
    reached[b] = 1;
    TreeLink& L = links[b - 1];
    L.body = b;
    L.parent = 0;
    setModel(L, kFreeBody);
    order.push_back(b);
    grow(b);
  }
  // Coordinates: the joints' in sys.joints order, then the free bodies'.
  nq = nv = 0;
  std::sort(cut_joints.begin(), cut_joints.end());
  for (int j = 0; j < sys.numJoints(); ++j) {
    if (joint_link[j] < 0) continue;  // a cut joint
    TreeLink& L = links[joint_link[j]];
    L.iq = nq, L.iv = nv;
    nq += L.nq, nv += L.nv;
  }
  for (TreeLink& L : links)
    if (L.joint < 0) {  // a free body
      L.iq = nq, L.iv = nv;
      nq += L.nq, nv += L.nv;
    }
  // Welded groups (joint_space/tree.h), parents first: a fixed link's constant pose relative to
  // its parent (forwardKinematics' Rrel and rho with the joint's identity pose) and, composed
  // along the fixed links above it, relative to its host.
  for (int b : order) {
    TreeLink& L = links[b - 1];
    const bool parent_fixed = L.parent != 0 && links[L.parent - 1].welds();
    if (!L.welds()) {
      L.host = b;
      L.parent_welded = parent_fixed;
      L.aparent = parent_fixed ? links[L.parent - 1].host : L.parent;
      continue;
    }
    const Matrix3d Rrel = L.Rp * L.Rc.transpose();
    L.E0 = Rrel.transpose();
    L.rho0 = L.sp - Rrel * L.sc;
    if (parent_fixed) {  // X_{L,h} = X_{L,P} X_{P,h}
      const TreeLink& P = links[L.parent - 1];
      L.host = P.host;
      L.Eh = L.E0 * P.Eh;
      L.rhoh = P.rhoh + P.Eh.transpose() * L.rho0;
    } else {
      L.host = L.parent;
      L.Eh = L.E0;
      L.rhoh = L.rho0;
    }
  }
  for (TreeLink& L : links) {
    if (L.welds()) continue;
    const Body& B = sys.bodies[L.body];
    L.Ic0.setZero();
    L.Ic0.topLeftCorner<3, 3>() = B.Jp;
    L.Ic0.bottomRightCorner<3, 3>().diagonal().setConstant(B.m);
    L.mass = B.m;
  }
  for (int b : order) {
    const TreeLink& L = links[b - 1];
    if (!L.welds() || L.host == 0) continue;  // (a body welded to ground stays)
    TreeLink& H = links[L.host - 1];
    const Body& B = sys.bodies[b];
    Matrix6d I = Matrix6d::Zero();
    I.topLeftCorner<3, 3>() = B.Jp;
    I.bottomRightCorner<3, 3>().diagonal().setConstant(B.m);
    addTransformedInertia(L.Eh, L.rhoh, I, H.Ic0);
    H.composite = true;
    H.welded.push_back(b);
    H.mass += B.m;
    H.mc += B.m * L.rhoh;
  }
  for (const TreeLink& L : links)
    if (L.quaternion >= 0) quaternions.push_back(L.iq + L.quaternion);
  if (embed_couplers) embedCouplers(sys, *this);
  armature = Eigen::VectorXd::Zero(nv);
  for (const RotorInertia& R : sys.rotors) {
    for (size_t c = 0; c < R.coords.size(); ++c)
      if (joint_link[R.coords[c].first] >= 0)
        armature[links[joint_link[R.coords[c].first]].iv + R.coords[c].second] += R.B(c, c);
    if (!R.coupled() || joint_link[R.coords[0].first] < 0 || joint_link[R.coords[1].first] < 0) continue;
    RotorCoupling C;
    C.i = links[joint_link[R.coords[0].first]].iv + R.coords[0].second;
    C.j = links[joint_link[R.coords[1].first]].iv + R.coords[1].second;
    C.inertia = R.B(0, 1), C.damping = R.damping_coupling;
    rotor_couplings.push_back(C);
    rotors_coupled = true;
  }
}

void TreeModel::holdTies(Eigen::VectorXd& q, Eigen::VectorXd& qdot, Eigen::VectorXd* q_round,
                         Eigen::VectorXd* qdot_round) const {
  for (int k : ties) {
    const TreeLink& L = links[k];
    const TreeLink& M = links[L.tie];
    q(L.iq) = L.tie_mult * q(M.iq) + L.tie_offset;
    qdot(L.iv) = L.tie_mult * qdot(M.iv);
    if (q_round && q_round->size() == nq) (*q_round)(L.iq) = L.tie_mult * (*q_round)(M.iq);
    if (qdot_round && qdot_round->size() == nv) (*qdot_round)(L.iv) = L.tie_mult * (*qdot_round)(M.iv);
  }
}

Eigen::VectorXd TreeModel::neutralPositions(const System& sys) const {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(nq);
  for (const TreeLink& L : links) {
    if (L.quaternion >= 0) q(L.iq + L.quaternion) = 1.0;
    if (L.joint < 0) {  // a free body where the System's body starts
      const Body& B = sys.bodies[L.body];
      const Quaterniond p = B.p.normalized();
      q.segment<3>(L.iq) = B.r;
      q.segment<4>(L.iq + 3) << p.w(), p.x(), p.y(), p.z();
    }
  }
  return q;
}

TreeWorkspace::TreeWorkspace(const TreeModel& model) {
  const int n = model.nb;
  A.assign(n, Matrix3d::Identity());
  r.assign(n, Vector3d::Zero());
  E.assign(n, Matrix3d::Identity());
  rho.assign(n, Vector3d::Zero());
  v.assign(n, Vector6d::Zero());
  c = a = pA = f = v;
  IA.assign(n, Matrix6d::Zero());
  W.assign(n, Vector6d::Zero());
  dd.assign(n, 0.0), beta.assign(n, 0.0);
  tie_Dinv.assign(n, 0.0), tie_u.assign(n, 0.0);
  S.resize(n), U.resize(n), Dinv.resize(n), u.resize(n);
  for (int k = 0; k < n; ++k) {
    const int nv = model.links[k].nv;
    S[k].setZero(6, nv);
    if (model.links[k].constant_S) S[k].col(0) = model.links[k].S0;  // forwardKinematics leaves it
    U[k].setZero(6, nv);
    Dinv[k].setZero(nv, nv);
    u[k].setZero(nv);
  }
  if (!model.rotor_couplings.empty()) {
    const int m = 2 * static_cast<int>(model.rotor_couplings.size());
    rotor_tau.setZero(model.nv), rotor_z.setZero(m), rotor_r.setZero(m);
    rotor_Y.setZero(model.nv, m), rotor_K.setZero(m, m);
    rotor_lu = Eigen::PartialPivLU<Eigen::MatrixXd>(m);
    rotor_p.assign(n, Vector6d::Zero()), rotor_a.assign(n, Vector6d::Zero());
  }
}

// ---- the joint calculation (RBDA ch. 4, "jcalc": X_J, S, c_J; the joint type's
// TreeJointModel::calc)
//
// For the pose T(q) = (R, t) of frame j in frame i (JointTypeInfo::relativePose), S is the
// motion subspace of frame j relative to frame i in frame-j Plucker coordinates, v_J = S
// q_dot, and c = S_ring q_dot the apparent derivative of S's coordinates (RBDA ch. 4:
// c_J, the velocity-product part of the joint acceleration). Where S is constant, c = 0.
// A link built by hand (the tests) carries its tag alone: its type's model is the tag's.
void jointTransform(const TreeLink& L, const double* q, const double* qd, Matrix3d& R, Vector3d& t,
                    MotionSubspace& S, Vector6d& c) {
  S.setZero(6, L.nv);
  c.setZero();
  R.setIdentity();
  t.setZero();
  const TreeJointModel& m =
      L.jmodel ? *L.jmodel : (L.kind == TreeJointKind::kFree ? kFreeBody : treeJointModel(L.kind));
  m.calc(L.params, q, qd, R, t, S, c);
  if (L.reversed) {
    // The child carries frame i: its motion relative to frame j is minus that of j
    // relative to i, in frame-i coordinates S' = -(i_X_j) S. The bias is c' = -(i_X_j) c:
    // the extra term -(d/dt i_X_j) S q_dot = -(i_X_j v_J) x (i_X_j v_J) vanishes (a vector
    // fixed in j seen from i changes at v_J x: RBDA ch. 2, differentiation in moving
    // frames). The pose is the inverse, (R^T, -R^T t).
    const Matrix3d Et = R;                 // i_X_j: E = R (j -> i components)
    const Vector3d rho = -R.transpose() * t;  // i's origin relative to j's, j components
    for (int k = 0; k < L.nv; ++k) S.col(k) = -transformMotion(Et, rho, S.col(k));
    c = -transformMotion(Et, rho, c);
    t = -R.transpose() * t;
    R.transposeInPlace();
  }
}

// ---- the workspace's generations

long nextWorkspaceGeneration() {
  static std::atomic<long> last{0};
  return ++last;
}

void absoluteState(const TreeModel& model, const TreeWorkspace& ws, Eigen::VectorXd& x, Eigen::VectorXd& u) {
  x.resize(7 * model.nb);
  u.resize(6 * model.nb);
  for (int k = 0; k < model.nb; ++k) {
    const Quaterniond p(ws.A[k]);
    x.segment<3>(7 * k) = ws.r[k];
    x.segment<4>(7 * k + 3) << p.w(), p.x(), p.y(), p.z();
    u.segment<3>(6 * k) = ws.A[k] * ws.v[k].tail<3>();  // v = A_Oi (A_Oi^T v)
    u.segment<3>(6 * k + 3) = ws.v[k].head<3>();        // omega' (body components)
  }
}

}  // namespace mechanism_sim
