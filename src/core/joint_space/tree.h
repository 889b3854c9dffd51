// Joint-space (relative-coordinate) dynamics of a tree: the recursions of the joint
// formulation, in which the spanning tree moves in joint coordinates and only the closures
// stay algebraic. Free-standing: it reads a finalized System and does not touch the
// absolute Stepper.
//
//   TreeModel          the tree of a System whose joints form a forest: per moving body its
//                      parent (or ground) and the joint to it; bodies that no joint reaches
//                      float freely (6 dof, unit quaternion)
//   forwardKinematics  joint state (q, q_dot) -> each body's absolute pose and velocity,
//                      i.e. the absolute State x, u (r, p; v global, omega' body)
//   forwardDynamics    q_ddot by the articulated-body algorithm (Featherstone, "Rigid Body
//                      Dynamics Algorithms" (RBDA), 2008, section 7.3, table 7.1): O(n), no
//                      mass matrix, no allocation after the workspace is built
//   inverseDynamics    the efforts for a given q_ddot (recursive Newton-Euler, RBDA 5.3,
//                      table 5.1): a second, independent recursion to check the first
//   bodyAccelerations  q_ddot -> absolute accelerations as State::acc has them
//
// Coordinates (per joint, in sys.joints order; a free body's after all joints'):
//   the joint type's tree model (TreeJointModel, joint.h, written beside its constraint
//   rows in core/model/joints/<type>.cpp): its nq/nv position/velocity coordinates, as
//   a rule q_k = Row::Phi and q_dot_k = Row::Phi_dot of Joint::coordinates() (a spherical
//   joint's q is the unit quaternion of frame j in frame i, Joint::treePositions), and its
//   calculation ("jcalc": pose, motion subspace, bias). A body no joint reaches floats
//   freely, the tree's own link:
//     free body    7/6  q: r (3, global), p (4, w x y z), as State::x; q_dot: v (3,
//                       global), omega' (3, body), as State::u
//   A generalized effort tau_k is what the absolute solver takes as Inputs::effort (it
//   acts as q_x,k^T tau_k); on a free body tau is (force global, torque in body
//   components) at the centre of mass.
// Welds (joints without coordinates: fixed joints) are merged: a body welded to a moving
// body (its host) adds its constant spatial inertia to the host's (TreeLink::Ic0) and its external forces to the
// host's, and the articulated-body and composite-rigid-body passes skip it; its pose and
// velocity are still computed (closures, tf and reactions read them) and the recursive
// Newton-Euler pass still runs over every body, so the reaction at a fixed joint and the
// merged dynamics check each other (RBDA 6.2/7.3 for one rigid composite body).
// What the formulation runs is jointSpaceUnsupported()'s answer; the TreeModel itself only
// refuses what the recursion cannot represent (a joint type without a tree model, a joint
// from a body to itself). It leaves out everything that is not a tree joint: couplers,
// drives, limits, springs, joint damping and friction are the caller's (a stepper applies
// damping as tau -= c q_dot and springs as body loads), and joints the spanning tree does
// not use are cut joints (TreeModel::cut_joints), for the loop closures.
#pragma once
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/StdVector>

#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// The Plucker transform X = B_X_A of motion vectors from frame A to frame B, given by E (A
// components -> B components) and rho (B's origin relative to A's, A components):
// X = [E 0; -E rho~ E] (RBDA ch. 2, with r = rho).
inline Vector6d transformMotion(const Matrix3d& E, const Vector3d& rho, const Vector6d& m) {
  Vector6d out;
  out.head<3>() = E * m.head<3>();
  out.tail<3>() = E * (m.tail<3>() - rho.cross(m.head<3>()));
  return out;
}

// X^T f: a force in B coordinates back to A coordinates (B_X_A^* inverse = X^T).
inline Vector6d transformForceBack(const Matrix3d& E, const Vector3d& rho, const Vector6d& f) {
  Vector6d out;
  out.tail<3>() = E.transpose() * f.tail<3>();
  out.head<3>() = E.transpose() * f.head<3>() + rho.cross(out.tail<3>());
  return out;
}

// At most 6 rows and columns (a free body), stored in place: no heap (MotionSubspace: joint.h).
using SmallMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
using SmallVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>;
// Vectors of the 16-byte-aligned fixed-size types.
template <class T>
using AlignedVector = std::vector<T, Eigen::aligned_allocator<T>>;

