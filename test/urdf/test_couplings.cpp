// <mechanism_sim:coupling> through URDF (couplings.h, doc/model_format.md): the examples'
// known answers in both formulations. Planetary train (urdf/planetary_gear.urdf), ring
// held, sun driven at 10 rad/s: the carrier at Z_s / (Z_s + Z_r) of it, 2.5 rad/s, each
// planet at -Z_s / Z_p (w_s - w_c) = -7.5 rad/s on the carrier. Open differential
// (urdf/differential.urdf): the carrier at 1/4 of the pinion's 40 rad/s; the wheels, under
// damping 1 and 3 N m s/rad, settle where their torques are equal (an open differential),
// 15 and 5 rad/s, the spider coupling carrying lambda = -15 N m; the pinion's drive puts in
// the 300 W the wheels' damping takes out. Rack and pinion: q_rack = 0.01 q_column
// throughout. A redundant mesh is a dependent equation and changes no motion. Two
// coordinates of one cylindrical joint, translation = alpha rotation, fall as a screw.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;

std::unique_ptr<MechanismModel> loadIn(const std::string& rel, const char* formulation) {
  LoadOptions o;
  o.formulation = formulation;
  return loadModelFile(kSource + "/" + rel, o);
}

int coupling(const MechanismModel& m, const std::string& name) {
  for (size_t c = 0; c < m.couplings().size(); ++c)
    if (m.couplings()[c].name == name) return static_cast<int>(c);
  ADD_FAILURE() << "no coupling '" << name << "'";
  return 0;
}

TEST(Couplings, PlanetaryTrainTurnsTheCarrierByWillis) {
  const double Zs = 24, Zr = 72, Zp = 24, w_s = 10;
  const double w_c = w_s * Zs / (Zs + Zr), w_p = -Zs / Zp * (w_s - w_c);
  double carrier[2];
  int n = 0;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    auto m = loadIn("urdf/planetary_gear.urdf", f);
    ASSERT_EQ(m->couplings().size(), 4u);
    const int sun = m->dofIndex("sun_joint"), ring = m->dofIndex("ring_joint"), c = m->dofIndex("carrier_joint");
    double worst = 0;
    for (int s = 0; s < 1000; ++s) {
      m->step(1e-3);
      worst = std::max(worst, std::fabs(m->velocity(c) - w_c));
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::fabs(m->velocity(m->dofIndex("planet" + std::to_string(k) + "_joint")) - w_p));
    }
    EXPECT_NEAR(m->velocity(sun), w_s, 1e-12 * w_s);
    EXPECT_NEAR(m->velocity(ring), 0.0, 1e-12 * w_s);
    EXPECT_LT(worst, 1e-11 * w_s) << "carrier and planets at Willis' speeds throughout";
    EXPECT_NEAR(m->position(c), w_c * m->time(), 1e-11 * w_s);
    carrier[n++] = m->position(c);
    std::printf("[planetary, %s] carrier %.15f rad/s (Willis %.15f), planets %.15f rad/s\n", f, m->velocity(c), w_c,
                m->velocity(m->dofIndex("planet0_joint")));
  }
  EXPECT_NEAR(carrier[0], carrier[1], 1e-12 * w_s);
}

TEST(Couplings, OpenDifferentialSplitsTheCarrierTurnAtEqualTorques) {
  const double w_p = 40, w_c = w_p / 4, b_l = 1, b_r = 3;
  const double w_l = 2 * w_c * b_r / (b_l + b_r), w_r = 2 * w_c - w_l, torque = b_l * w_l;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    auto m = loadIn("urdf/differential.urdf", f);
    const int pinion = m->dofIndex("pinion_joint"), carrier = m->dofIndex("carrier_joint");
    const int left = m->dofIndex("left_axle"), right = m->dofIndex("right_axle");
    double worst_tie = 0;
    for (int s = 0; s < 3000; ++s) {
      m->step(1e-3);
      worst_tie = std::max(worst_tie, std::fabs(m->position(left) + m->position(right) - 2 * m->position(carrier)));
    }
    EXPECT_NEAR(m->velocity(carrier), w_c, 1e-12 * w_c);
    EXPECT_NEAR(m->position(carrier), m->position(pinion) / 4, 1e-12 * m->position(pinion));
    EXPECT_LT(worst_tie, 1e-11 * m->position(carrier));
    EXPECT_NEAR(m->velocity(left), w_l, 1e-6 * w_l) << "settled (time constant about 0.2 s)";
    EXPECT_NEAR(m->velocity(right), w_r, 1e-6 * w_l);
    const std::vector<double> lambda = m->couplingReactions();
    EXPECT_NEAR(lambda[coupling(*m, "spider_gears")], -torque, 1e-6 * torque) << "each wheel takes -lambda";
    // power in (the pinion's drive) = power out (the wheels' damping)
    const double in = m->effort(pinion) * m->velocity(pinion);
    const double out = b_l * m->velocity(left) * m->velocity(left) + b_r * m->velocity(right) * m->velocity(right);
    EXPECT_NEAR(in, out, 1e-6 * out);
    std::printf("[differential, %s] wheels %.9f and %.9f rad/s (15, 5), spider lambda %.9f N m, power in %.6f W, out %.6f W\n",
                f, m->velocity(left), m->velocity(right), lambda[coupling(*m, "spider_gears")], in, out);
  }
}

