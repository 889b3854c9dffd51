// checkMassRank (assembly/mass_check.cpp): M + Phi_q^T W Phi_q is singular exactly when a
// motion the joints allow moves no mass. Oracle: the motions are known by construction: a
// point mass on a ball joint turns freely about its centre (no inertia), a massless link
// between two ball joints spins about its axis; with inertia, or with a revolute joint that
// fixes the turn away from the centre, every motion moves mass; a hinge whose axis passes
// through the point mass turns it in place.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "bodies.h"
#include "core/absolute/stepper.h"
#include "core/assembly/mass_check.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

using test_util::frame;

// A link hung from the ground by `type` at the origin, its centre 0.5 m below, of mass m
// and principal moments J (all equal). The joint's z axis is global x (a hinge's turn
// swings the centre) or, with `axis_through_centre`, global z.
std::string check(const char* type, double m, double J, bool axis_through_centre = false) {
  const Matrix3d R = axis_through_centre ? Matrix3d::Identity()
                                         : Matrix3d(Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitY()));
  Mechanism mech;
  mech.addBody(test_util::body("link", m, Vector3d::Constant(J), Vector3d(0, 0, -0.5)));
  mech.addJoint(makeJoint(type, "hinge", 0, frame(Vector3d::Zero(), R), 1, frame(Vector3d(0, 0, 0.5), R)));
  mech.build();
  const System& sys = mech.system();
  State s = mech.state();
  Stepper st(sys);
  st.load(sys, s.x.data(), s.u.data());
  st.evaluate(sys, s);
  try {
    checkMassRank(sys, st.evaluation(), st.solver().penalty());
  } catch (const ModelError& e) {
    return e.what();
  }
  return "";
}

TEST(MassCheck, APointMassOnABallJointIsRefusedNamingItsBody) {
  const std::string what = check("spherical", 1.0, 0.0);
  EXPECT_NE(what.find("bodies that can move without moving any mass: 'link'"), std::string::npos) << what;
}

TEST(MassCheck, APointMassOnAHingeMovesMassInItsOnlyMotion) {
  EXPECT_EQ(check("revolute", 1.0, 0.0), "");  // (the turn about the hinge moves the mass 0.5 m out)
}

TEST(MassCheck, APointMassOnAHingeWhoseAxisPassesThroughItIsRefused) {
  const std::string what = check("revolute", 1.0, 0.0, true);
  EXPECT_NE(what.find("without moving any mass: 'link'"), std::string::npos) << what;
}

TEST(MassCheck, ABodyWithInertiaOnABallJointIsAccepted) { EXPECT_EQ(check("spherical", 1.0, 0.01), ""); }

}  // namespace
}  // namespace mechanism_sim