// The link from a moving body to its parent. (Its members are ordered by use: what every
// pass reads of every link first, in the link's first cache line; the kinematics' constant
// parts next; what only welds, composites and ties read last.)
struct TreeLink {
  int body = 0;          // the moving body (1..nb)
  int parent = 0;        // its parent (0: ground)
  int joint = -1;        // index in sys.joints; -1: a free body (no joint)
  int nq = 0, nv = 0;    // coordinates of this link
  int iq = 0, iv = 0;    // where they start in q and q_dot
  // Moving links: the articulated parent (the parent's host: 0 for ground or a body welded
  // to ground), and whether the parent is a welded body (the transform to the articulated
  // parent is then X_k X_parent,h, composed at each pass).
  int aparent = 0;
  bool parent_welded = false;
  // Moving links with welded bodies (composite: Ic0 below holds theirs too).
  bool composite = false;
  // One coordinate whose motion subspace is constant in the child's centre-of-mass
  // coordinates (TreeJointModel::axis; either direction): S0 below, and c_J = 0.
  // forwardKinematics then computes only the pose (RBDA ch. 4: S constant for these).
  bool constant_S = false;
  // The child is the joint's body i (the joint was written parent-last): frame j then sits
  // on the parent, and the child's frame is frame i.
  bool reversed = false;
  // An embedded coupler (TreeModel's embed_couplers; Jain, "Robot and Multibody Dynamics"
  // ch. 11, constraint embedding, for a linear coupling): this link's one coordinate is
  // tie_mult q_master + tie_offset, its master the link `tie`, tie_coupler the coupler's
  // constraint. The articulated passes carry the master's coordinate up from every link
  // tied to it and eliminate it at one link:
  // - the master's own link when it is an ancestor of its slaves (the links between them
  //   welded or tied to the same master): tie_master;
  // - else (siblings: a parallel gripper's fingers) the links' nearest common moving
  //   ancestor T, whose `pivot` is the master's coordinate (its index in q_dot; pivot_link
  //   the master's link); the master's link is then tied to itself (tie its own index,
  //   tie_mult 1, tie_coupler -1) and eliminates nothing.
  bool tie_master = false;
  int tie = -1, tie_coupler = -1;
  int pivot = -1, pivot_link = -1;
  double tie_mult = 0.0, tie_offset = 0.0;
  // The joint type's tree model (JointTypeInfo::tree; a free body's is the tree's own) and
  // what the passes read of it in place: its tag, its constant axis motion, the offset of
  // a unit quaternion in its coordinates (-1: none) and the frame of its rates.
  TreeJointKind kind = TreeJointKind::kFree;
  AxisMotion axis = AxisMotion::kNone;
  signed char quaternion = -1;
  bool quaternion_in_child = false;
  const Joint* ptr = nullptr;
  const TreeJointModel* jmodel = nullptr;
  JointParams params;    // screw: alpha, phi0
  // For constant_S links, the pose as constant parts (forwardKinematics): with
  // R = Rz(angle), Rrel = Rp R Rc^T = cos K_c + sin K_s + K_0 and the child's centre
  // rho = sp + t_z Rp z - Rrel sc = k_0 + t_z Rp z - cos k_c - sin k_s (k_c = K_c sc,
  // k_s = K_s sc, k_0 = sp - K_0 sc); a sliding joint's Rrel is K_0 + K_c (angle 0); and the
  // motion subspace S0 (TreeWorkspace::S holds it from its construction).
  Matrix3d Kc = Matrix3d::Zero(), Ks = Matrix3d::Zero(), K0 = Matrix3d::Zero();
  Vector3d kc = Vector3d::Zero(), ks = Vector3d::Zero(), k0 = Vector3d::Zero();
  Vector6d S0 = Vector6d::Zero();
  // The joint frame on the parent (F_p) and on the child (F_c), body components relative to
  // that body's centre of mass; ground's in global components.
  Matrix3d Rp = Matrix3d::Identity(), Rc = Matrix3d::Identity();
  Vector3d sp = Vector3d::Zero(), sc = Vector3d::Zero();
  // Fixed links: the constant pose of the child relative to the parent (E0: parent -> child
  // components, rho0: the child's centre relative to the parent's, parent components), and
  // relative to the host (Eh, rhoh), the moving body (0: ground) the welded group moves with.
  Matrix3d E0 = Matrix3d::Identity(), Eh = Matrix3d::Identity();
  Vector3d rho0 = Vector3d::Zero(), rhoh = Vector3d::Zero();
  int host = 0;  // a fixed link's host; any other link's own body
  // Moving links: the spatial inertia at this body's centre in its axes, its own and, on a
  // composite link, its welded bodies' (X^T I X); the bodies welded to it, their total mass
  // with its own and sum m_i rhoh_i (gravity on the group is (mc x g'; m g'), g' in its axes).
  Matrix6d Ic0 = Matrix6d::Zero();
  std::vector<int> welded;
  double mass = 0.0;
  Vector3d mc = Vector3d::Zero();
  // A joint without coordinates welds its body to its parent (a fixed joint).
  bool welds() const { return nv == 0; }
};