TEST(Couplings, RackFollowsThePinion) {
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    auto m = loadIn("urdf/rack_and_pinion_steering.urdf", f);
    const int rack = m->dofIndex("rack_joint"), column = m->dofIndex("column_joint");
    const int knuckle = m->dofIndex("left_kingpin");
    double worst = 0, steer = 0;
    for (int s = 0; s < 2000; ++s) {  // (straight ahead to full lock left)
      m->step(1e-3);
      worst = std::max(worst, std::fabs(m->position(rack) - 0.01 * m->position(column)));
      steer = std::max(steer, std::fabs(m->position(knuckle)));
    }
    EXPECT_LT(worst, 1e-12);
    EXPECT_GT(steer, 0.25) << "the wheels steer";
  }
}

// A redundant coupling (planet 0's mesh with the ring, which Willis' equation and its mesh
// with the sun imply) is reported among the dependent equations and changes no motion; the
// load the dependent meshes share is then not unique (each formulation reports least-norm
// multipliers), but the drives' efforts are.
TEST(Couplings, ARedundantCouplingIsDependentAndChangesNothing) {
  std::ifstream in(kSource + "/urdf/planetary_gear.urdf");
  std::stringstream text;
  text << in.rdbuf();
  std::string xml = text.str();
  const std::string drives = "  <mechanism_sim:drive joint=\"ring_joint\"";
  xml.replace(xml.find(drives), 0, R"(  <mechanism_sim:coupling name="ring_planet0">
    <joint name="ring_joint" coefficient="72"/><joint name="carrier_joint" coefficient="-72"/>
    <joint name="planet0_joint" coefficient="-24"/>
  </mechanism_sim:coupling>
)");
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    LoadOptions o;
    o.formulation = f;
    auto m = loadModelString(xml, "planetary_redundant.urdf", o);
    const DependencyReport& dep = m->mechanism().dependencies();
    EXPECT_EQ(dep.dependent, 1);
    ASSERT_EQ(dep.by_constraint.size(), 1u);
    EXPECT_EQ(dep.by_constraint[0].first, "ring_planet0");
    for (int s = 0; s < 500; ++s) m->step(1e-3);
    EXPECT_NEAR(m->velocity(m->dofIndex("carrier_joint")), 2.5, 1e-12);
    EXPECT_NEAR(m->velocity(m->dofIndex("planet0_joint")), -7.5, 1e-11);
    EXPECT_NEAR(m->effort(m->dofIndex("sun_joint")), 0.05 * 2.5 * 24 / 96, 1e-12);
    EXPECT_NEAR(m->effort(m->dofIndex("ring_joint")), 0.05 * 2.5 * 72 / 96, 1e-12);
  }
}

