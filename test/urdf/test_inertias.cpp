// Inertias as real files have them (doc/robots.md, "Inertias that are not physical"): a
// body whose merged inertia is not physical runs with the nearest physical one and one note
// giving the change; strict_inertia refuses it as before. Fixtures in test/urdf/, shaped
// like a mobile manipulator's finger (iyy = izz = 0) and a quadruped's hip (products of
// inertia past the triangle inequality).
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;

std::vector<std::string> notesWith(const MechanismModel& m, const std::string& part) {
  std::vector<std::string> out;
  for (const std::string& n : m.notes())
    if (n.find(part) != std::string::npos) out.push_back(n);
  return out;
}

std::string loadError(const std::string& path, const LoadOptions& o) {
  try {
    loadModelFile(path, o);
  } catch (const LoadError& e) {
    return e.what();
  }
  return "(loaded)";
}

Eigen::Vector3d moments(const Eigen::Matrix3d& J) { return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(J).eigenvalues(); }

// The finger's moments (0, 0, 3e-5) become (1e-5, 1e-5, 2e-5) (the projection onto the
// face l_3 = l_1 + l_2), one note for the finger and none for the other, and it runs.
TEST(Inertias, AFingerWithTwoZeroMomentsRunsWithTheNearestPhysicalInertia) {
  auto m = loadModelFile(kSource + "/test/urdf/finger_zero_moments.urdf");
  const std::vector<std::string> notes = notesWith(*m, "the nearest physical inertia");
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0],
            "body 'left_finger': its inertia violates the triangle inequality (a principal moment exceeds the sum of "
            "the other two); principal moments (0, 0, 3e-05) -> (1e-05, 1e-05, 2e-05) kg m^2, the nearest physical "
            "inertia (fix the <inertia> of link 'left_finger'; strict_inertia refuses)");
  const Mechanism& mech = m->mechanism();
  const Eigen::Matrix3d& J = mech.body(m->links()[m->linkIndex("left_finger")].body).Jp;
  EXPECT_NEAR(J(0, 0), 2e-5, 1e-18);
  EXPECT_NEAR(J(1, 1), 1e-5, 1e-18);
  EXPECT_NEAR(J(2, 2), 1e-5, 1e-18);
  m->setEffort(m->dofIndex("left_finger_joint"), 1.0);
  for (int i = 0; i < 100; ++i) m->step(1e-3);
  EXPECT_GT(m->position(m->dofIndex("left_finger_joint")), 0.0);
  EXPECT_LT(m->relativePositionViolation(), 1e-10);
}

// The hip's products give moments (7.4e-4, 7.4e-4, 1.52e-3): the largest exceeds the sum
// by 4e-5, which the projection spreads over the three (4e-5 / 3 each), the principal axes
// kept.
TEST(Inertias, AHipWithProductsPastTheTriangleInequalityRuns) {
  LoadOptions o;
  o.velocities = {{"hip_abduction", 2.0}};
  auto m = loadModelFile(kSource + "/test/urdf/hip_products.urdf", o);
  ASSERT_EQ(notesWith(*m, "the nearest physical inertia").size(), 1u);
  EXPECT_EQ(notesWith(*m, "body 'hip'").size(), 1u);
  const Eigen::Matrix3d& J = m->mechanism().body(m->links()[m->linkIndex("hip")].body).Jp;
  const Eigen::Vector3d l = moments(J);
  const double d = 4e-5 / 3;
  EXPECT_NEAR(l(0), 7.4e-4 + d, 1e-17);
  EXPECT_NEAR(l(1), 7.4e-4 + d, 1e-17);
  EXPECT_NEAR(l(2), 1.52e-3 - d, 1e-17);
  // the axis of the largest moment stays (1, 1, 1) / sqrt(3)
  Eigen::Vector3d axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(J).eigenvectors().col(2);
  EXPECT_NEAR(std::abs(axis.dot(Eigen::Vector3d::Ones().normalized())), 1.0, 1e-12);
  // it swings with the inertia it has: no damping, so the energy stays
  const double E0 = m->kineticEnergy() + m->potentialEnergy();
  for (int i = 0; i < 200; ++i) m->step(1e-3);
  EXPECT_LT(m->relativePositionViolation(), 1e-10);
  EXPECT_GT(std::abs(m->position(m->dofIndex("hip_abduction"))), 0.1);
  EXPECT_NEAR(m->kineticEnergy() + m->potentialEnergy(), E0, 1e-8 * m->kineticEnergy());
}

