// The saturating mode (Mechanism::setActuatorLimits, doc/actuators.md): a drum of inertia I
// behind a gear N, a load torque tau_L on it, its drive bounded by a DC motor's line
// (stall T_s, no-load speed w0) or a peak torque. Known answers:
//   - a drive asking for more speed than the motor has settles where the line meets the
//     load, T_s (1 - N q_dot / w0) = tau_L / N, in both formulations, the line never exceeded;
//   - while the motor is at its bound the drum accelerates as (N tau_m - tau_L) / I;
//   - a drive that asks too much only for a while falls behind, comes back and follows its
//     profile exactly again; a drive within the envelope moves bit for bit as in the sizing
//     mode; the motor's work is the change of kinetic energy plus the load's work.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "mechanism_sim/core/models.h"

namespace mechanism_sim {
namespace {

struct Winch {
  double I = 0.02, N = 20.0, tau_L = 4.0;   // kg m^2, -, N m (m g r of a load on the drum)
  double T_s = 0.5, w0 = 400.0;              // the motor's line: N m, rad/s
  Mechanism mech;
  int drive = -1;
  explicit Winch(const std::string& formulation, double v_drive, double peak = 0.0, bool limits = true) {
    Body b;
    b.name = "drum";
    b.m = 1.0;
    b.Jp = Vector3d(0.01, I, 0.01).asDiagonal();
    const int body = mech.addBody(b);
    mech.addJoint(makeJoint("revolute", "drum_joint", Mechanism::kGround, models::axisY(Vector3d::Zero()), body,
                            models::axisY(Vector3d::Zero())));
    drive = mech.addDrive(0, 0, DriveProfile::velocity(v_drive));
    IntegratorOptions o;
    o.formulation = formulation;
    mech.setIntegrator(o);
    // (gravity acts on the drum's centre, on its axis: no torque)
    mech.build();
    mech.assemble();
    // the load: a torque about the drum's axis (body y is global y) against positive turning
    mech.setBodyWrench(body, Vector3d::Zero(), Vector3d(0, -tau_L, 0));
    if (limits) {
      ActuatorLimit L;
      L.name = "motor";
      L.reduction = N;
      L.ratings.stall_torque = T_s, L.ratings.no_load_speed = w0, L.ratings.peak_torque = peak;
      mech.setActuatorLimits({L});
    }
  }
  double omega() const { return N * mech.jointVelocity(0, 0); }
  double torque() const { return (-mech.state().lambda[mech.system().layout[mech.system().drives[drive].constraint].row]) / N; }
  // where the line meets the load
  double settled() const { return w0 * (1.0 - tau_L / (N * T_s)); }
};

TEST(Saturation, WinchSettlesWhereTheLineMeetsTheLoadInBothFormulations) {
  const double h = 1e-3;
  double v[2];
  int f = 0;
  for (const char* formulation : {"absolute", "joint"}) {
    Winch w(formulation, 30.0);  // asks 600 rad/s at the motor, past its 400 no-load
    EXPECT_STREQ(w.mech.formulation(), formulation);
    double worst = 0.0;
    bool saturated_seen = false;
    for (int k = 0; k < 3000; ++k) {
      w.mech.step(h);
      const TorqueBounds b = torqueBounds(ActuatorRatings{0, 0, 0, w.T_s, w.w0}, w.omega());
      worst = std::max(worst, (w.torque() - b.hi) / w.T_s);
      saturated_seen = saturated_seen || w.mech.driveSaturated(w.drive);
      // at the bound the drum accelerates as the bound torque makes it
      if (k > 0 && w.mech.driveSaturated(w.drive))
        EXPECT_NEAR(w.mech.jointAcceleration(0, 0), (w.N * w.torque() - w.tau_L) / w.I, 1e-8 * w.tau_L / w.I) << k;
    }
    EXPECT_TRUE(saturated_seen);
    EXPECT_LT(worst, 1e-10);  // never above the line (to the solves' round-off)
    EXPECT_TRUE(w.mech.driveSaturated(w.drive));
    EXPECT_NEAR(w.omega(), w.settled(), 1e-9 * w.w0) << formulation;
    EXPECT_NEAR(w.torque(), w.tau_L / w.N, 1e-9 * w.T_s) << formulation;
    // the lag: what the profile asks minus where the drum is
    double q, q_dot, q_ddot;
    w.mech.driveTarget(w.drive, &q, &q_dot, &q_ddot);
    EXPECT_NEAR(w.mech.driveLag(w.drive), q - w.mech.jointPosition(0, 0), 1e-9);
    EXPECT_GT(w.mech.driveLag(w.drive), 1.0);
    v[f++] = w.mech.jointVelocity(0, 0);
  }
  EXPECT_NEAR(v[0], v[1], 1e-9 * v[0]);
}

TEST(Saturation, SettledSpeedDoesNotDependOnTheStep) {
  for (double h : {4e-3, 1e-3, 2.5e-4}) {
    Winch w("absolute", 30.0);
    for (int k = 0; k < static_cast<int>(std::lround(3.0 / h)); ++k) w.mech.step(h);
    EXPECT_NEAR(w.omega(), w.settled(), 1e-9 * w.w0) << h;
  }
}

TEST(Saturation, SizingModeFollowsTheDriveWhateverTheTorque) {
  Winch w("absolute", 30.0, 0.0, false);
  for (int k = 0; k < 500; ++k) w.mech.step(1e-3);
  EXPECT_NEAR(w.mech.jointVelocity(0, 0), 30.0, 1e-12);
  EXPECT_EQ(w.mech.driveLag(w.drive), 0.0);
  // 600 rad/s is past the no-load speed: the line allows no motoring torque there
  EXPECT_GT(w.torque(), torqueBounds(ActuatorRatings{0, 0, 0, w.T_s, w.w0}, w.omega()).hi);
}

// Within the envelope the saturating mode changes nothing: bit for bit.
TEST(Saturation, ADriveWithinTheEnvelopeMovesBitForBitAsInSizing) {
  for (const char* formulation : {"absolute", "joint"}) {
    Winch sized(formulation, 5.0, 0.0, false), bounded(formulation, 5.0);  // 100 rad/s at the motor
    for (int k = 0; k < 400; ++k) {
      sized.mech.step(1e-3), bounded.mech.step(1e-3);
      ASSERT_EQ(sized.mech.state().x, bounded.mech.state().x) << k;
      ASSERT_EQ(sized.mech.state().u, bounded.mech.state().u) << k;
      ASSERT_EQ(sized.mech.state().lambda, bounded.mech.state().lambda) << k;
    }
    EXPECT_FALSE(bounded.mech.driveSaturated(bounded.drive));
    EXPECT_EQ(bounded.mech.driveLag(bounded.drive), 0.0);
  }
}

// A velocity command whose ramp asks more torque than the peak: the drum falls behind while
// accelerating at (N peak - tau_L) / I, then catches up and follows the profile exactly.
TEST(Saturation, ARampAskingTooMuchFallsBehindAndRejoins) {
  double final_q[2];
  int f = 0;
  for (const char* formulation : {"absolute", "joint"}) {
    Winch w(formulation, 0.0, 0.6);
    w.T_s = 0.0;  // (peak torque only)
    ActuatorLimit L;
    L.name = "motor";
    L.reduction = w.N;
    L.ratings.peak_torque = 0.6;
    w.mech.setActuatorLimits({L});
    const double h = 1e-3;
    for (int k = 0; k < 100; ++k) w.mech.step(h);  // holds the load at rest: 0.2 N m
    EXPECT_NEAR(w.torque(), w.tau_L / w.N, 1e-12);
    // 10 rad/s in 0.05 s: 200 rad/s^2 needs (0.02 * 200 + 4) / 20 = 0.4 N m: within; at
    // 1000 rad/s^2 (0.01 s) it needs 1.2 N m, twice the peak
    w.mech.commandDriveVelocity(w.drive, 10.0, 1000.0);
    double lag_max = 0.0, t_max = 0.0, last_saturated = -1.0;
    for (int k = 0; k < 400; ++k) {
      w.mech.step(h);
      EXPECT_LE(std::fabs(w.torque()), 0.6 * (1 + 1e-12)) << k;
      if (w.mech.driveSaturated(w.drive)) {
        last_saturated = w.mech.time();
        EXPECT_NEAR(w.mech.jointAcceleration(0, 0), (w.N * w.torque() - w.tau_L) / w.I, 1e-8 * w.tau_L / w.I) << k;
      }
      if (w.mech.driveLag(w.drive) > lag_max) lag_max = w.mech.driveLag(w.drive), t_max = w.mech.time();
    }
    // at the peak the drum accelerates at (20 * 0.6 - 4) / 0.02 = 400 rad/s^2, reaching 10
    // rad/s 0.025 s after the command, the profile 0.01 s after it: the lag then is the area
    // between the two velocity ramps, 10 (0.025 - 0.01) / 2 = 0.075 rad, its largest
    EXPECT_NEAR(lag_max, 0.075, 1e-4);
    EXPECT_NEAR(t_max, 0.1255, 0.0015);
    EXPECT_GT(last_saturated, 0.1);
    EXPECT_LT(last_saturated, 0.3);
    // back on the profile exactly
    EXPECT_EQ(w.mech.driveLag(w.drive), 0.0);
    EXPECT_FALSE(w.mech.driveSaturated(w.drive));
    double q, q_dot, q_ddot;
    w.mech.driveTarget(w.drive, &q, &q_dot, &q_ddot);
    EXPECT_NEAR(w.mech.jointPosition(0, 0), q, 1e-12 * (1 + std::fabs(q)));
    EXPECT_NEAR(w.mech.jointVelocity(0, 0), 10.0, 1e-11);
    EXPECT_NEAR(w.torque(), w.tau_L / w.N, 1e-9);
    final_q[f++] = w.mech.jointPosition(0, 0);
  }
  EXPECT_NEAR(final_q[0], final_q[1], 1e-9);
}

// A path (a trajectory's drive) that asks too much for a while: from rest to 1 rad in 0.1 s
// (a quintic: up to 577 rad/s^2) and held there, where the peak torque gives the drum
// (20 * 0.6 - 4) / 0.02 = 400 rad/s^2 against its load. The drum falls behind,
// accelerating at the peak's (N peak - tau_L) / I, comes back and holds the path's end
// exactly; the two formulations agree.
TEST(Saturation, APathAskingTooMuchFallsBehindAndEndsWhereItEnds) {
  double q_end[2], lag_max[2];
  int f = 0;
  for (const char* formulation : {"absolute", "joint"}) {
    Winch w(formulation, 0.0);
    ActuatorLimit L;
    L.name = "motor", L.reduction = w.N, L.ratings.peak_torque = 0.6;
    w.mech.setActuatorLimits({L});
    const double h = 1e-3;
    auto path = std::make_shared<const DrivePath>(
        DrivePath::through(PathKnot{0.0, w.mech.jointPosition(0, 0), 0.0, 0.0}, {0.1, 0.3}, {1.0, 1.0}, {0.0, 0.0},
                           {0.0, 0.0}));
    w.mech.commandDrivePath(w.drive, path);
    double worst = 0.0, at_bound = 0.0;
    lag_max[f] = 0.0;
    for (int k = 0; k < 600; ++k) {
      w.mech.step(h);
      worst = std::max(worst, std::fabs(w.torque()) / 0.6 - 1.0);
      lag_max[f] = std::max(lag_max[f], std::fabs(w.mech.driveLag(w.drive)));
      if (w.mech.driveSaturated(w.drive)) {
        at_bound += h;
        EXPECT_NEAR(std::fabs(w.torque()), 0.6, 1e-12) << k;
      }
    }
    EXPECT_LT(worst, 1e-12);
    EXPECT_GT(at_bound, 0.05);
    EXPECT_GT(lag_max[f], 0.05);
    EXPECT_EQ(w.mech.driveLag(w.drive), 0.0);
    EXPECT_NEAR(w.mech.jointPosition(0, 0), 1.0, 1e-12);
    EXPECT_NEAR(w.mech.jointVelocity(0, 0), 0.0, 1e-10);
    q_end[f++] = w.mech.jointPosition(0, 0);
  }
  EXPECT_NEAR(q_end[0], q_end[1], 1e-12);
  EXPECT_NEAR(lag_max[0], lag_max[1], 1e-9);
}

// The motor's work, summed over the run's states by the trapezoidal rule, against the drum's
// kinetic energy gained plus the work done against the load, in the saturating mode. The
// torque at each state is the one from there on (the lag chosen there), so the sum is of
// first order in h: its error halves with the step.
TEST(Saturation, MotorWorkIsTheEnergyGainedPlusTheLoadsWork) {
  double error[3];
  int i = 0;
  for (double h : {1e-3, 5e-4, 2.5e-4}) {
    Winch w("absolute", 30.0);
    const double q0 = w.mech.jointPosition(0, 0), T0 = w.mech.kineticEnergy();
    w.mech.step(h);  // (the load's torque in the multipliers from the first step on)
    double work = 0.0, p_last = w.torque() * w.omega();
    const double q1 = w.mech.jointPosition(0, 0), T1 = w.mech.kineticEnergy();
    for (int k = 0; k < static_cast<int>(std::lround(1.0 / h)); ++k) {
      w.mech.step(h);
      const double p = w.torque() * w.omega();
      work += 0.5 * h * (p + p_last);
      p_last = p;
    }
    const double gained = w.mech.kineticEnergy() - T1 + w.tau_L * (w.mech.jointPosition(0, 0) - q1);
    (void)q0, (void)T0;
    error[i++] = (work - gained) / gained;
  }
  EXPECT_LT(std::fabs(error[2]), 1e-3);
  EXPECT_NEAR(error[0] / error[1], 2.0, 0.2);
  EXPECT_NEAR(error[1] / error[2], 2.0, 0.2);
}

// Lifting the bounds: a drive behind its profile keeps its lag as it stands and moves with its
// profile from there.
TEST(Saturation, LiftedBoundsKeepTheLagAndFollowTheProfilesVelocity) {
  for (const char* formulation : {"absolute", "joint"}) {
    Winch w(formulation, 30.0);
    for (int k = 0; k < 500; ++k) w.mech.step(1e-3);
    const double lag = w.mech.driveLag(w.drive);
    ASSERT_GT(lag, 1.0);
    w.mech.setActuatorLimits({});
    EXPECT_EQ(w.mech.driveLag(w.drive), lag);
    EXPECT_NEAR(w.mech.jointVelocity(0, 0), 30.0, 1e-9) << formulation;
    for (int k = 0; k < 100; ++k) w.mech.step(1e-3);
    double q, q_dot, q_ddot;
    w.mech.driveTarget(w.drive, &q, &q_dot, &q_ddot);
    EXPECT_EQ(w.mech.driveLag(w.drive), lag);
    EXPECT_NEAR(w.mech.jointPosition(0, 0), q - lag, 1e-9 * q) << formulation;
    EXPECT_NEAR(w.mech.jointVelocity(0, 0), 30.0, 1e-9) << formulation;
  }
}

TEST(Saturation, BadLimitsAreRefusedNamingTheActuator) {
  Winch w("absolute", 1.0, 0.0, false);
  ActuatorLimit L;
  L.name = "m1";
  L.reduction = 0.0;
  try {
    w.mech.setActuatorLimits({L});
    FAIL();
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("actuator 'm1'"), std::string::npos);
  }
  L.reduction = 1.0, L.joint = 3;
  EXPECT_THROW(w.mech.setActuatorLimits({L}), UsageError);
  L.joint = 0, L.ratings.stall_torque = 1.0;  // a line needs its no-load speed
  EXPECT_THROW(w.mech.setActuatorLimits({L}), UsageError);
}

}  // namespace
}  // namespace mechanism_sim
