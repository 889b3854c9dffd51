// Every registered joint type (jointTypes()), each against a case written here (its
// relative motion, equation count and coordinate ranges; a registered type without one
// fails): Jacobian, gamma and coordinate rows against finite differences at random poses
// (a spherical joint's rates against the relative angular velocity); rank of its
// equations in random poses and in assembled poses (the screw at its start angle
// included); coordinates reading back the motion that made the pose, and the registry's
// relative pose matching it; the equations allowing exactly the case's relative motion
// (the fixed joint: none, its relative pose held).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "fd_util.h"
#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/model/joint.h"

namespace mechanism_sim {
namespace {

constexpr double kAlpha = 0.02;  // screw lead per radian

std::unique_ptr<Joint> randomJoint(const std::string& type, std::mt19937& rng) {
  JointFrame fi, fj;
  fi.sp_B = test::randomVector(rng, 0.8);
  fj.sp_B = test::randomVector(rng, 0.8);
  fi.Rp = test::randomRotation(rng);
  fj.Rp = test::randomRotation(rng);
  JointParams params;
  params.alpha = kAlpha;
  return makeJoint(type, type, 1, fi, 2, fj, params);
}

struct Evaluation {
  Eigen::VectorXd Phi, gamma;
  Eigen::MatrixXd J;
};

// A joint on its own: constraint id 0, its tracked angles in tr.
Evaluation evaluate(const Joint& joint, const std::vector<BodyKin>& kin, const Tracked& tr) {
  Evaluation e{Eigen::VectorXd(joint.size()), Eigen::VectorXd(joint.size()),
               Eigen::MatrixXd(joint.size(), 12)};
  const BodyKin* ptrs[2] = {&kin[0], &kin[1]};
  joint.evaluate(ptrs, EvalContext{&tr, nullptr}, e.Phi, e.J, e.gamma);
  return e;
}

// Moves the tracked angles to the pose kin (as an accepted step does). The rates track()
// gives are those trackedRates() gives there, to the bit (a step reuses them).
void track(const Joint& joint, const std::vector<BodyKin>& kin, Tracked& tr) {
  const BodyKin* ptrs[2] = {&kin[0], &kin[1]};
  Tracked rate{NAN, NAN}, expected{NAN, NAN};
  joint.track(ptrs, EvalContext{&tr, nullptr}, tr, rate);
  joint.trackedRates(ptrs, EvalContext{&tr, nullptr}, expected);
  EXPECT_EQ(rate, expected) << joint.type();
}

// A random joint of the type between two bodies at random poses, its angles tracked
// there, and its evaluation: the tests' common start.
struct PosedJoint {
  std::unique_ptr<Joint> joint;
  std::vector<BodyKin> kin;
  Tracked tr;
  Evaluation e;
};

// Whether a and b hold the same bits (the sign of zero included).
bool same(double a, double b) { return a == b && std::signbit(a) == std::signbit(b); }

PosedJoint posedJoint(const std::string& type, std::mt19937& rng) {
  PosedJoint p;
  p.joint = randomJoint(type, rng);
  p.kin = {test::randomBody(rng), test::randomBody(rng)};
  p.tr = p.joint->initialTracked();
  track(*p.joint, p.kin, p.tr);  // track angles from this pose
  p.e = evaluate(*p.joint, p.kin, p.tr);
  return p;
}

// What each joint type is meant to allow, written here and not asked of the registry: the
// relative motion of frame j in frame i (rotation R and translation t, frame i components)
// that its coordinates q describe, how many equations it has, and the range its
// coordinates are drawn from. A registered type without a case here fails every test.
struct FreeMotion {
  Matrix3d R = Matrix3d::Identity();
  Vector3d t = Vector3d::Zero();
};

struct JointCase {
  std::string type;
  int size;                   // equations: 6 - dof
  std::vector<double> range;  // q_k drawn from (-range_k, range_k); its size is the dof
  FreeMotion (*motion)(const std::vector<double>& q);
};

Matrix3d rotX(double x) { return Eigen::AngleAxisd(x, Vector3d::UnitX()).toRotationMatrix(); }
Matrix3d rotY(double x) { return Eigen::AngleAxisd(x, Vector3d::UnitY()).toRotationMatrix(); }
Matrix3d rotZ(double x) { return Eigen::AngleAxisd(x, Vector3d::UnitZ()).toRotationMatrix(); }

const std::vector<JointCase>& jointCases() {
  static const std::vector<JointCase> cases = {
      // rotation vector q about the common point: a rotation by |q| about a generic axis
      // (|q| < pi, where the rotation vector is unique)
      {"spherical", 3, {1.7, 1.7, 1.7},
       [](const std::vector<double>& q) {
         const Vector3d v(q[0], q[1], q[2]);
         FreeMotion m;
         if (v.norm() > 0) m.R = Eigen::AngleAxisd(v.norm(), v.normalized()).toRotationMatrix();
         return m;
       }},
      {"revolute", 5, {3.0},
       [](const std::vector<double>& q) { return FreeMotion{rotZ(q[0]), Vector3d::Zero()}; }},
      {"cylindrical", 4, {3.0, 3.0},
       [](const std::vector<double>& q) { return FreeMotion{rotZ(q[0]), Vector3d(0, 0, q[1])}; }},
      {"prismatic", 5, {3.0},
       [](const std::vector<double>& q) { return FreeMotion{Matrix3d::Identity(), Vector3d(0, 0, q[0])}; }},
      {"screw", 5, {3.0},  // lead kAlpha per radian, phi0 = 0
       [](const std::vector<double>& q) { return FreeMotion{rotZ(q[0]), Vector3d(0, 0, kAlpha * q[0])}; }},
      {"universal", 4, {3.0, 1.5},  // about x of frame i, then about the turned y
       [](const std::vector<double>& q) { return FreeMotion{rotX(q[0]) * rotY(q[1]), Vector3d::Zero()}; }},
      {"fixed", 6, {},  // the relative pose is held: frame j is frame i
       [](const std::vector<double>&) { return FreeMotion{}; }},
      {"planar", 3, {3.0, 3.0, 3.0},  // x, y in the plane of frame i, then the rotation about z
       [](const std::vector<double>& q) { return FreeMotion{rotZ(q[2]), Vector3d(q[0], q[1], 0)}; }},
  };
  return cases;
}

// The case of a registered type; a failure naming it when the test has none.
const JointCase* jointCase(const std::string& type) {
  for (const auto& c : jointCases())
    if (c.type == type) return &c;
  ADD_FAILURE() << "joint type '" << type << "' is registered (jointTypes()) but test_joints.cpp has no case "
                << "for it: add its motion, equation count and coordinate ranges to jointCases()";
  return nullptr;
}

std::vector<double> randomCoordinates(const JointCase& c, std::mt19937& rng, bool at_start) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> q;
  for (double r : c.range) q.push_back(at_start ? 0.0 : r * u(rng));
  return q;
}

// Body j placed so that frame j sits at the relative pose m from frame i on body i.
BodyKin placeJ(const Joint& joint, const BodyKin& ki, const FreeMotion& m, BodyKin kj) {
  const JointFrame &fi = joint.frameI(), &fj = joint.frameJ();
  kj.A_Oi = ki.A_Oi * fi.Rp * m.R * fj.Rp.transpose();
  kj.r = ki.r + ki.A_Oi * (fi.sp_B + fi.Rp * m.t) - kj.A_Oi * fj.sp_B;
  return kj;
}

Tracked trackedAt(const Joint& joint, const std::vector<double>& q) {
  Tracked tr = joint.initialTracked();
  for (int k = 0; k < joint.dof() && k < static_cast<int>(q.size()); ++k)
    if (joint.trackedSlot(k) >= 0) tr[joint.trackedSlot(k)] = q[k];
  return tr;
}

class JointTypes : public ::testing::TestWithParam<std::string> {};

TEST_P(JointTypes, JacobianAndGammaMatchFiniteDifferences) {
  jointCase(GetParam());  // fails for a type without a case (the checks here still run)
  std::mt19937 rng(11);
  for (int n = 0; n < 100; ++n) {
    const auto [joint, kin, tr, e] = posedJoint(GetParam(), rng);
    ASSERT_EQ(e.Phi.size(), joint->size());
    // (init-captures: C++17 captures no structured binding by name)
    auto f = [&joint = joint, &tr = tr](const std::vector<BodyKin>& k) { return evaluate(*joint, k, tr).Phi; };
    const double scale = 1.0 + e.J.cwiseAbs().maxCoeff();
    EXPECT_LT((test::fdJacobian(f, kin) - e.J).cwiseAbs().maxCoeff(), 1e-7 * scale) << n;
    EXPECT_LT((test::fdGamma(f, kin) - e.gamma).cwiseAbs().maxCoeff(),
              2e-5 * (1.0 + e.gamma.cwiseAbs().maxCoeff())) << n;
    EXPECT_EQ(test::rankOf(e.J), joint->size()) << "random pose " << n;
  }
}

// evaluateRows (the closures' idle rows left out): on the rows it is asked for, the bits of
// evaluate(); it writes no other row it was not asked for through the shared helpers.
TEST_P(JointTypes, SelectedRowsAreTheFullEvaluationsRows) {
  std::mt19937 rng(12);
  for (int n = 0; n < 20; ++n) {
    const auto [joint, kin, tr, e] = posedJoint(GetParam(), rng);
    const int size = joint->size();
    const BodyKin* ptrs[2] = {&kin[0], &kin[1]};
    const EvalContext ctx{&tr, nullptr};  // (constraint id 0, as evaluate() above)
    for (unsigned mask = 1; mask < (1u << size); ++mask) {
      Eigen::VectorXd Phi = Eigen::VectorXd::Constant(size, -7.0), gamma = Phi;
      Eigen::MatrixXd J = Eigen::MatrixXd::Constant(size, 12, -7.0);
      joint->evaluateRows(ptrs, ctx, Phi, J, gamma, mask);
      for (int r = 0; r < size; ++r) {
        if (!(mask & (1u << r))) continue;
        EXPECT_EQ(Phi(r), e.Phi(r)) << GetParam() << " mask " << mask << " row " << r;
        EXPECT_EQ(gamma(r), e.gamma(r)) << GetParam() << " mask " << mask << " row " << r;
        EXPECT_EQ((J.row(r) - e.J.row(r)).cwiseAbs().maxCoeff(), 0.0) << GetParam() << " mask " << mask << " row " << r;
      }
    }
  }
}

// evaluateSelected (the closures' kept rows written straight to their places): the marked
// rows of evaluate(), in order, compact, to the bit (sign of zero included), and no row past
// them written.
TEST_P(JointTypes, CompactSelectedRowsAreTheFullEvaluationsRows) {
  std::mt19937 rng(16);
  for (int n = 0; n < 20; ++n) {
    const auto [joint, kin, tr, e] = posedJoint(GetParam(), rng);
    const int size = joint->size();
    const BodyKin* ptrs[2] = {&kin[0], &kin[1]};
    const EvalContext ctx{&tr, nullptr};
    for (unsigned mask = 1; mask < (1u << size); ++mask) {
      Eigen::VectorXd Phi = Eigen::VectorXd::Constant(size, -7.0), gamma = Phi;
      Eigen::MatrixXd J = Eigen::MatrixXd::Constant(size, 12, -7.0);
      joint->evaluateSelected(ptrs, ctx, Phi, J, gamma, mask);
      int k = 0;
      for (int r = 0; r < size; ++r) {
        if (!(mask & (1u << r))) continue;
        EXPECT_TRUE(same(Phi(k), e.Phi(r))) << GetParam() << " mask " << mask << " row " << r;
        EXPECT_TRUE(same(gamma(k), e.gamma(r))) << GetParam() << " mask " << mask << " row " << r;
        for (int c = 0; c < 12; ++c) EXPECT_TRUE(same(J(k, c), e.J(r, c))) << GetParam() << " mask " << mask << " row " << r;
        ++k;
      }
      for (; k < size; ++k) {
        EXPECT_EQ(Phi(k), -7.0) << GetParam() << " mask " << mask;
        EXPECT_EQ(gamma(k), -7.0) << GetParam() << " mask " << mask;
        EXPECT_EQ(J.row(k).cwiseAbs().maxCoeff(), 7.0) << GetParam() << " mask " << mask;
      }
    }
  }
}

// The coordinates' values alone (coordinateValues, a revolute's or a screw's angle computed
// without its variation and rates) are coordinates()' Phi to the bit, and trackAngles() moves
// the tracked angles as track() does, near a reference some turns away too.
TEST_P(JointTypes, CoordinateValuesAndTrackedAnglesAreTheFullOnesBits) {
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> turns(-3.0, 3.0);
  for (int n = 0; n < 40; ++n) {
    auto [joint, kin, tr, e] = posedJoint(GetParam(), rng);
    for (double& a : tr) a += 2.0 * M_PI * std::round(turns(rng)) + 0.4 * turns(rng);
    Row rows[kMaxJointDofs];
    joint->coordinates(kin[0], kin[1], tr, rows);
    double q[kMaxJointDofs];
    joint->coordinateValues(kin[0], kin[1], tr, q);
    for (int k = 0; k < joint->dof(); ++k)
      EXPECT_TRUE(same(q[k], rows[k].Phi)) << GetParam() << " coordinate " << k << ": " << q[k] << " against " << rows[k].Phi;
    const BodyKin* ptrs[2] = {&kin[0], &kin[1]};
    Tracked full = tr, alone = tr, rate;
    joint->track(ptrs, EvalContext{&tr, nullptr}, full, rate);
    joint->trackAngles(ptrs, EvalContext{&tr, nullptr}, alone);
    for (size_t s = 0; s < full.size(); ++s) EXPECT_TRUE(same(alone[s], full[s])) << GetParam() << " slot " << s;
  }
}

// An evaluation without rates (EvalContext::rates false, the queries'): Phi and the
// Jacobian have every bit of the full evaluation's (sign of zero included), and the
// geometry it reads leaves the rates out (zero, where the full one has them).
TEST_P(JointTypes, EvaluationWithoutRatesHasTheFullEvaluationsPhiAndJacobian) {
  std::mt19937 rng(13);
  for (int n = 0; n < 20; ++n) {
    const auto [joint, kin, tr, e] = posedJoint(GetParam(), rng);
    const int size = joint->size();
    const BodyKin* ptrs[2] = {&kin[0], &kin[1]};
    EvalContext ctx{&tr, nullptr};
    ctx.rates = false;
    Eigen::VectorXd Phi(size), gamma(size);
    Eigen::MatrixXd J(size, 12);
    joint->evaluate(ptrs, ctx, Phi, J, gamma);
    for (int r = 0; r < size; ++r) {
      EXPECT_TRUE(same(Phi(r), e.Phi(r))) << GetParam() << " row " << r << ": " << Phi(r) << " against " << e.Phi(r);
      for (int c = 0; c < 12; ++c)
        EXPECT_TRUE(same(J(r, c), e.J(r, c))) << GetParam() << " row " << r << " column " << c;
    }
  }
  // the geometry without rates: the same values and variations, no rates
  auto joint = randomJoint(GetParam(), rng);
  const BodyKin ki = test::randomBody(rng), kj = test::randomBody(rng);
  const JointGeometry full = joint->geometry(ki, kj), bare = joint->geometry(ki, kj, kAllParts | kNoRates);
  for (auto [f, b] : {std::make_pair(&full.bx_i, &bare.bx_i), std::make_pair(&full.bz_j, &bare.bz_j)}) {
    EXPECT_EQ(f->a, b->a);
    EXPECT_EQ(f->a_th, b->a_th);
    EXPECT_GT(f->a_dot.norm(), 0.0);
    EXPECT_EQ(b->a_dot, Vector3d::Zero());
    EXPECT_EQ(b->a_cen, Vector3d::Zero());
  }
  EXPECT_EQ(full.d.d, bare.d.d);
  EXPECT_EQ(full.d.d_thi, bare.d.d_thi);
  EXPECT_EQ(full.d.d_thj, bare.d.d_thj);
  EXPECT_GT(full.d.d_dot.norm(), 0.0);
  EXPECT_EQ(bare.d.d_dot, Vector3d::Zero());
  EXPECT_EQ(bare.d.d_cen, Vector3d::Zero());
}

TEST_P(JointTypes, CoordinateRowsMatchFiniteDifferences) {
  const JointCase* c = jointCase(GetParam());
  if (!c) return;
  std::mt19937 rng(12);
  for (int n = 0; n < 100; ++n) {
    auto joint = randomJoint(GetParam(), rng);
    ASSERT_EQ(joint->dof(), static_cast<int>(c->range.size()));
    if (joint->dof() == 0) {  // fixed: no coordinates, coordinates() writes no row
      const std::vector<BodyKin> kin = {test::randomBody(rng), test::randomBody(rng)};
      Row rows[1];
      rows[0].Phi = 7.0;
      joint->coordinates(kin[0], kin[1], joint->initialTracked(), rows);
      EXPECT_EQ(rows[0].Phi, 7.0);
      continue;
    }
    const std::vector<BodyKin> kin = {test::randomBody(rng), test::randomBody(rng)};
    Tracked tr = joint->initialTracked();
    track(*joint, kin, tr);
    auto coords = [&](const std::vector<BodyKin>& k, Eigen::MatrixXd* G, Eigen::VectorXd* rate,
                      Eigen::VectorXd* gamma) {
      Row rows[3];
      joint->coordinates(k[0], k[1], tr, rows);
      Eigen::VectorXd q(joint->dof());
      for (int c = 0; c < joint->dof(); ++c) {
        q(c) = rows[c].Phi;
        if (G) G->row(c) = rows[c].J;
        if (rate) (*rate)(c) = rows[c].Phi_dot;
        if (gamma) (*gamma)(c) = rows[c].gamma;
      }
      return q;
    };
    Eigen::MatrixXd G(joint->dof(), 12);
    Eigen::VectorXd rate(joint->dof()), gamma(joint->dof());
    coords(kin, &G, &rate, &gamma);
    EXPECT_LT((G * test::velocityOf(kin) - rate).cwiseAbs().maxCoeff(), 1e-10);
    if (!joint->holonomicCoordinates()) {
      // rates, not derivatives of positions: the relative angular velocity in frame i,
      // omega with dR/dt = tilde(omega) R for R = F_i^T F_j (F = A_Oi Rp), by differences
      ASSERT_EQ(joint->dof(), 3);
      auto relative = [&](double t) {
        const BodyKin bi = test::advance(kin[0], t), bj = test::advance(kin[1], t);
        return Matrix3d((bi.A_Oi * joint->frameI().Rp).transpose() * bj.A_Oi * joint->frameJ().Rp);
      };
      const double h = 1e-6;
      const Matrix3d W = (relative(h) - relative(-h)) / (2 * h) * relative(0).transpose();
      EXPECT_LT((Vector3d(W(2, 1), W(0, 2), W(1, 0)) - rate).cwiseAbs().maxCoeff(), 1e-8 * (1 + rate.norm())) << n;
      // gamma is the rates' own: at constant body velocities (advance) d/dt rate = -gamma
      auto rates = [&](const std::vector<BodyKin>& k) {
        Eigen::VectorXd r(3);
        coords(k, nullptr, &r, nullptr);
        return r;
      };
      EXPECT_LT((test::fdRate(rates, kin) + gamma).cwiseAbs().maxCoeff(), 1e-7 * (1 + gamma.cwiseAbs().maxCoeff()))
          << n;
      continue;
    }
    auto f = [&](const std::vector<BodyKin>& k) { return coords(k, nullptr, nullptr, nullptr); };
    EXPECT_LT((test::fdJacobian(f, kin) - G).cwiseAbs().maxCoeff(), 1e-7 * (1 + G.cwiseAbs().maxCoeff()));
    EXPECT_LT((test::fdGamma(f, kin) - gamma).cwiseAbs().maxCoeff(), 2e-5 * (1 + gamma.cwiseAbs().maxCoeff()));
  }
}

TEST(JointRegistry, EveryRegisteredTypeHasATestCaseAndEveryCaseIsRegistered) {
  const std::vector<std::string> types = jointTypes();
  for (const auto& type : types) {
    const JointCase* c = jointCase(type);
    if (!c) continue;
    std::mt19937 rng(10);
    auto joint = randomJoint(type, rng);
    EXPECT_EQ(joint->dof(), static_cast<int>(c->range.size())) << type;
    EXPECT_EQ(jointTypeInfo(type).dof(), joint->dof()) << type;
    EXPECT_EQ(joint->size(), c->size) << type;
    EXPECT_EQ(joint->size() + joint->dof(), 6) << type;  // equations and freedoms share the 6 of a body
    EXPECT_EQ(joint->type(), type);
  }
  for (const auto& c : jointCases())
    EXPECT_NE(std::find(types.begin(), types.end(), c.type), types.end())
        << "test_joints.cpp has a case for joint type '" << c.type << "', which is not registered";
}

TEST_P(JointTypes, FullRankAndZeroViolationInAssembledPoses) {
  const JointCase* c = jointCase(GetParam());
  if (!c) return;
  std::mt19937 rng(13);
  for (int n = 0; n < 100; ++n) {
    auto joint = randomJoint(GetParam(), rng);
    const std::vector<double> q = randomCoordinates(*c, rng, n == 0);  // n = 0: the start pose
    const FreeMotion m = c->motion(q);
    std::vector<BodyKin> kin = {test::randomBody(rng), test::randomBody(rng)};
    kin[1] = placeJ(*joint, kin[0], m, kin[1]);
    const Tracked tr = trackedAt(*joint, q);
    const Evaluation e = evaluate(*joint, kin, tr);
    EXPECT_LT(e.Phi.cwiseAbs().maxCoeff(), 1e-12) << n;
    EXPECT_EQ(test::rankOf(e.J), joint->size()) << "assembled pose " << n;
    Row rows[3];
    joint->coordinates(kin[0], kin[1], tr, rows);
    for (size_t k = 0; k < q.size(); ++k) EXPECT_NEAR(rows[k].Phi, q[k], 1e-10) << n << " coordinate " << k;
    // the registry's map from coordinates to the relative pose is this motion
    if (joint->dof() == static_cast<int>(q.size())) {
      JointParams params;
      params.alpha = kAlpha;
      const Eigen::Isometry3d T = jointTypeInfo(GetParam()).relativePose(q.data(), params);
      EXPECT_LT((T.linear() - m.R).cwiseAbs().maxCoeff(), 1e-12) << n;
      EXPECT_LT((T.translation() - m.t).cwiseAbs().maxCoeff(), 1e-12) << n;
    }
  }
}

// The equations allow exactly the joint's motion: displacing frame j relative to frame i
// (body i held) along the motion's tangent leaves them satisfied to first order, along
// any other relative direction violates them. P maps a relative twist xi of frame j
// (its components: [translation, rotation] in frame j) to the first-order change of Phi,
// by central differences at assembled poses; its null space must be the span of the
// tangents d/dq_k of the motion (also by differences), of dimension dof. For the fixed
// joint that is: every relative displacement violates it, the relative pose is held.
TEST_P(JointTypes, EquationsAllowExactlyTheJointsRelativeMotion) {
  const JointCase* c = jointCase(GetParam());
  if (!c) return;
  std::mt19937 rng(14);
  const double eps = 1e-6;
  auto displaced = [](const FreeMotion& m, const Eigen::Matrix<double, 6, 1>& xi) {
    FreeMotion d;
    d.R = m.R * expRotation(xi.tail<3>()).toRotationMatrix();
    d.t = m.t + m.R * xi.head<3>();
    return d;
  };
  auto twist = [](const FreeMotion& from, const FreeMotion& to) {  // in frame j of 'from'
    Eigen::Matrix<double, 6, 1> xi;
    xi << from.R.transpose() * (to.t - from.t), logRotation(Quaterniond(Matrix3d(from.R.transpose() * to.R)));
    return xi;
  };
  for (int n = 0; n < 50; ++n) {
    auto joint = randomJoint(GetParam(), rng);
    const std::vector<double> q = randomCoordinates(*c, rng, n == 0);
    const FreeMotion m = c->motion(q);
    const BodyKin ki = test::randomBody(rng), kj0 = test::randomBody(rng);
    const Tracked tr = trackedAt(*joint, q);
    auto phi = [&](const FreeMotion& rel) {
      return evaluate(*joint, {ki, placeJ(*joint, ki, rel, kj0)}, tr).Phi;
    };
    Eigen::MatrixXd P(joint->size(), 6);
    for (int k = 0; k < 6; ++k) {
      Eigen::Matrix<double, 6, 1> xi = Eigen::Matrix<double, 6, 1>::Zero();
      xi(k) = eps;
      P.col(k) = (phi(displaced(m, xi)) - phi(displaced(m, -xi))) / (2 * eps);
    }
    const double scale = 1.0 + P.cwiseAbs().maxCoeff();
    for (size_t k = 0; k < q.size(); ++k) {
      std::vector<double> qp = q, qm = q;
      qp[k] += eps;
      qm[k] -= eps;
      const Eigen::Matrix<double, 6, 1> tangent = (twist(m, c->motion(qp)) - twist(m, c->motion(qm))) / (2 * eps);
      ASSERT_GT(tangent.norm(), 1e-3) << "coordinate " << k << " does not move the case's motion";
      EXPECT_LT((P * tangent).norm(), 1e-7 * scale * tangent.norm())
          << "pose " << n << ": moving coordinate " << k << " violates the equations";
    }
    EXPECT_EQ(test::rankOf(P), 6 - static_cast<int>(q.size()))
        << "pose " << n << ": the equations allow a relative motion the joint does not have (or forbid one it has)";
  }
}

INSTANTIATE_TEST_SUITE_P(AllTypes, JointTypes, ::testing::ValuesIn(jointTypes()),
                         [](const auto& info) { return info.param; });

TEST(JointRegistry, UnknownTypeAndInfiniteLeadAreRejected) {
  JointFrame f;
  EXPECT_THROW(makeJoint("helical", "j", 1, f, 2, f), ModelError);
  EXPECT_THROW(makeJoint("screw", "j", 1, f, 2, f, JointParams{INFINITY, 0.0}), ModelError);
  EXPECT_EQ(makeJoint("screw", "j", 1, f, 2, f, JointParams{0.01, 0.0})->size(), 5);
}

// The screw counts turns: after ten turns phi is 20 pi + x, not x.
TEST(ScrewJoint, TracksManyTurns) {
  JointFrame f;
  auto joint = makeJoint("screw", "s", 1, f, 2, f, JointParams{0.01, 0.0});
  std::vector<BodyKin> kin(2);
  Tracked tr = joint->initialTracked();
  double phi = 0;
  for (int k = 0; k < 200; ++k) {
    phi += 0.33;
    kin[1].A_Oi = Eigen::AngleAxisd(phi, Vector3d::UnitZ()).toRotationMatrix();
    kin[1].r = Vector3d(0, 0, 0.01 * phi);
    track(*joint, kin, tr);
    const Evaluation e = evaluate(*joint, kin, tr);
    EXPECT_LT(e.Phi.cwiseAbs().maxCoeff(), 1e-12);
  }
  Row rows[1];
  joint->coordinates(kin[0], kin[1], tr, rows);
  EXPECT_NEAR(rows[0].Phi, phi, 1e-9);
}

}  // namespace
}  // namespace mechanism_sim