// Two coordinates of one joint (dof=): a cylindrical joint whose translation is tied to its
// rotation, t - alpha phi = 0, is a screw of lead 2 pi alpha. A 2 kg nut (I = 0.01 about the
// axis) on a vertical one falls as one coordinate: phi'' = -m g alpha / (I + m alpha^2),
// exactly (RK4 on a constant acceleration), the translation carrying -lambda = m (g + t'').
// A multi-dof joint without dof= is refused, naming its dofs.
TEST(Couplings, TwoCoordinatesOfOneJointMakeAScrew) {
  const double m = 2.0, I = 0.01, alpha = 0.004, g = 9.81;
  auto xml = [](const std::string& first_dof) {
    return std::string(R"(<robot name="nut" xmlns:mechanism_sim="https://mechanism-sim.github.io/urdf-extension">
  <link name="base"/>
  <link name="nut"><inertial><mass value="2"/><inertia ixx="0.008" iyy="0.008" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="thread" type="continuous"><parent link="base"/><child link="nut"/><origin xyz="0 0 1"/><axis xyz="0 0 1"/></joint>
  <mechanism_sim:joint name="thread" type="cylindrical"/>
  <mechanism_sim:coupling name="lead">
    <joint name="thread" )") + first_dof + R"( coefficient="1"/>
    <joint name="thread" dof="rotation" coefficient="-0.004"/>
  </mechanism_sim:coupling>
</robot>)";
  };
  const double acc = -m * g * alpha / (I + m * alpha * alpha);
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    LoadOptions o;
    o.formulation = f;
    auto model = loadModelString(xml("dof=\"translation\""), "nut.urdf", o);
    const int rot = model->dofIndex("thread.rotation"), tr = model->dofIndex("thread.translation");
    for (int s = 0; s < 1000; ++s) model->step(1e-3);
    const double t = model->time();
    EXPECT_NEAR(model->velocity(rot), acc * t, 1e-10 * std::fabs(acc * t));
    EXPECT_NEAR(model->position(rot), 0.5 * acc * t * t, 1e-10 * std::fabs(acc * t * t));
    EXPECT_NEAR(model->position(tr), alpha * model->position(rot), 1e-11 * std::fabs(model->position(tr)));
    EXPECT_NEAR(-model->couplingReactions()[0], m * (g + alpha * acc), 1e-9 * m * g);
  }
  try {
    loadModelString(xml(""), "nut.urdf");
    ADD_FAILURE() << "a multi-dof joint without dof= was accepted";
  } catch (const LoadError& e) {
    EXPECT_NE(std::string(e.what()).find("nut.urdf:7: joint 'thread': 2 degrees of freedom (rotation, translation)"),
              std::string::npos) << e.what();
  }
}

// Backlash (urdf/gear_pair_backlash.urdf): the pinion driven q_p = 0.5 sin(pi t) from the
// centre of a clearance |20 q_p + 40 q_w| <= 0.2 turns alone, the wheel exactly at rest and
// the mesh's reaction 0, until 20 q_p = 0.2 (t* = asin(0.02) / pi); from the step that
// reaches the stop the wheel follows at -20/40 of the pinion's speed, the stop holding the
// sum at 0.2, and the mesh carries what the damped wheel needs: on the wheel
// -40 lambda = I_w w_dot + c w. Both formulations, which agree.
TEST(Couplings, GearPairWithBacklashTakesUpTheClearanceFirst) {
  const double A = 0.5, w = M_PI, c = 0.02, I_w = 0.00032, h = 1e-3;
  const double t_contact = std::asin(0.2 / 20 / A) / w;
  double end[2];
  int n = 0;
  for (const char* f : {"absolute", "joint"}) {
    SCOPED_TRACE(f);
    auto m = loadIn("urdf/gear_pair_backlash.urdf", f);
    const int p = m->dofIndex("pinion_joint"), wh = m->dofIndex("wheel_joint");
    const int mesh = coupling(*m, "mesh");
    int engaged = 0;
    for (int s = 0; s < 400; ++s) {
      m->step(h);
      const double t = m->mechanism().time();
      if (t < t_contact) {
        EXPECT_NEAR(m->position(wh), 0.0, 1e-15) << "t = " << t;
        EXPECT_NEAR(m->velocity(wh), 0.0, 1e-15) << "t = " << t;
        EXPECT_EQ(m->couplingReactions()[mesh], 0.0) << "t = " << t;
      } else if (t > t_contact + h) {
        ++engaged;
        const double qd = A * w * std::cos(w * t), qdd = -A * w * w * std::sin(w * t);
        EXPECT_NEAR(m->velocity(p), qd, 1e-12);
        EXPECT_NEAR(20 * m->position(p) + 40 * m->position(wh), 0.2, 1e-12) << "t = " << t;
        EXPECT_NEAR(m->velocity(wh), -0.5 * qd, 1e-12) << "t = " << t;
        const double lambda = -(I_w * (-0.5 * qdd) + c * (-0.5 * qd)) / 40;
        EXPECT_NEAR(m->couplingReactions()[mesh], lambda, 1e-9 * std::fabs(lambda)) << "t = " << t;
      }
    }
    EXPECT_GT(engaged, 300);
    for (int s = 0; s < 1600; ++s) m->step(h);  // through the reversals
    end[n++] = m->position(wh);
    std::printf("[backlash, %s] the wheel at rest until %.6f s; at 2 s q_wheel = %.12f, q_pinion = %.12f\n", f,
                t_contact, m->position(wh), m->position(p));
  }
  EXPECT_NEAR(end[0], end[1], 1e-6);
}

}  // namespace
}  // namespace mechanism_sim