// Empty when the joint-space formulation can run the System; otherwise a sentence naming
// the first thing it cannot run (a joint type without a tree model, a constraint type
// that is neither a joint, a coupler, a drive nor a limit, a joint from a body to itself;
// and, by default, closures). Springs, joint damping and Coulomb friction pass: the caller
// applies them as loads and efforts. Closures (the joints that close loops, couplers,
// drives, limits: loop_closure.h) pass only with loops_as_closures: a caller that
// integrates them as closures says so; the default refuses them, because a stepper that
// ignored them would run a different mechanism.
std::string jointSpaceUnsupported(const System& sys, bool loops_as_closures = false);

struct TreeModel {
  // Throws UsageError for a System that is not finalized, ModelError for a tree joint of a
  // type the recursion has no model of, or a joint from a body to itself.
  // embed_couplers: a coupler (URDF mimic) q_s = r q_m + o between one-coordinate tree
  // joints is held by the recursions themselves (TreeLink::tie) instead of as a closure row
  // when m's coordinate can be eliminated at one link: m's own, an ancestor of s with only
  // welded links or links tied to the same master between them, or the nearest common
  // moving ancestor of both reached the same way (TreeLink::pivot), a link no other group
  // uses; `ties` lists those slave links, parents first.
  explicit TreeModel(const System& sys, bool embed_couplers = false);

  int nb = 0;                   // moving bodies
  int nq = 0, nv = 0;           // position and velocity coordinates
  std::vector<TreeLink> links;  // per moving body b at links[b - 1]
  std::vector<int> order;       // moving bodies, each after its parent (b, 1..nb)
  std::vector<int> joint_link;  // per sys joint: its link (body - 1); -1 for a cut joint
  std::vector<int> cut_joints;  // sys joints that close loops (not on the tree), ascending
  // Per q_dot coordinate: the diagonal of the reflected rotor inertias on it (System::rotors),
  // added to D_i in the articulated-body pass as an armature (Featherstone, RBDA 7.3) and to
  // H_ii in the composite one.
  Eigen::VectorXd armature;
  // Rotors that couple two coordinates i, j (a differential's): the off-diagonal B_01 of
  // their reflected inertia and D_01 of their motors' damping. forwardDynamics adds them
  // exactly to the articulated-body pass, whose M_a has only the armature (the Woodbury
  // identity, tree_dynamics.cpp); the other users of M_a's factors (closures, friction,
  // implicit damping, forwardDynamicsAtKinematics alone) do not take them:
  // jointSpaceUnsupported and JointDamping refuse those.
  struct RotorCoupling {
    int i = 0, j = 0;
    double inertia = 0.0, damping = 0.0;
  };
  std::vector<RotorCoupling> rotor_couplings;
  bool rotors_coupled = false;  // rotor_couplings not empty
  std::vector<int> ties;        // links tied to a master's coordinate (embed_couplers), parents first
  std::vector<int> quaternions; // where each unit quaternion starts in q (TreeJointModel::quaternion)
  // q_s = r q_m + o and q_dot_s = r q_dot_m of every tie (their round-off in q_round and
  // qdot_round likewise, when given): what the integration holds up to round-off, exactly.
  void holdTies(Eigen::VectorXd& q, Eigen::VectorXd& qdot, Eigen::VectorXd* q_round = nullptr,
                Eigen::VectorXd* qdot_round = nullptr) const;

