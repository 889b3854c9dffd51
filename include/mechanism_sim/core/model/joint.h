// A joint: constraint equations between body i and body j, each given a joint frame
// (point B and axes bx, by, bz fixed in the body), plus the joint's own coordinates
// along its free directions.
#pragma once
#include <array>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "mechanism_sim/core/model/constraint.h"

namespace mechanism_sim {

// The most degrees of freedom a joint has (spherical, planar): room for its coordinate rows.
constexpr int kMaxJointDofs = 3;

// Joint frame in body components: origin sp_B and axes Rp = [bxp byp bzp].
struct JointFrame {
  Vector3d sp_B = Vector3d::Zero();
  Matrix3d Rp = Matrix3d::Identity();
};

// What a joint type may need beyond its frames.
struct JointParams {
  double alpha = 0.0;  // screw: lead per radian (m/rad), right-handed positive
  double phi0 = 0.0;   // screw: relative angle at which B_i and B_j coincide
};

// ---- The joint's calculation in the joint-space tree ("jcalc", Featherstone, "Rigid Body
// Dynamics Algorithms" (RBDA), 2008, ch. 4; Pinocchio's JointModel::calc). Each joint type
// describes it once, beside its constraint rows (JointTypeInfo::tree); the joint-space
// recursions read it and know no joint type by name.

using Vector6d = Eigen::Matrix<double, 6, 1>;
// A motion subspace: at most 6 columns (a free body), stored in place (no heap).
using MotionSubspace = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6>;

// The tag of a tree model, by which a caller singles out a type (kFree: a body no joint
// reaches, the tree's own 6-dof link). A new joint type adds its own.
enum class TreeJointKind { kFixed, kRevolute, kPrismatic, kCylindrical, kScrew, kUniversal, kSpherical, kPlanar, kFree };

// How a one-coordinate joint whose motion subspace is constant moves frame j along bz_i:
// turning about it (by q), sliding along it (by q) or both (turning by q, sliding by
// alpha (q - phi0)). The tree precomputes such a joint's pose as constant parts.
enum class AxisMotion { kNone, kTurn, kSlide, kHelix };

// For the pose (R, t) of frame j in frame i at q (JointTypeInfo::relativePose's, with the
// tree's own coordinates), the motion subspace S of frame j relative to frame i in frame-j
// Plucker coordinates (omega; v of its origin), v_J = S q_dot, and c = S_ring q_dot, the
// apparent derivative of S's coordinates along the motion (RBDA ch. 4: c_J). The caller
// passes R = 1, t = 0, S = 0 (6 x nv) and c = 0: a calculation writes what differs.
using TreeJointCalc = void (*)(const JointParams& params, const double* q, const double* q_dot, Matrix3d& R,
                               Vector3d& t, MotionSubspace& S, Vector6d& c);

// A joint type's tree model: its coordinates and its calculation.
struct TreeJointModel {
  TreeJointKind kind = TreeJointKind::kFixed;
  // position and velocity coordinates; a joint with none welds its bodies in the pose of
  // coincident frames (R = 1, t = 0)
  int nq = 0, nv = 0;
  // Where a unit quaternion (w x y z) starts in q (-1: none); its three rates are the
  // velocity coordinates at the same offset, and every other coordinate integrates as
  // itself (q_dot its time derivative). Rates in frame-i components (the relative angular
  // velocity, dq/dt = 1/2 (0, q_dot) (x) q) or, with quaternion_in_child, in the child's
  // (dq/dt = 1/2 q (x) (0, q_dot)).
  int quaternion = -1;
  bool quaternion_in_child = false;
  AxisMotion axis = AxisMotion::kNone;  // a constant motion subspace along bz_i (one coordinate)
  unsigned lengths = 0;     // bit k: velocity coordinate k is a translation (its unit a length)
  unsigned free_turns = 0;  // bit k: coordinate k is an angle assembly may draw anywhere in a turn
  TreeJointCalc calc = nullptr;
};

// ---- The joint's equations

// The joint frames' axes and the gap d_ij in one evaluation; a joint computes only those
// it uses (Joint::equationAxes), the others stay unset. kNoRates, with any of them: their
// values and variations alone (the rates FixedVector::a_dot, a_cen and Gap::d_dot, d_cen
// zero), all that Phi and its Jacobian read (an evaluation without rates, EvalContext).
enum GeometryPart : unsigned {
  kBxI = 1, kByI = 2, kBzI = 4, kBxJ = 8, kByJ = 16, kBzJ = 32, kGap = 64, kAllParts = 127, kNoRates = 128
};
struct JointGeometry {
  FixedVector bx_i, by_i, bz_i, bx_j, by_j, bz_j;
  Gap d;
};

class Joint : public Constraint {
 public:
  Joint(std::string name, int body_i, const JointFrame& frame_i, int body_j,
        const JointFrame& frame_j)
      : Constraint(std::move(name), {body_i, body_j}), frame_i_(frame_i), frame_j_(frame_j) {}

