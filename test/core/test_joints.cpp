// Every joint type: Jacobian, gamma and coordinate rows against finite differences at
// random poses; rank of its equations in random poses and in assembled poses (the screw
// at its start angle included); coordinates reading back the motion that made the pose.
#include <gtest/gtest.h>

#include "fd_util.h"
#include "mechanism_sim/core/joint.h"

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

class JointTypes : public ::testing::TestWithParam<std::string> {};

TEST_P(JointTypes, JacobianAndGammaMatchFiniteDifferences) {
  std::mt19937 rng(11);
  for (int n = 0; n < 100; ++n) {
    auto joint = randomJoint(GetParam(), rng);
    const std::vector<BodyKin> kin = {test::randomBody(rng), test::randomBody(rng)};
    Tracked tr = joint->initialTracked();
    track(*joint, kin, tr);  // track angles from this pose
    const Evaluation e = evaluate(*joint, kin, tr);
    ASSERT_EQ(e.Phi.size(), joint->size());
    auto f = [&](const std::vector<BodyKin>& k) { return evaluate(*joint, k, tr).Phi; };
    const double scale = 1.0 + e.J.cwiseAbs().maxCoeff();
    EXPECT_LT((test::fdJacobian(f, kin) - e.J).cwiseAbs().maxCoeff(), 1e-7 * scale) << n;
    EXPECT_LT((test::fdGamma(f, kin) - e.gamma).cwiseAbs().maxCoeff(),
              2e-5 * (1.0 + e.gamma.cwiseAbs().maxCoeff())) << n;
    EXPECT_EQ(test::rankOf(e.J), joint->size()) << "random pose " << n;
  }
}

TEST_P(JointTypes, CoordinateRowsMatchFiniteDifferences) {
  std::mt19937 rng(12);
  for (int n = 0; n < 100; ++n) {
    auto joint = randomJoint(GetParam(), rng);
    if (joint->dof() == 0) return;
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
    if (!joint->holonomicCoordinates()) continue;  // rates, not derivatives of positions
    auto f = [&](const std::vector<BodyKin>& k) { return coords(k, nullptr, nullptr, nullptr); };
    EXPECT_LT((test::fdJacobian(f, kin) - G).cwiseAbs().maxCoeff(), 1e-7 * (1 + G.cwiseAbs().maxCoeff()));
    EXPECT_LT((test::fdGamma(f, kin) - gamma).cwiseAbs().maxCoeff(), 2e-5 * (1 + gamma.cwiseAbs().maxCoeff()));
  }
}

// Relative motion along the joint's free directions, frame i to frame j:
// rotation R and translation t (in frame i), and the coordinates that describe it.
struct FreeMotion {
  Matrix3d R = Matrix3d::Identity();
  Vector3d t = Vector3d::Zero();
  std::vector<double> q;
};

FreeMotion freeMotion(const std::string& type, std::mt19937& rng, bool at_start) {
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  const double a = at_start ? 0.0 : u(rng), b = at_start ? 0.0 : u(rng) / 2, c = at_start ? 0.0 : u(rng);
  FreeMotion m;
  auto Rz = [](double x) { return Eigen::AngleAxisd(x, Vector3d::UnitZ()).toRotationMatrix(); };
  if (type == "spherical") m.R = test::randomRotation(rng);
  if (type == "revolute") m.R = Rz(a), m.q = {a};
  if (type == "cylindrical") m.R = Rz(a), m.t.z() = c, m.q = {a, c};
  if (type == "prismatic") m.t.z() = c, m.q = {c};
  if (type == "screw") m.R = Rz(a), m.t.z() = kAlpha * a, m.q = {a};
  if (type == "universal")
    m.R = Eigen::AngleAxisd(a, Vector3d::UnitX()).toRotationMatrix() *
          Eigen::AngleAxisd(b, Vector3d::UnitY()).toRotationMatrix(),
    m.q = {a, b};
  if (type == "planar") m.R = Rz(a), m.t << b, c, 0, m.q = {b, c, a};
  return m;
}

TEST_P(JointTypes, FullRankAndZeroViolationInAssembledPoses) {
  std::mt19937 rng(13);
  for (int n = 0; n < 100; ++n) {
    auto joint = randomJoint(GetParam(), rng);
    const FreeMotion m = freeMotion(GetParam(), rng, n == 0);  // n = 0: the start pose
    std::vector<BodyKin> kin = {test::randomBody(rng), test::randomBody(rng)};
    const JointFrame &fi = joint->frameI(), &fj = joint->frameJ();
    kin[1].A_Oi = kin[0].A_Oi * fi.Rp * m.R * fj.Rp.transpose();
    kin[1].r = kin[0].r + kin[0].A_Oi * (fi.sp_B + fi.Rp * m.t) - kin[1].A_Oi * fj.sp_B;
    Tracked tr = joint->initialTracked();
    for (int k = 0; k < joint->dof() && k < static_cast<int>(m.q.size()); ++k)
      if (joint->trackedSlot(k) >= 0) tr[joint->trackedSlot(k)] = m.q[k];
    const Evaluation e = evaluate(*joint, kin, tr);
    EXPECT_LT(e.Phi.cwiseAbs().maxCoeff(), 1e-12) << n;
    EXPECT_EQ(test::rankOf(e.J), joint->size()) << "assembled pose " << n;
    Row rows[3];
    joint->coordinates(kin[0], kin[1], tr, rows);
    for (size_t k = 0; k < m.q.size(); ++k) EXPECT_NEAR(rows[k].Phi, m.q[k], 1e-10) << n;
  }
}

INSTANTIATE_TEST_SUITE_P(AllTypes, JointTypes, ::testing::ValuesIn(jointTypes()),
                         [](const auto& info) { return info.param; });

TEST(JointRegistry, UnknownTypeAndInfiniteLeadAreRejected) {
  JointFrame f;
  EXPECT_THROW(makeJoint("helical", "j", 1, f, 2, f), std::invalid_argument);
  EXPECT_THROW(makeJoint("screw", "j", 1, f, 2, f, JointParams{INFINITY, 0.0}), std::invalid_argument);
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
