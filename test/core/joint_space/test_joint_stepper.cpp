// The joint formulation (joint_stepper.h) against known answers and against the absolute
// formulation, which stays the reference: the same trees move the same way in both; a wheel
// at 4000 rad/s and a nut on a screw spun as fast are exact to round-off at 1 ms (where
// the absolute formulation halves its steps 16 times and still carries RK4's phase error);
// a pendulum 1e5 m from the origin swings as the one at the origin; errors fall as h^4; a
// snapshot continues bit for bit; and the choice of formulation is explicit and explained.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <cstdio>
#include <random>
#include <string>

#include "bodies.h"
#include "compare.h"
#include "core/absolute/stepper.h"
#include "core/joint_space/joint_stepper.h"
#include "mechanism_sim/core/models.h"
#include "pendulum.h"

namespace mechanism_sim {
namespace {

using test_util::frame;

IntegratorOptions formulation(const char* f, const char* method = "rk4") {
  IntegratorOptions io;
  io.formulation = f;
  io.method = method;
  return io;
}

// The same mechanism (`model` adds it) in absolute coordinates (a) and joint ones (j),
// built and assembled.
void buildBoth(Mechanism& a, Mechanism& j, const std::function<void(Mechanism&)>& model) {
  for (auto [m, f] : {std::make_pair(&a, "absolute"), std::make_pair(&j, "joint")}) {
    model(*m);
    m->setIntegrator(formulation(f));
    m->build();
    m->assemble();
  }
}

// A random tree of every joint type and a free body, frames coinciding at the start,
// random velocities (assembly projects them), random efforts and a spring.
void randomTree(Mechanism& m, unsigned seed, int n) {
  std::mt19937 rng(seed);
  auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  auto rotation = [&]() {
    return Quaterniond(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)).normalized().toRotationMatrix();
  };
  const char* types[] = {"revolute", "prismatic", "cylindrical", "screw", "universal", "spherical", "planar", "fixed"};
  std::vector<Vector3d> r(1, Vector3d::Zero());
  std::vector<Matrix3d> A(1, Matrix3d::Identity());
  for (int b = 1; b <= n; ++b) {
    const int parent = std::uniform_int_distribution<int>(0, b - 1)(rng);
    const Vector3d P = r[parent] + 0.3 * Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    const Vector3d rb = P + 0.3 * Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    const Matrix3d Ab = rotation(), R = rotation();
    const double mass = uniform(0.5, 2.0);
    Body body = test_util::body("b" + std::to_string(b), mass, mass * Vector3d(uniform(0.01, 0.02), uniform(0.01, 0.02), uniform(0.01, 0.02)), rb);
    body.p = Quaterniond(Ab);
    body.v = 0.3 * Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    body.w = Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    m.addBody(body);
    r.push_back(rb), A.push_back(Ab);
    JointParams params;
    params.alpha = 0.05;
    m.addJoint(makeJoint(types[std::uniform_int_distribution<int>(0, 7)(rng)], "j" + std::to_string(b), parent,
                         frame(A[parent].transpose() * (P - r[parent]), A[parent].transpose() * R), b,
                         frame(Ab.transpose() * (P - rb), Ab.transpose() * R), params));
  }
  // a free body tied to the tree by a spring
  Body free = test_util::body("free", 1.0, Vector3d(0.02, 0.03, 0.04), Vector3d(0.5, 0.2, -0.4));
  free.w = Vector3d(0.5, -1.0, 2.0);
  const int f = m.addBody(free);
  SpringDamper s;
  s.name = "tie";
  s.body_i = 1, s.body_j = f, s.k = 20.0, s.c = 0.5, s.L0 = 0.3;
  m.addSpring(s);
}

// Joint positions of both formulations after T seconds of the same tree.
double treeDifference(unsigned seed, double h, double T) {
  Mechanism a, j;
  randomTree(a, seed, 3 + static_cast<int>(seed % 7));
  randomTree(j, seed, 3 + static_cast<int>(seed % 7));
  a.setIntegrator(formulation("absolute"));
  j.setIntegrator(formulation("joint"));
  for (Mechanism* m : {&a, &j}) {
    m->build();
    m->assemble();
    for (int k = 0; k < m->numJoints(); ++k)
      if (m->joint(k).dof() > 0) m->setJointEffort(k, 0, 0.05 * std::cos(k + 1.0));
  }
  EXPECT_STREQ(j.formulation(), "joint");
  EXPECT_STREQ(a.formulation(), "absolute");
  for (long k = 0, n = std::lround(T / h); k < n; ++k) a.step(h), j.step(h);
  return test_util::difference(a, j);
}

// The two formulations are two discretizations of the same equations: their difference
// is the larger of their truncation errors, O(h^4), and vanishes with h.
TEST(JointFormulation, RandomTreesMoveAsInAbsoluteCoordinates) {
  double worst_1ms = 0, worst_half = 0;
  for (unsigned seed = 1; seed <= 8; ++seed) {
    const double d1 = treeDifference(seed, 1e-3, 2.0), d2 = treeDifference(seed, 5e-4, 2.0);
    worst_1ms = std::max(worst_1ms, d1);
    worst_half = std::max(worst_half, d2);
    EXPECT_LT(d2, 1e-8) << "seed " << seed;
  }
  std::printf("[random trees] joint against absolute after 2 s: %.2e at 1 ms, %.2e at 0.5 ms\n", worst_1ms, worst_half);
  EXPECT_GT(worst_1ms / worst_half, 10.0) << "the difference does not fall as h^4";
}

// The accelerations, efforts and reactions the queries report at one state are those of
// the absolute formulation at that state.
TEST(JointFormulation, QueriesAtAStateAreTheAbsoluteOnes) {
  Mechanism a, j;
  randomTree(a, 11, 6);
  randomTree(j, 11, 6);
  a.setIntegrator(formulation("absolute"));
  j.setIntegrator(formulation("auto"));
  for (Mechanism* m : {&a, &j}) {
    m->build();
    m->assemble();
    m->setJointEffort(0, 0, 0.3);
  }
  EXPECT_STREQ(j.formulation(), "joint") << j.formulationReason();
  for (int k = 0; k < 50; ++k) j.step(1e-3);
  a.restore(j.snapshot());  // the joint formulation's state, solved in absolute coordinates
  a.step(1e-9);             // (a step of round-off size: the absolute accelerations there)
  double acc = 0, scale = 0;
  for (int k = 0; k < j.numJoints(); ++k)
    for (int c = 0; c < j.joint(k).dof(); ++c) {
      acc = std::max(acc, std::fabs(a.jointAcceleration(k, c) - j.jointAcceleration(k, c)));
      scale = std::max(scale, std::fabs(a.jointAcceleration(k, c)));
    }
  EXPECT_LT(acc, 1e-6 * scale);
  const std::vector<Reaction> ra = a.jointReactions(), rj = j.jointReactions();
  double react = 0, rscale = 0;
  for (size_t k = 0; k < ra.size(); ++k) {
    react = std::max({react, (ra[k].force - rj[k].force).norm(), (ra[k].torque - rj[k].torque).norm()});
    rscale = std::max({rscale, ra[k].force.norm(), ra[k].torque.norm()});
  }
  std::printf("[queries] joint against absolute: accelerations %.2e, reactions %.2e (relative)\n", acc / scale,
              react / rscale);
  EXPECT_LT(react, 1e-6 * rscale);
}

// A step leaves the bodies' state State::x, u and acc to be written when something reads
// it (State::bodies_pending). What a reader gets is the same bits whether the stepper still
// holds the step's kinematics or another stepper writes them, and the accelerations are
// the absolute formulation's solve at that state; Mechanism hands out only complete States.
TEST(JointFormulation, TheBodiesStateIsWrittenWhenRead) {
  Mechanism m;
  randomTree(m, 5, 6);
  // (damping: no step is judged by its error estimate, which reads the accelerations)
  for (int k = 0; k < m.numJoints(); ++k)
    if (m.joint(k).dof() > 0) m.setJointDamping(k, 0, 0.01);
  m.setIntegrator(formulation("absolute"));
  m.build();
  m.assemble();
  const System& sys = m.system();
  Inputs in = zeroInputs(sys);
  in.effort[0][0] = 0.3;
  State s = m.snapshot();
  JointStepper js(sys);
  js.settle(sys, s, in);
  EXPECT_FALSE(s.bodies_pending);
  for (int k = 0; k < 20; ++k) js.step(sys, s, in, 1e-3);
  ASSERT_TRUE(s.bodies_pending);
  State elsewhere = s;
  js.completeState(s);  // (from the kinematics the step left)
  EXPECT_FALSE(s.bodies_pending);
  JointStepper other(sys);
  other.completeState(elsewhere);  // (from the State alone)
  EXPECT_FALSE(elsewhere.bodies_pending);
  for (const auto& [a, b] : {std::make_pair(&s.x, &elsewhere.x), std::make_pair(&s.u, &elsewhere.u),
                              std::make_pair(&s.acc, &elsewhere.acc)}) {
    ASSERT_EQ(a->size(), b->size());
    for (Eigen::Index i = 0; i < a->size(); ++i) EXPECT_EQ((*a)[i], (*b)[i]) << i;
  }
  // the absolute formulation's accelerations at the same positions and velocities
  State d = s;
  Stepper absolute(sys);
  absolute.adopt(sys, d, in);
  absolute.settle(sys, d, in);
  const double scale = d.acc.cwiseAbs().maxCoeff();
  EXPECT_LT((d.acc - s.acc).cwiseAbs().maxCoeff(), 1e-9 * scale);
  // (an absolute stepper refuses a State whose accelerations are pending)
  State pending = elsewhere;
  pending.bodies_pending = true;
  EXPECT_THROW(absolute.adopt(sys, pending, in), std::logic_error);

  Mechanism j;
  randomTree(j, 5, 6);
  j.setIntegrator(formulation("joint"));
  j.build();
  j.assemble();
  for (int k = 0; k < 20; ++k) j.step(1e-3);
  EXPECT_FALSE(j.snapshot().bodies_pending);
  EXPECT_FALSE(j.state().bodies_pending);
}

// A wheel spinning at 4000 rad/s, and a nut on a screw of 1 mm lead spun as fast, stepped
// at 1 ms: the angle is a coordinate integrated exactly (constant rate), not a rotation
// followed by RK4.
TEST(JointFormulation, FastWheelAndScrewAreExact) {
  for (const char* type : {"revolute", "screw"}) {
    Mechanism m;
    const int w = m.addBody(body("wheel", 1.0, Vector3d(0.1, 0.1, 0.2).asDiagonal(), Vector3d::Zero()));
    JointParams params;
    params.alpha = 1e-3 / (2 * M_PI);
    m.addJoint(makeJoint(type, "axle", Mechanism::kGround, JointFrame(), w, JointFrame(), params));
    m.setGravity(Vector3d::Zero());
    m.setIntegrator(formulation("joint"));
    m.build();
    m.assemble({}, {CoordinateTarget{0, 0, 4000.0}});
    for (int k = 0; k < 1000; ++k) m.step(1e-3);
    const double angle = m.jointPosition(0, 0) - 4000.0;
    std::printf("[%s at 4000 rad/s, 1 ms] angle off by %.2e rad after 1 s", type, angle);
    EXPECT_LT(std::fabs(angle), 1e-6) << type;
    if (std::string(type) == "screw") {
      const double height = m.position(w).z() - params.alpha * 4000.0;
      std::printf(", height off by %.2e m", height);
      EXPECT_LT(std::fabs(height), 1e-6 * params.alpha * 2 * M_PI);
    }
    std::printf("\n");
  }
}

// The state's update carries its round-off to the next step (joint_stepper.cpp, compensated
// summation): a wheel at 1 rad/s, 1e5 steps of 0.1 ms, is at 10 rad to a few ulps. The
// plain sum q + h q_dot rounded at every step was 1e-11 rad off (an error a step of the ulp
// of q, which smaller steps make more of).
TEST(JointFormulation, SmallStepsDoNotAccumulateTheUpdatesRoundOff) {
  Mechanism m;
  const int w = m.addBody(body("wheel", 1.0, Vector3d(0.1, 0.1, 0.2).asDiagonal(), Vector3d::Zero()));
  m.addJoint(makeJoint("revolute", "axle", Mechanism::kGround, JointFrame(), w, JointFrame()));
  m.setGravity(Vector3d::Zero());
  m.setIntegrator(formulation("joint"));
  m.build();
  m.assemble({}, {CoordinateTarget{0, 0, 1.0}});
  const double rate = m.jointVelocity(0, 0), h = 1e-4;
  const long n = 100000;
  for (long k = 0; k < n; ++k) m.step(h);
  const double off = static_cast<double>(m.jointPosition(0, 0) - static_cast<long double>(n) * h * rate);
  std::printf("[wheel at 1 rad/s, 1e5 steps of 0.1 ms] angle off by %.2e rad\n", off);
  EXPECT_LT(std::fabs(m.jointVelocity(0, 0) - rate), 1e-15);
  EXPECT_LT(std::fabs(off), 1e-13);
}

// A pendulum 1e5 m from the origin swings as the same pendulum at the origin: its angle is
// relative to its pivot, whatever the pivot's coordinates.
TEST(JointFormulation, PendulumFarFromTheOriginSwingsAsAtTheOrigin) {
  Pendulum near, far;
  far.pivot = Vector3d(1e5, -2e4, 3e4);
  Mechanism a, b;
  near.add(a), far.add(b);
  for (Mechanism* m : {&a, &b}) {
    m->setIntegrator(formulation("joint"));
    m->build();
    m->assemble();
    for (int k = 0; k < 2000; ++k) m->step(1e-3);
  }
  const double d = std::fabs(a.jointPosition(0, 0) - b.jointPosition(0, 0));
  std::printf("[pendulum 1e5 m out] angle differs from the one at the origin by %.2e rad after 2 s\n", d);
  EXPECT_LT(d, 1e-8);
}

// A step far beyond explicit RK4's stability even in the 64 substeps step control takes
// (a 4-link chain released at 30 s steps, substeps of 0.47 s: its rates grow without bound
// within a few steps) ends in an error that says so, not in one about the model's inertia
// (the articulated inertia turns NaN once the state is infinite). (At 0.3 s steps the
// substeps of 4.7 ms follow the chain.)
TEST(JointFormulation, ADivergingIntegrationSaysSo) {
  Mechanism m;
  models::pendulumChain(m, 4, 0.5, 1.0, 1.2);
  m.setIntegrator(formulation("joint"));
  m.build();
  m.assemble();
  std::string what;
  int k = 0;
  try {
    for (; k < 1000; ++k) m.step(30.0);
  } catch (const Error& e) {
    what = e.what();
  }
  std::printf("[chain at 0.3 s steps] stopped at step %d: %s\n", k, what.c_str());
  EXPECT_LT(k, 1000);
  EXPECT_NE(what.find("diverged"), std::string::npos) << what;
}

// RK4's truncation error: the pendulum at 1 ms is within 1e-10 m of the exact motion after
// 10 s, and the error falls as h^4.
TEST(JointFormulation, PendulumReachesRk4sTruncationError) {
  auto error = [](double h, double T) {
    Pendulum p;
    Mechanism m;
    const int b = p.add(m);
    m.setIntegrator(formulation("joint"));
    m.build();
    m.assemble();
    for (long k = 0, n = std::lround(T / h); k < n; ++k) m.step(h);
    return (m.position(b) - p.exact(T)).norm();
  };
  const double e10 = error(1e-3, 10.0);
  std::printf("[pendulum] joint formulation, 10 s at 1 ms: %.2e m from the exact motion\n", e10);
  EXPECT_LT(e10, 1e-10);
  double previous = 0;
  for (double h : {8e-3, 4e-3, 2e-3}) {
    const double e = error(h, 2.0);
    if (previous > 0) EXPECT_GT(previous / e, 12.0) << "h = " << h;
    previous = e;
  }
}

// A snapshot is the State, joint state included: restoring it repeats the run bit for bit.
TEST(JointFormulation, SnapshotRestoreContinuesBitIdentically) {
  Mechanism m;
  randomTree(m, 5, 5);
  m.setIntegrator(formulation("joint"));
  m.build();
  m.assemble();
  for (int k = 0; k < 100; ++k) m.step(1e-3);
  const auto [a, b] = test_util::runTwiceFromSnapshot(m, 200);
  ASSERT_EQ(a.q.size(), b.q.size());
  for (int i = 0; i < a.q.size(); ++i) ASSERT_EQ(a.q[i], b.q[i]) << i;
  for (int i = 0; i < a.x.size(); ++i) ASSERT_EQ(a.x[i], b.x[i]) << i;
  EXPECT_EQ(a.tracked, b.tracked);
}

// The queries read the evaluation of the State, found once per state (Mechanism::evaluated
// keeps it until the State changes): after every kind of change they answer as a
// Mechanism restored to that State does.
TEST(JointFormulation, QueriesFollowEveryChangeOfTheState) {
  for (const char* f : {"joint", "absolute"}) {
    Mechanism m, fresh;
    randomTree(m, 7, 5);
    randomTree(fresh, 7, 5);
    for (Mechanism* x : {&m, &fresh}) {
      x->setIntegrator(formulation(f));
      x->build();
      x->assemble();
    }
    auto same = [&](const char* after) {
      fresh.restore(m.snapshot());
      auto close = [&](double a, double b) { return std::fabs(a - b) <= 1e-12 * std::max(1.0, std::fabs(b)); };
      for (int b = 1; b < m.numBodies(); ++b)
        EXPECT_TRUE((m.position(b) - fresh.position(b)).norm() <= 1e-12 * std::max(1.0, fresh.position(b).norm()))
            << f << ", after " << after << ": body " << b;
      for (int j = 0; j < m.numJoints(); ++j)
        for (int k = 0; k < m.joint(j).dof(); ++k)
          EXPECT_TRUE(close(m.jointPosition(j, k), fresh.jointPosition(j, k)) &&
                      close(m.jointVelocity(j, k), fresh.jointVelocity(j, k)))
              << f << ", after " << after << ": joint " << j << " coordinate " << k;
      EXPECT_TRUE(close(m.positionViolation(), fresh.positionViolation())) << f << ", after " << after;
    };
    same("assemble");
    const Mechanism::Snapshot snap = m.snapshot();
    m.step(1e-3);
    same("a step");
    m.restore(snap);
    same("restore");
    m.setIntegrator(formulation(std::string(f) == "joint" ? "absolute" : "joint"));
    same("a change of formulation");
    m.step(1e-3);
    same("a step in the other formulation");
  }
}

// The same through a loop's branch passage (branch_passage.cpp), where what is held
// across the branch comes from the step before: it is in the State too. The snapshot is
// taken just before the four-bar passes flat; the restored run's first step computes its
// accelerations again, the uninterrupted one reuses them.
TEST(JointFormulation, SnapshotRestoreContinuesBitIdenticallyThroughABranchPassage) {
  Mechanism m;
  models::fourBarChain(m, 1, 0.4, 1.0, 0.3);  // flat at q = 0.3
  m.setIntegrator(formulation("joint"));
  m.build();
  m.assemble({CoordinateTarget{0, 0, 0.0}}, {CoordinateTarget{0, 0, 9.0}});
  while (m.jointPosition(0, 0) < 0.295) m.step(1e-3);  // (0.005 rad before flat: held there)
  const Mechanism::Snapshot snap = m.snapshot();
  auto run = [&]() {
    for (int k = 0; k < 100; ++k) m.step(1e-3);
    return m.snapshot();
  };
  const State a = run();
  EXPECT_GT(m.jointPosition(0, 0), 0.5) << "passed flat";
  m.restore(snap);
  const State b = run();
  for (int i = 0; i < a.q.size(); ++i) ASSERT_EQ(a.q[i], b.q[i]) << i;
  for (int i = 0; i < a.qdot.size(); ++i) ASSERT_EQ(a.qdot[i], b.qdot[i]) << i;
  EXPECT_EQ(a.tracked, b.tracked);
}

// Limits, a drive and a mimic coupler are equations on the joint coordinates: a chain
// swinging onto its stops, its top joint driven and two joints coupled, moves as in
// absolute coordinates (joint positions after 1 s; the same stops reached), passes no
// stop, and reports the drive's effort and the stops' reactions as the absolute one.
TEST(JointFormulation, LimitsDrivesAndCouplersMoveAsInAbsoluteCoordinates) {
  Mechanism a, j;
  buildBoth(a, j, [](Mechanism& m) {
    models::pendulumChain(m, 4, 0.5, 1.0, 0.4);
    m.setJointLimits(1, 0, -0.3, 0.3);
    m.setJointLimits(2, 0, -0.25, 0.25);
    m.addCoupler("mimic", 3, 0, 2, 0, -0.5, 0.0);
    m.addDrive(0, 0, DriveProfile::harmonic(0.0, 0.3, 0.7, 0.0));
  });
  ASSERT_STREQ(j.formulation(), "joint") << j.formulationReason();
  bool reached = false;
  double worst_drive = 0, drive_scale = 0;
  for (int k = 0; k < 1000; ++k) {
    a.step(1e-3), j.step(1e-3);
    for (int q : {1, 2}) {
      const double stop = q == 1 ? 0.3 : 0.25;
      ASSERT_LE(std::fabs(j.jointPosition(q, 0)), stop + 1e-9) << "joint " << q << " at t = " << j.time();
      reached = reached || std::fabs(j.jointPosition(q, 0)) > stop - 1e-9;
    }
    worst_drive = std::max(worst_drive, std::fabs(a.jointEffort(0, 0) - j.jointEffort(0, 0)));
    drive_scale = std::max(drive_scale, std::fabs(a.jointEffort(0, 0)));
  }
  EXPECT_TRUE(reached) << "no stop reached: the test did not test the stops";
  double worst = 0;
  for (int q = 0; q < 4; ++q) worst = std::max(worst, std::fabs(a.jointPosition(q, 0) - j.jointPosition(q, 0)));
  std::printf("[limits, drive, coupler] joint against absolute after 1 s: positions %.2e rad, drive effort %.2e "
              "(relative, largest over the run)\n",
              worst, worst_drive / drive_scale);
  EXPECT_LT(worst, 1e-7);
  // (over the run the efforts differ most at the steps where a stop engages: an inelastic
  // impact, taken by each formulation's own projection; at the end they agree)
  EXPECT_LT(worst_drive, 1e-2 * drive_scale);
  EXPECT_NEAR(a.jointEffort(0, 0), j.jointEffort(0, 0), 1e-7 * drive_scale);
  EXPECT_NEAR(j.jointPosition(3, 0), -0.5 * j.jointPosition(2, 0), 1e-12);
  EXPECT_NEAR(j.jointPosition(0, 0), 0.3 * std::sin(2 * M_PI * 0.7 * 1.0), 1e-12);
}

// Joint damping, not stiff (h c / I well below RK4's threshold): an effort in the stages
// of both formulations, so a damped 6-link chain swinging from horizontal moves the same
// way in both (joint positions after 2 s), loses energy monotonically, and its joints
// report -c q_dot. (Stiff damping: test_stiff_damping.cpp runs every case in both.)
TEST(JointFormulation, DampedChainMovesAsInAbsoluteCoordinates) {
  Mechanism a, j;
  buildBoth(a, j, [](Mechanism& m) {
    models::pendulumChain(m, 6, 0.3, 0.5, 0.0);
    for (int k = 0; k < 6; ++k) m.setJointDamping(k, 0, 0.02 * (k + 1));
  });
  ASSERT_STREQ(j.formulation(), "joint");
  double E = j.kineticEnergy() + j.potentialEnergy(), worst = 0;
  for (int s = 0; s < 4000; ++s) {
    a.step(5e-4), j.step(5e-4);
    const double E1 = j.kineticEnergy() + j.potentialEnergy();
    ASSERT_LE(E1, E + 1e-12 * std::fabs(E)) << "t = " << j.time();
    E = E1;
  }
  for (int k = 0; k < 6; ++k) worst = std::max(worst, std::fabs(a.jointPosition(k, 0) - j.jointPosition(k, 0)));
  std::printf("[damped chain] joint against absolute after 2 s: %.2e rad\n", worst);
  EXPECT_LT(worst, 1e-8);
  for (int k = 0; k < 6; ++k) EXPECT_DOUBLE_EQ(j.jointEffort(k, 0), -0.02 * (k + 1) * j.jointVelocity(k, 0));
}

// The choice: "auto" runs trees and loops in joint coordinates (drives at most one per 2
// coordinates), saying why; "joint" refuses what it cannot run with the reason, the mechanism unchanged.
TEST(JointFormulation, TheChoiceIsExplainedAndRefusalsAreClear) {
  Mechanism chain;
  models::pendulumChain(chain, 3);
  chain.setIntegrator(formulation("auto"));
  chain.build();
  EXPECT_STREQ(chain.formulation(), "joint") << chain.formulationReason();

  // limits cost the joint formulation nothing while free, and couplers on tree coordinates
  // are rows on q itself: auto keeps joint coordinates with 4 on 8 coordinates; drives go
  // through their absolute equations: 4 on 8 still joint, a fifth tips it over
  for (int drives : {0, 4, 5}) {
    Mechanism arm;
    models::pendulumChain(arm, 8);
    for (int k = 0; k < 8; ++k) arm.setJointLimits(k, 0, -1.0, 1.0);
    for (int k = 0; k < 4; ++k) arm.addCoupler("mimic" + std::to_string(k), 2 * k + 1, 0, 2 * k, 0, 1.0, 0.0);
    for (int k = 0; k < drives; ++k) arm.addDrive(k, 0, DriveProfile::velocity(0.0));
    arm.setIntegrator(formulation("auto"));
    arm.build();
    EXPECT_STREQ(arm.formulation(), drives <= 4 ? "joint" : "absolute") << drives << ": " << arm.formulationReason();
  }

  // a loop: joint coordinates too (its closure on the tree), saying so
  Mechanism loop;
  models::fourBarChain(loop, 1);
  loop.setIntegrator(formulation("auto"));
  loop.build();
  EXPECT_STREQ(loop.formulation(), "joint");
  EXPECT_NE(loop.formulationReason().find("closes a loop"), std::string::npos) << loop.formulationReason();

  // asked for, the joint formulation runs the loop (its closure on the tree)
  Mechanism joint_loop;
  models::fourBarChain(joint_loop, 1);
  joint_loop.setIntegrator(formulation("joint"));
  joint_loop.build();
  EXPECT_STREQ(joint_loop.formulation(), "joint");

  // friction on a joint-formulation mechanism, set while running: an effort along the
  // joint coordinates like damping; "joint" and "auto" keep joint coordinates and go on
  // (joint_space/test_joint_stepper_friction.cpp: the model against known answers and the absolute formulation)
  for (const char* asked : {"joint", "auto"}) {
    Mechanism a;
    models::pendulumChain(a, 2);
    a.setJointDamping(1, 0, 0.01);
    a.setIntegrator(formulation(asked));
    a.build();
    a.assemble();
    for (int k = 0; k < 10; ++k) a.step(1e-3);
    a.setJointFriction(0, 0, 0.1);
    EXPECT_STREQ(a.formulation(), "joint") << asked << ": " << a.formulationReason();
    for (int k = 0; k < 10; ++k) a.step(1e-3);
    EXPECT_LT(a.positionViolation(), 1e-12);
    EXPECT_NEAR(std::fabs(a.state().friction[0][0]), 0.1, 1e-15) << "sliding: friction at its limit";
  }
  // drives added while running: equations on the joint coordinates, followed. auto turns
  // to absolute coordinates (a drive is a closure on the tree through its absolute
  // equation, cheaper there when there are more than one per 2 coordinates: here 2 on 2);
  // joint keeps them.
  for (auto [asked, runs] : {std::make_pair("auto", "absolute"), std::make_pair("joint", "joint")}) {
    Mechanism d;
    models::pendulumChain(d, 2);
    d.setIntegrator(formulation(asked));
    d.build();
    d.assemble();
    for (int k = 0; k < 10; ++k) d.step(1e-3);
    const int drive = d.addDrive(0, 0, DriveProfile::velocity(0.0));
    EXPECT_STREQ(d.formulation(), "joint") << asked << ": one drive on 2 coordinates: " << d.formulationReason();
    d.addDrive(1, 0, DriveProfile::velocity(0.0));
    EXPECT_STREQ(d.formulation(), runs) << asked << ": " << d.formulationReason();
    if (std::string(asked) == "auto")
      EXPECT_NE(d.formulationReason().find("drive"), std::string::npos) << d.formulationReason();
    const double q0 = d.jointPosition(0, 0);
    d.commandDriveVelocity(drive, 0.5, INFINITY);
    for (int k = 0; k < 100; ++k) d.step(1e-3);
    EXPECT_NEAR(d.jointPosition(0, 0), q0 + 0.05, 1e-9) << asked;
  }
}

// What run loops check at every step (Mechanism::stepPositionViolation): in joint
// coordinates the closures' rows, whose values the step computed; the tree joints' hold by
// construction. A four-bar projected only beyond a loose tolerance (1e-3 relative), at
// steps of 20 ms in joint coordinates (1 ms in absolute ones, which diverge at 20), leaves
// its loop open after each step by what the step drifted (measured: up to 4.2e-14 m joint,
// 5.4e-13 m absolute, against round-off of 1e-16 on the tree): the step's figures are the
// whole evaluation's, the largest violation being the loop's. On a chain without closures
// they are 0 in joint coordinates, where the whole evaluation finds round-off; in absolute
// coordinates they are the whole evaluation's.
TEST(JointFormulation, StepViolationIsThatOfTheClosures) {
  for (const char* f : {"joint", "absolute"}) {
    SCOPED_TRACE(f);
    Mechanism loop, chain;
    models::fourBarChain(loop, 1);
    IntegratorOptions io = formulation(f);
    io.position_tol = io.velocity_tol = 1e-3;
    const double h = std::string(f) == "joint" ? 2e-2 : 1e-3;
    loop.setIntegrator(io);
    loop.build();
    loop.assemble();
    models::pendulumChain(chain, 5, 0.5, 1.0, 0.4);
    chain.setIntegrator(formulation(f));
    chain.build();
    chain.assemble();
    ASSERT_STREQ(loop.formulation(), f);
    ASSERT_STREQ(chain.formulation(), f);
    double open = 0.0;
    for (int k = 0; k < 200; ++k) {
      loop.step(h), chain.step(1e-3);
      const double p = loop.positionViolation(), v = loop.velocityViolation();
      open = std::max(open, p);
      EXPECT_NEAR(loop.stepPositionViolation(), p, 1e-6 * p + 1e-15) << "t = " << loop.time();
      EXPECT_NEAR(loop.stepVelocityViolation(), v, 1e-6 * v + 1e-14) << "t = " << loop.time();
      if (std::string(f) == "joint") {
        EXPECT_EQ(chain.stepPositionViolation(), 0.0);
        EXPECT_EQ(chain.stepVelocityViolation(), 0.0);
        EXPECT_LT(chain.positionViolation(), 1e-15);
        EXPECT_LT(chain.velocityViolation(), 1e-14);
      } else {
        EXPECT_EQ(chain.stepPositionViolation(), chain.positionViolation());
        EXPECT_EQ(chain.stepVelocityViolation(), chain.velocityViolation());
      }
    }
    EXPECT_GT(open, 2e-14);  // (the loop was open: the test compared violations, not round-off)
    std::printf("[%s] the four-bar's largest violation after a step, tolerance 1e-3: %.2e m\n", f, open);
  }
}

}  // namespace
}  // namespace mechanism_sim