  int bodyI() const { return bodies()[0]; }
  int bodyJ() const { return bodies()[1]; }
  const JointFrame& frameI() const { return frame_i_; }
  const JointFrame& frameJ() const { return frame_j_; }

  // Degrees of freedom and their names ("" for a one-dof joint). A joint class declares
  // them once, as static kType and kDofNames (at most kMaxJointDofs); the registry reads
  // those (registerJoint in joint_registry.cpp).
  virtual int dof() const = 0;
  std::string dofName(int k) const;  // from the registry (JointTypeInfo::dof_names)
  // Whether the equations hold bz_j parallel to bz_i, which they also meet opposed
  // (bz_j = -bz_i), and whether they lock the twist about it by bx_i . bx_j, which they
  // also meet turned by pi: assembly rejects those mirrored closures.
  virtual bool holdsAxesParallel() const { return false; }
  virtual bool locksTwist() const { return false; }
  // Whether q_dot = q_x v is the time derivative of q (false for a spherical joint,
  // whose rates are the relative angular velocity in frame i).
  virtual bool holonomicCoordinates() const { return true; }
  // The tracked-angle slot (Constraint::tracked) behind coordinate k, or -1: assembly seeds
  // it so that a target of, say, 5 rad means 5 rad and not 5 - 2 pi.
  virtual int trackedSlot(int /*k*/) const { return -1; }
  // Whether coordinates 0 and 1 are two translations in one plane (a planar joint): their
  // Coulomb friction is then a disc (an ellipse for unequal values), not a box.
  virtual bool planarTranslation() const { return false; }
  // The joint's coordinates in the joint-space tree (TreeJointModel: nq values) for the
  // bodies' poses: by default the values of coordinates() (Phi); a joint whose tree
  // coordinates are not those (a spherical joint's quaternion) says how.
  virtual void treePositions(const BodyKin& ki, const BodyKin& kj, const Tracked& t, double* q) const;
  // The type's parameters beyond its frames (a screw's alpha and phi0; the defaults else).
  virtual JointParams params() const { return {}; }
  // Joint coordinates: out[k] (k < dof) holds q_k (Phi), its rate (Phi_dot), the row q_x,k
  // (J) with q_dot_k = q_x,k v, and gamma_k. A generalized effort tau_k along coordinate k
  // acts on the bodies as q_x,k^T tau_k.
  // The tracked angles t are the branch references (State).
  virtual void coordinates(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* out) const = 0;
  // Their values alone, q[k] = out[k].Phi of coordinates() bit for bit (a joint type that
  // has a cheaper way computes nothing else; by default coordinates() itself).
  virtual void coordinateValues(const BodyKin& ki, const BodyKin& kj, const Tracked& t, double* q) const;

  const Joint* jointOn(int b) const override { return b == bodyJ() ? this : nullptr; }

  void evaluate(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma) const final {
    RowWriter out(Phi, J, gamma);
    equations(geometry(*kin[0], *kin[1], equationAxes() | ratesPart(ctx)), *kin[0], *kin[1], ctx.tracked[id()], out);
  }
  // evaluate() of the rows `rows` marks alone (bit e: row e; the others' Phi, J and gamma are
  // left as they were, or written): the same numbers on the marked rows. The closures leave
  // out rows no motion of the tree moves (loop_closure.h, idle rows) and skip computing them.
  void evaluateRows(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                    Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma, unsigned rows) const {
    RowWriter out(Phi, J, gamma, rows);
    equations(geometry(*kin[0], *kin[1], equationAxesFor(rows) | ratesPart(ctx)), *kin[0], *kin[1], ctx.tracked[id()],
              out);
  }
  // The same rows written compactly: row e of the rows `rows` marks (at most the first 32),
  // in their order, into row e of Phi, J and gamma (as many rows as marks), the same bits;
  // nothing else written. (The closures' kept rows go straight to their places.)
  void evaluateSelected(const BodyKin* const* kin, const EvalContext& ctx, Eigen::Ref<Eigen::VectorXd> Phi,
                        Eigen::Ref<Eigen::MatrixXd> J, Eigen::Ref<Eigen::VectorXd> gamma, unsigned rows) const {
    RowWriter out(Phi, J, gamma, rows, true);
    equations(geometry(*kin[0], *kin[1], equationAxesFor(rows) | ratesPart(ctx)), *kin[0], *kin[1], ctx.tracked[id()],
              out);
  }
  // Tracked angles are the coordinates k with trackedSlot(k) >= 0: track() stores their
  // values and rates, trackedRates() their rates.
  void track(const BodyKin* const* kin, const EvalContext& ctx, Tracked& t, Tracked& rate) const final;
  void trackAngles(const BodyKin* const* kin, const EvalContext& ctx, Tracked& t) const final;
  void trackedRates(const BodyKin* const* kin, const EvalContext& ctx, Tracked& rate) const final;