  const TreeLink& link(int b) const { return links[b - 1]; }
  // A neutral joint state: zero coordinates, identity quaternions, free bodies where the
  // System's bodies start.
  Eigen::VectorXd neutralPositions(const System& sys) const;
};

// Scratch space of the recursions, one per model; sized once (no allocation after that).
struct TreeWorkspace {
  explicit TreeWorkspace(const TreeModel& model);
  // per moving body (index b - 1), all spatial quantities (omega; v) in body coordinates at
  // the centre of mass (the body's reference point): Featherstone's Plucker coordinates.
  AlignedVector<Matrix3d> A;        // A_Oi: body -> global (seed lecture A^{Oi})
  AlignedVector<Vector3d> r;        // centre of mass, global
  AlignedVector<Matrix3d> E;        // X_{b <- parent}: rotation parent -> body components
  AlignedVector<Vector3d> rho;      // X_{b <- parent}: b's centre relative to the parent's, parent components
  AlignedVector<MotionSubspace> S;  // motion subspace in body coordinates
  AlignedVector<Vector6d> v, c;     // velocity, velocity-product acceleration c_J + v x v_J
  AlignedVector<Vector6d> a;        // spatial acceleration
  AlignedVector<Matrix6d> IA;       // articulated inertia
  AlignedVector<Vector6d> pA;       // articulated bias force
  AlignedVector<MotionSubspace> U;  // IA S
  AlignedVector<SmallMatrix> Dinv;  // (S^T IA S)^-1
  AlignedVector<SmallVector> u;     // tau - S^T pA
  AlignedVector<Vector6d> f;        // RNEA: force transmitted by the joint
  // Ties (TreeLink::tie): per link, the articulated quantities that couple it to the tied
  // coordinate it carries up, W (6) and its own inertia dd, and the bias beta (pass 2)
  AlignedVector<Vector6d> W;
  std::vector<double> dd, beta;
  std::vector<double> tie_Dinv, tie_u;  // at a link with a pivot: 1 / dd and -beta there
  // Rotor couplings (TreeModel::rotor_couplings): the efforts with their damping, Y = M_a^-1 U
  // (U: a unit column per coupled coordinate, two per coupling), the small system of the
  // Woodbury identity and the passes' forces and accelerations
  Eigen::VectorXd rotor_tau, rotor_z, rotor_r;
  Eigen::MatrixXd rotor_Y, rotor_K;
  Eigen::PartialPivLU<Eigen::MatrixXd> rotor_lu;
  AlignedVector<Vector6d> rotor_p, rotor_a;
  // A number no other write has had (across workspaces), taken each time forwardKinematics
  // or the articulated passes rewrite the poses, subspaces or factors (E, rho, S, U, Dinv):
  // what a cache of results computed from them keys on (LoopClosures' factorization).
  long generation = 0;
};
// The next such number (thread-safe).
long nextWorkspaceGeneration();

