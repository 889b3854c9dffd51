// Every tolerance and iteration cap of the core, each with the reason for its value, in one
// place (as MuJoCo gathers its runtime tolerances in mjOption). The tolerances a user tunes
// per run are options (IntegratorOptions in model/system.h: position_tol, velocity_tol,
// solve_tol, the integrator); what is here are the algorithms' own thresholds. All are
// relative (scale-free): a residual over the size of its terms, a motion over the length
// scale, a pivot over its diagonal, so metres and millimetres run alike.
#pragma once

namespace mechanism_sim {
namespace numerics {

// ---- shared by both formulations

// Velocity projections solved exactly (the joint formulation's closures): passes of the
// least-norm correction Phi_q du = -Phi_q u. One pass is exact for the linear equations up
// to round-off; the further passes take the round-off of a badly scaled Phi_q down to the
// tolerance; 8 is reached only at a singular configuration, where more would not help.
// (The absolute formulation's penalty form has its own cap, kMaxPenaltyVelocityPasses.)
constexpr int kMaxVelocityPasses = 8;

// Residual floors (evaluation.h, relative()): kFloor times the system's largest motion
// (force), so that a mechanism at rest is not judged on round-off divided by round-off.
constexpr double kFloor = 1e-6;

// The stand-in mass (and moments) a body without them gets in the penalty form's
// preconditioner (massFloor), as a share of its stand-in (System::Minv): enough to make H
// definite in the directions only its equations fix, too small to change a motion that
// moves mass.
constexpr double kMassFloor = 1e-6;

// A coordinate within this fraction of its limits' and the model's scale past a bound is
// on it (limitSlack, model/system.h): an assembled or driven position's round-off, far
// below any motion a limit is there to stop.
constexpr double kLimitSlack = 1e-9;

// A step that fails (a projection that cannot bring it back onto the constraints) is
// retaken as two half steps, at most this deep (1/64 of the step), in both formulations:
// past it the step size itself is wrong, and the run stops saying so.
constexpr int kMaxHalvings = 6;
// A step's estimated velocity error (h/6 |k4 - k5| of the bodies' velocities: Stepper::advance,
// JointStepper::advance) past this share of the motion's velocity scale is taken again as
// halves: a leap over an event (a dead point whipped through within the step, the tight
// turn where a near-parallelogram's branches pass close), not a smooth step's error. At
// 1e-2 a crank whipped through its dead point lost 13 % of its energy in 2 s at 1 ms, at
// 1e-3 0.5 %.
constexpr double kMaxStepError = 1e-3;

// ---- the absolute formulation (absolute/)
namespace absolute {

// Above this relative residual the constraints are visibly broken and the step fails
// (StepFailure: retaken in halves, then the run stops); between the tolerance and it a
// projection is counted short and the run goes on.
constexpr double kFailureResidual = 1e-6;
// Newton iterations of a position projection: it converges quadratically from a step's
// drift (a few iterations); 20 leaves room for a start near a singular configuration.
constexpr int kMaxNewton = 20;
// Extra iterations past the tolerance near dependent equations, while each halves the last
// (projection.h): round-off there is worth a few more.
constexpr int kRoundoffSteps = 4;
// Dropped rows whose relative residual passes this many times the position tolerance are no
// longer implied by the rows kept (the stepper analyzes the dependencies again).
constexpr double kDependentDrift = 10.0;
// Radians a body may turn in one step: RK4's phase error at 0.25 rad a step is below 1e-6 rad.
constexpr double kMaxTurn = 0.25;
// The penalty form's dimensionless weight kappa in H = M + kappa Phi_q^T W Phi_q: each
// refinement pass contracts the KKT error by about 1/(kappa sigma), sigma the smallest
// eigenvalue of the row-scaled W^1/2 Phi_q M^-1 Phi_q^T W^1/2 (1 for one joint, about 1/N^2
// along a chain of N bodies), while H's condition number, and the round-off of one solve,
// grows like kappa. 1e7 is where the two balance: a larger kappa drifts by the round-off
// of H, a smaller one takes more passes.
constexpr double kKappa = 1e7;
// Velocity projection passes on the penalty form (projection.cpp): a pass is not exact, it
// contracts the residual by about 1 / (1 + kappa sigma), and sigma is small wherever two rows
// act on nearly the same motion in the metric M^-1: a bob whose rotational inertia Ic is
// tiny beside m L^2 has its pivot's lateral row and its limit's row both mostly on its
// rotation, sigma about Ic / (2 m L^2), whatever the diagonal row weights (van der Sluis:
// the rows' own weights are within a factor of the row count of the best diagonal ones).
// The passes go on while each halves the residual against the starting scales (a pass that
// gains less ends them); this cap only bounds that: from a relative residual of 1 to double
// round-off (2^-52) under the residual floor kFloor (about 2^-20) is 72 halvings.
constexpr int kMaxPenaltyVelocityPasses = 72;
// Refinement passes of a KKT solve on its exact residual (each contracts by 1/(kappa sigma)).
constexpr int kMaxSolvePasses = 12;
// A pass with H factored at a nearby state that gains less than 1/kNearbyGain triggers a
// factorization here (a slow contraction costs more passes than one factorization).
constexpr double kNearbyGain = 0.25;
// Dependency analysis: a row with less than this squared fraction of its norm outside the
// span of the rows before it is dependent (about 3e-5 of its length: far above round-off,
// far below any real joint's independent direction).
constexpr double kDependencyPivot = 1e-9;
// Stiff damping's refinement: at most kStiffPasses passes; a correction below
// kStiffRoundOff of the velocities' scale is round-off, and the refinement stops there.
constexpr int kStiffPasses = 12;
constexpr double kStiffRoundOff = 1e-15;

}  // namespace absolute

// ---- the joint-space formulation (joint_space/)
namespace joint_space {

// A pivot of the Jacobi-scaled closure matrix (unit diagonal) below this sends the solve to
// the rank-revealing dense path (whose threshold, kClosureRankThreshold, is smaller: a
// marginal pivot is decided there, not here).
constexpr double kClosureSparsePivot = 1e-8;
// Relative pivot threshold of the Jacobi-scaled G M^-1 G^T (unit diagonal): below it a
// direction is dependent (ten digits lost of sixteen).
constexpr double kClosureRankThreshold = 1e-10;
// A G entry counts as round-off when below this fraction of the size of its terms.
constexpr double kClosureZeroEntry = 1e-11;
// Branch passages (branch_passage.cpp): a direction of the term-normalized G whose singular
// value is below kPassageBand is near a crossing of branches and held by the motion; below
// kPassageDependent it is a structural dependency (dropped, as the rank threshold drops it;
// the decomposition is each closure's own, singular values from its rows, not squared).
constexpr double kPassageBand = 1e-2;
constexpr double kPassageDependent = 1e-8;
// Below kPassageNear the projections go on to round-off past their tolerance (at most
// kPassageRoundoffSteps more steps, while each halves the last), and only for steps below
// kRoundoffStepBound of the length (positions) or speed (rates) scale.
constexpr double kPassageNear = 0.1;
constexpr int kPassageRoundoffSteps = 4;
constexpr double kRoundoffStepBound = 1e-8;
// The cheap gate before the passages' decomposition: W W^T - kPassageGate^2 I positive
// definite means no singular value near the band (0.3 is 30 times the band: the gate never
// lets a passage through unseen), kPassageGateMargin more for the LLT's own round-off.
constexpr double kPassageGate = 0.3;
constexpr double kPassageGateMargin = 1e-10;
// The damping classification is held over steps (joint_damping.cpp, classifyDamping) for at
// most kHoldSteps, while no body has moved more than kHoldMotion (rad, or of the length
// scale), and only where every coordinate's h s_k is kHoldMargin away from the stability
// bound: RK4's limit, 2.785, is 1.39 times its bound of 2, so a set held at 1.25 from it
// stays stable if s_k crosses unseen.
constexpr int kHoldSteps = 16;
constexpr double kHoldMotion = 0.05, kHoldMargin = 1.25;

}  // namespace joint_space

// ---- assembly (assembly.cpp)
namespace assembly {

// Levenberg-Marquardt iterations on the positions, augmented Lagrangian passes on the
// velocities, and the relative residual above which either fails (ModelError: the targets
// or the closures cannot be met) whatever the tolerances ask.
constexpr int kMaxPositionIterations = 300;
constexpr int kMaxVelocityIterations = 60;
constexpr double kAssemblyFailureResidual = 1e-9;
// The precision of a description, relative to its length scale: six significant digits, as
// CAD exporters write them (a rounded rpy is off by up to 5e-6 rad); loops whose dependent
// equations disagree by less at their least-squares pose are accepted (with a note), not
// refused.
constexpr double kDescriptionPrecision = 1e-5;
// Continuation: corrector iterations per step, iterations at s = 1, the smallest step of s
// (ten halvings: a path not followed at 1/1024 is left), the largest move of a coordinate in
// one iteration (radians, or length scales: beyond it the linearization misleads), the
// residual that counts as on the path, the gap 2 - |bz_j - bz_i| below which axes count as
// opposed, and how far (radians, length scales) a start is moved from opposed axes.
constexpr int kCorrectorIterations = 12;
constexpr int kFinalIterations = 200;
constexpr double kMinContinuationStep = 1.0 / 1024;
constexpr double kMaxStep = 0.5;
constexpr double kFollowTolerance = 1e-6;
constexpr double kOpposed = 1e-6;
constexpr double kNudge = 0.1;
// Restarts from poses drawn within the limits where the path from the file's pose ends in
// a minimum that does not close (TreeAssembly::run), and the draws' seed.
constexpr int kRestarts = 24;
constexpr unsigned kRestartSeed = 20261129;
// Closing the independent equations alone where the dependent ones disagree at the file's
// precision (closeIndependent): Gauss-Newton steps, and the largest move of one step in
// length scales. A file's rounding closes in two or three steps of 1e-5; a step beyond a
// hundredth of the model is not a rounding but a pose far from closing.
constexpr int kIndependentSteps = 8;
constexpr double kIndependentStepSize = 1e-2;

}  // namespace assembly

}  // namespace numerics
}  // namespace mechanism_sim