  JointGeometry geometry(const BodyKin& ki, const BodyKin& kj, unsigned parts = kAllParts) const;
  // The parts of JointGeometry that equations() reads (GeometryPart bits).
  virtual unsigned equationAxes() const { return kAllParts; }
  // Those the rows `rows` marks read (evaluateRows; by default all of equationAxes()).
  virtual unsigned equationAxesFor(unsigned /*rows*/) const { return equationAxes(); }

 protected:
  virtual void equations(const JointGeometry& g, const BodyKin& ki, const BodyKin& kj,
                         const Tracked& t, RowWriter& out) const = 0;

  // The coordinate rows (at branch references t) when the joint tracks any angle.
  bool trackedRows(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* rows) const;

  // C(p1)(bz_i, bz_j) = tilde(bz_i) bz_j = 0 (A8.1): of its three rows the one along bz_i
  // vanishes identically; its components along by_i and -bx_i are the two independent
  // rows bx_i^T bz_j = 0 and by_i^T bz_j = 0, each a C(n1) (8.11).
  static void putParallelAxes(const JointGeometry& g, RowWriter& out) {
    if (!out.wants(2)) return out.skip(2);  // (evaluateRows: neither row read)
    out.put(Cn1(g.bx_i, g.bz_j));
    out.put(Cn1(g.by_i, g.bz_j));
  }
  // C(p2)(bz_i, d_ij) = tilde(bz_i) d_ij = 0 (A8.2), reduced the same way to
  // bx_i^T d_ij = 0 and by_i^T d_ij = 0, each a C(n2) (8.13).
  static void putOnAxis(const JointGeometry& g, RowWriter& out) {
    if (!out.wants(2)) return out.skip(2);
    out.put(Cn2(g.bx_i, g.d));
    out.put(Cn2(g.by_i, g.d));
  }
  // Point coincidence d_ij = 0.
  static void putPoint(const JointGeometry& g, RowWriter& out);
  // relativeAngle(bx_i, by_i, bx_j)'s value alone (relativeAngleValue), the axes' global
  // components computed as geometry() computes them: the bits of coordinates()' angle.
  double relativeAngleValueOf(const BodyKin& ki, const BodyKin& kj, double phi_ref) const;
  // The geometry's rates when the evaluation asks for them (kNoRates else).
  static unsigned ratesPart(const EvalContext& ctx) { return ctx.rates ? 0u : unsigned{kNoRates}; }

 private:
  JointFrame frame_i_, frame_j_;
};

using JointFactory = std::unique_ptr<Joint> (*)(const std::string& name, int body_i,
                                                const JointFrame& frame_i, int body_j,
                                                const JointFrame& frame_j,
                                                const JointParams& params);

// What a joint type is, described once (joint_registry.cpp): its name, its factory, its
// degrees of freedom and their names ("" for a one-dof joint), and the map from its
// coordinates q (dof values) to the pose of joint frame j in joint frame i, and its tree
// model (TreeJointModel; calc null: the joint-space tree has none). The loader, the XML
// reader, the tree and the tests ask this instead of building joints to learn it.
using RelativePose = Eigen::Isometry3d (*)(const double* q, const JointParams& params);
struct JointTypeInfo {
  std::string name;
  JointFactory make = nullptr;
  std::vector<std::string> dof_names;
  RelativePose relative_pose = nullptr;
  TreeJointModel tree;
  int dof() const { return static_cast<int>(dof_names.size()); }
  Eigen::Isometry3d relativePose(const double* q, const JointParams& params) const {
    return relative_pose(q, params);
  }
};
// Throws ModelError naming the type when it is unknown.
const JointTypeInfo& jointTypeInfo(const std::string& type);
// The tree model of a joint type (null: an unknown type, or one without a tree model), and
// the first registered type's of a tag (ModelError for none; not kFree, the tree's own).
const TreeJointModel* treeJointModel(const std::string& type);
const TreeJointModel& treeJointModel(TreeJointKind kind);

// Joint types by name ("revolute", "screw", ...); throws ModelError on an
// unknown type or parameters the type cannot take.
std::unique_ptr<Joint> makeJoint(const std::string& type, const std::string& name, int body_i,
                                 const JointFrame& frame_i, int body_j,
                                 const JointFrame& frame_j, const JointParams& params = {});
std::vector<std::string> jointTypes();

}  // namespace mechanism_sim