// One link k of the inverse-mass inward pass (the articulated-body algorithm with zero
// velocity and no external force, RBDA table 7.1, passes on the factors U, D^-1 in ws):
// u_k = tau_k - S_k^T p_k into out (tau and out may be the same array), and the parent's
// p += X^T (p_k + U_k D_k^-1 u_k), on N columns at once (each column's operations in the
// same order as alone: the same bits), the link visited once. The caller visits children
// before parents with p zeroed first: LoopClosures::applyInverseMass over every link,
// ClosureSolver over rows' paths, two at a time.
// With ties (TreeLink::tie) tau and out must be the same array: a tied link adds
// r (tau_s - S_s^T p_s) to its master's entry, which the master's own step (or the pivot's,
// at the common ancestor) then reads as its u, and leaves 0 at its own (its coordinate is
// not eliminated there; the master's own link, tied to itself, leaves the sum).
template <int N>
inline void inverseMassInwardColumns(const TreeModel& model, const TreeWorkspace& ws, int k, const double* const* tau,
                                     double* const* out, AlignedVector<Vector6d>* const* p) {
  const TreeLink& L = model.links[k];
  Vector6d pa[N];
  for (int c = 0; c < N; ++c) pa[c] = (*p[c])[k];
  if (L.tie >= 0) {  // a tied link (TreeLink::tie): its effort and S^T p go to the master's u
    const double r = L.tie_mult;
    const int master = model.links[L.tie].iv;
    for (int c = 0; c < N; ++c) {
      const double ts = tau[c][L.iv];
      out[c][L.iv] = 0.0;  // (zeroed first: the master's own link then adds to its own entry)
      out[c][master] += r * ts - r * ws.S[k].col(0).dot(pa[c]);
      (*p[c])[L.parent - 1] += transformForceBack(ws.E[k], ws.rho[k], pa[c]);
    }
    return;
  }
  if (L.pivot >= 0)  // (the tied coordinate eliminated here first)
    for (int c = 0; c < N; ++c) pa[c] += ws.W[k] * (ws.tie_Dinv[k] * out[c][L.pivot]);
  for (int i = 0; i < L.nv; ++i)
    for (int c = 0; c < N; ++c) out[c][L.iv + i] = tau[c][L.iv + i] - ws.S[k].col(i).dot(pa[c]);
  if (L.parent == 0) return;
  for (int c = 0; c < N; ++c) {
    if (L.nv == 1) {
      pa[c] += ws.U[k].col(0) * (ws.Dinv[k](0, 0) * out[c][L.iv]);
    } else if (L.nv > 0) {
      const SmallVector u = Eigen::Map<const SmallVector>(out[c] + L.iv, L.nv);
      pa[c] += ws.U[k] * (ws.Dinv[k] * u);
    }
    (*p[c])[L.parent - 1] += transformForceBack(ws.E[k], ws.rho[k], pa[c]);
  }
}

// The same on one column.
inline void inverseMassInward(const TreeModel& model, const TreeWorkspace& ws, int k, const double* tau, double* out,
                              AlignedVector<Vector6d>& p) {
  AlignedVector<Vector6d>* ps[1] = {&p};
  inverseMassInwardColumns<1>(model, ws, k, &tau, &out, ps);
}

// Pass 3 of the articulated-body algorithm (RBDA table 7.1), outward over every link:
// a'_i = X a_parent (+ c_i with Bias), q_ddot_i = D^-1 (u_i - U_i^T a'_i),
// a_i = a'_i + S_i q_ddot_i (the ground does not accelerate); a tied link takes r times
// its master's q_ddot (an ancestor: done), a pivot's tied coordinate
// q_ddot_m = D^-1 (u_m - W^T a). u(k): link k's u (its nv entries), tie_u(k): the pivot's u_m;
// qddot may hold the u themselves (each is read before its q_ddot is written).
// forwardDynamics runs it with the velocity's bias c; the inverse-mass application
// without (v = 0).
template <bool Bias, class LinkU, class TieU>
inline void articulatedOutward(const TreeModel& model, const TreeWorkspace& ws, const LinkU& u, const TieU& tie_u,
                               double* qddot, AlignedVector<Vector6d>& a) {
  for (int b : model.order) {
    const int k = b - 1;
    const TreeLink& L = model.links[k];
    Vector6d ap;
    if constexpr (Bias) {
      ap = ws.c[k];
      if (L.parent != 0) ap += transformMotion(ws.E[k], ws.rho[k], a[L.parent - 1]);
    } else {
      ap.setZero();
      if (L.parent != 0) ap = transformMotion(ws.E[k], ws.rho[k], a[L.parent - 1]);
    }
    if (L.tie >= 0) {
      const double qdd = L.tie_mult * qddot[model.links[L.tie].iv];
      qddot[L.iv] = qdd;
      a[k] = ap + ws.S[k].col(0) * qdd;
    } else if (L.nv == 1) {
      const double qdd = ws.Dinv[k](0, 0) * (u(k)(0) - ws.U[k].col(0).dot(ap));
      qddot[L.iv] = qdd;
      a[k] = ap + ws.S[k].col(0) * qdd;
    } else if (L.nv > 0) {
      const SmallVector qdd = ws.Dinv[k] * (u(k) - ws.U[k].transpose() * ap);
      for (int i = 0; i < L.nv; ++i) qddot[L.iv + i] = qdd(i);
      a[k] = ap + ws.S[k] * qdd;
    } else {
      a[k] = ap;
    }
    if (L.pivot >= 0) qddot[L.pivot] = ws.tie_Dinv[k] * (tie_u(k) - ws.W[k].dot(a[k]));
  }
}