// strict_inertia (simulate --strict-inertia, the node's ~strict_inertia, the Python load
// keyword) refuses with the message of a loader that refuses every non-physical inertia.
TEST(Inertias, StrictInertiaRefusesAsBefore) {
  LoadOptions strict;
  strict.strict_inertia = true;
  const std::string triangle = kSource + "/test/urdf/inertia_triangle.urdf";
  EXPECT_EQ(loadError(triangle, strict),
            triangle + ":3: inertia: the rigid body of link 'arm' (with the links fixed to it): inertia violates the "
                       "triangle inequality (a principal moment exceeds the sum of the other two); fix the <inertia> "
                       "of link 'arm'");
  const std::string negative = kSource + "/test/urdf/negative_inertia.urdf";
  EXPECT_EQ(loadError(negative, strict),
            negative + ":3: inertia: the rigid body of link 'arm' (with the links fixed to it): inertia has a "
                       "negative principal moment; fix the <inertia> of link 'arm'");
  for (const std::string& f : {"finger_zero_moments.urdf", "hip_products.urdf"})
    EXPECT_NE(loadError(kSource + "/test/urdf/" + f, strict).find("violates the triangle inequality"), std::string::npos) << f;
  // without it, both run with a note
  for (const std::string& f : {triangle, negative}) {
    auto m = loadModelFile(f);
    EXPECT_EQ(notesWith(*m, "body 'arm': its inertia").size(), 1u) << f;
  }
}

// A pendulum whose bob is a point mass at distance L from its joint, written as two links
// fixed together whose merged inertia is round-off (the parallel-axis sum of a humanoid's
// point masses leaves -5e-20 kg m^2 on a 0.5 kg link 3 cm from its joint): its moments are
// judged against m L^2, the inertia it swings with, so at every unit scale it runs without
// a note, with the file's inertia. A moment negative by 1e-6 of m L^2 is still a fault,
// projected with its note.
std::string pointMassPendulum(double L, double m, double moment) {
  std::ostringstream os;
  os.precision(17);
  os << "<robot name='bob'><link name='base'/>"
     << "<link name='arm'><inertial><origin xyz='" << L << " 0 0'/><mass value='" << m << "'/>"
     << "<inertia ixx='" << moment << "' iyy='" << 0.5 * moment << "' izz='" << moment
     << "' ixy='0' ixz='0' iyz='0'/></inertial></link>"
     << "<joint name='pivot' type='continuous'><parent link='base'/><child link='arm'/><axis xyz='0 1 0'/></joint>"
     << "</robot>";
  return os.str();
}

TEST(Inertias, APointMassAwayFromItsJointTakesRoundOffOfItsOwnScaleAtEveryUnitScale) {
  for (double L : {1e-3, 1e-1, 1.0, 1e1, 1e3})
    for (double m : {1e-3, 1.0, 1e3}) {
      const std::string at = "L = " + std::to_string(L) + ", m = " + std::to_string(m);
      auto model = loadModelString(pointMassPendulum(L, m, -4e-17 * m * L * L), "bob.urdf");
      EXPECT_TRUE(notesWith(*model, "inertia").empty()) << at;
      const Eigen::Matrix3d& J = model->mechanism().body(model->links()[model->linkIndex("arm")].body).Jp;
      EXPECT_EQ(J(0, 0), -4e-17 * m * L * L) << at;  // the file's, not projected
      const double E0 = model->kineticEnergy() + model->potentialEnergy();
      const double h = 2e-3 * std::sqrt(L);
      for (int k = 0; k < 250; ++k) model->step(h);
      // from the horizontal at rest, a quarter swing and more: m L^2 q'' = m g L cos q
      EXPECT_GT(model->position(model->dofIndex("pivot")), 1.0) << at;
      EXPECT_NEAR(model->kineticEnergy() + model->potentialEnergy(), E0, 1e-9 * m * 9.81 * L) << at;

      auto bad = loadModelString(pointMassPendulum(L, m, -1e-6 * m * L * L), "bob.urdf");
      EXPECT_EQ(notesWith(*bad, "body 'arm': its inertia has a negative principal moment").size(), 1u) << at;
    }
}

// A body of mass 0 and inertia 0 is a massless body (no note about its inertia); a massless
// link among massive ones still meets the mass-rank check (test/invalid/massless_body_unmoved.urdf).
TEST(Inertias, ZeroMassAndZeroInertiaIsNoWarning) {
  auto m = loadModelFile(kSource + "/test/urdf/kinematic_arm.urdf");
  EXPECT_TRUE(notesWith(*m, "inertia").empty());
}

}  // namespace
}  // namespace mechanism_sim