// Poses and velocities of the bodies for (q, q_dot) into ws (A, r, v and the per-link
// transforms, subspaces and bias terms the dynamics reuse).
void forwardKinematics(const TreeModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qdot,
                       TreeWorkspace& ws);
// The absolute State that ws's kinematics describe: x (7 nb: r, p) and u (6 nb: v global,
// omega' body), as State::x and State::u.
void absoluteState(const TreeModel& model, const TreeWorkspace& ws, Eigen::VectorXd& x, Eigen::VectorXd& u);

// q_ddot under gravity (sys.gravity), the generalized efforts tau (nv) and, when `loads` is
// given, its body forces (global, at the centre of mass) and torques (body components) (its
// efforts are not read: pass them in tau, jointEfforts()). Runs forwardKinematics itself.
// Articulated-body algorithm; allocation-free once qddot has size nv.
void forwardDynamics(const TreeModel& model, const System& sys, const Eigen::VectorXd& q,
                     const Eigen::VectorXd& qdot, const Eigen::VectorXd& tau, TreeWorkspace& ws,
                     Eigen::VectorXd& qddot, const Inputs* loads = nullptr);
// The same at the kinematics ws holds (forwardKinematics at these q, q_dot ran last and
// nothing has changed ws's poses and rates since): the articulated passes alone.
void forwardDynamicsAtKinematics(const TreeModel& model, const System& sys, const Eigen::VectorXd& tau,
                                 TreeWorkspace& ws, Eigen::VectorXd& qddot, const Inputs* loads = nullptr);
// The efforts that give q_ddot (the inverse of forwardDynamics): recursive Newton-Euler.
void inverseDynamics(const TreeModel& model, const System& sys, const Eigen::VectorXd& q,
                     const Eigen::VectorXd& qdot, const Eigen::VectorXd& qddot, TreeWorkspace& ws,
                     Eigen::VectorXd& tau, const Inputs* loads = nullptr);
// The joint-space inertia matrix H (nv x nv, M of M q_ddot + h = tau) at ws's kinematics, by
// the composite-rigid-body algorithm (RBDA 6.2, table 6.2) in body coordinates: only the
// entries H(i, j) of coordinates on one branch (j an ancestor's or the same link's) are
// written, both triangles; the others are left as they are (zero: branch-induced sparsity,
// RBDA 6.5). The bodies' inertias are the model's (TreeLink::Ic0, welded bodies in their hosts'). Ic:
// scratch, per moving body (the composite inertias on return).
void jointSpaceInertia(const TreeModel& model, const TreeWorkspace& ws, AlignedVector<Matrix6d>& Ic,
                       Eigen::MatrixXd& H);
// Inputs::effort as a vector tau over q_dot (a free body's entries zero).
void jointEfforts(const TreeModel& model, const Inputs& in, Eigen::VectorXd& tau);

// The bodies' spatial accelerations ws.a from q_ddot at ws's kinematics (the outward pass).
void spatialAccelerations(const TreeModel& model, TreeWorkspace& ws, const Eigen::VectorXd& qddot);
// Absolute accelerations for q_ddot at the kinematics in ws (forwardKinematics or
// forwardDynamics at the same q, q_dot), as State::acc: per body a (3, global, of the centre
// of mass) and omega'_dot (3, body components).
void bodyAccelerations(const TreeModel& model, TreeWorkspace& ws, const Eigen::VectorXd& qddot,
                       Eigen::VectorXd& acc);

// dq/dt for (q, q_dot) (nq): q_dot itself except at the quaternions.
void positionRates(const TreeModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& qdot,
                   Eigen::VectorXd& qrate);
// Scales every quaternion in q to unit length.
void normalizeQuaternions(const TreeModel& model, Eigen::VectorXd& q);

// The pose of the child's joint frame in the parent's, the motion subspace in the child's
// joint-frame components and the bias S_dot q_dot there (RBDA ch. 4, "jcalc"), of one link:
// exposed for the tests.
void jointTransform(const TreeLink& link, const double* q, const double* qdot, Matrix3d& R, Vector3d& t,
                    MotionSubspace& S, Vector6d& c);

}  // namespace mechanism_sim
