// A URDF mechanism for the core: loaded with urdfdom, plus the mechanism_sim extension
// and Gazebo <gazebo><joint> loop closures (doc/model_format.md). ROS-free.
// MechanismModel is the library's entry point for programs that embed the simulator
// (doc/embedding.md): load, step, reset and ask it; mechanism() is the core
// underneath, for what the model does not answer itself.
#pragma once
#include <array>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/core/model/davenport.h"
#include "mechanism_sim/core/model/transmission.h"

namespace mechanism_sim {

// A file that cannot be simulated: "FILE:LINE: element 'name': what is wrong".
// Every failure while loading, building or assembling reaches the caller as a LoadError,
// one line naming the file (a core ModelError gets the file put before it; an internal
// error says it is one).
class LoadError : public Error {
 public:
  using Error::Error;
};

struct LoadOptions {
  // Initial positions / velocities by degree-of-freedom name ("joint" or "joint.dof"),
  // overriding the file's <mechanism_sim:initial>.
  std::vector<std::pair<std::string, double>> positions, velocities;
  std::string integrator;  // empty: the core's default
  std::string formulation;  // "absolute", "joint" or "auto" (IntegratorOptions); empty: auto
  // Velocity drives by dof name (simulate --drive), replacing the file's drive of that dof.
  std::vector<std::pair<std::string, double>> drives;
  // "Extended URDF" closures (YAML: closed_loop, type, name_mot; doc/loop_dialects.md).
  // Empty: loadModelFile reads FILE.yaml beside FILE.urdf if it lists closed_loop;
  // loadModelString reads none.
  std::string closures_file;
  // xacro arguments (name:=value) for a file ending in .xacro, which loadModelFile expands
  // first (doc/xacro.md); given for another file, they are an error.
  std::vector<std::pair<std::string, std::string>> xacro_args;
  // A rigid body whose inertia is not physical (principal moments that break the triangle
  // inequality) is refused; by default it runs with the nearest physical inertia and a
  // note (doc/robots.md, "Inertias that are not physical").
  bool strict_inertia = false;
  // Actuator ratings (YAML, doc/actuators.md) over the file's <mechanism_sim:actuator>.
  std::string actuators_file;
  // The saturating mode (MechanismModel::setActuatorLimits): actuators bound their drives.
  bool actuator_limits = false;
};

// One degree of freedom of a joint, tree or loop closure.
struct Dof {
  std::string name;       // "joint" for one-dof joints, "joint.rotation" etc. otherwise
  std::string joint;      // the joint's name
  int joint_index = -1;   // Mechanism joint index
  int k = 0;              // coordinate of that joint
  double effort_limit = 0.0, velocity_limit = 0.0;  // 0: none
  int drive = -1;         // Mechanism drive index, or -1 (not driven)
  // Takes an effort command or a drive. False for the passive dofs of a file that names its
  // actuated joints (an Extended-URDF name_mot: doc/loop_dialects.md) and for a gimbal's
  // (MechanismModel::whyPassive says which).
  bool actuated = true;
  // A ball the file writes as three revolute joints through massless links (doc/robots.md):
  // the index of its gimbal (MechanismModel::gimbalAngles); joint_index is the spherical
  // joint simulated in their place and k this joint's place in the chain. -1: none.
  int gimbal = -1;
};

// A ball the file writes as three revolute joints J0, J1, J2 through massless links L1, L2,
// simulated as one spherical joint and reported by the file's three angles: the spherical
// joint's relative rotation is Rot(e0, t0) Rot(e1, t1) Rot(e2, t2) (Davenport angles), so
// t0, t1, t2 are the joints' positions, and L1, L2 are placed where the angles turn them.
struct Gimbal {
  int joint = -1;                        // the spherical joint (Mechanism index)
  DavenportAxes axes{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ()};
  int parent_link = -1, link1 = -1, link2 = -1, child_link = -1;  // links(): J0's parent, L1, L2, J2's child
  // J0's and J1's joint frames in their parent and child links (z: the axis), as written
  std::array<Eigen::Isometry3d, 2> P_J, C_J;
};

struct Link {
  std::string name;
  int body = 0;                                          // Mechanism body (0: ground)
  Eigen::Isometry3d body_T_link = Eigen::Isometry3d::Identity();
};

// A URDF tree joint, as tf publishes it (parent link -> child link).
struct TreeJoint {
  std::string name, parent, child;
  bool fixed = false;
};

// A loop-closure joint (<mechanism_sim:joint> with parent and child, or <gazebo><joint>):
// the origin of its joint frame on each side, as a point in that link's frame. The two
// points coincide while the loop holds (for a joint whose frames coincide: revolute,
// spherical, universal, fixed; along the axis they may slide apart for prismatic,
// cylindrical and screw joints).
struct LoopJoint {
  std::string name, type;               // type as the core names it ("revolute", "spherical", ...)
  int parent_link = -1, child_link = -1;  // indices into links()
  Eigen::Vector3d parent_point = Eigen::Vector3d::Zero(), child_point = Eigen::Vector3d::Zero();
};

// The force and torque a joint exerts on its child link, at the joint origin, in the
// joint frame on the child as the file defines it (a URDF joint: the child link's frame; a
// loop closure: its child_origin) (Gazebo's JointWrench body2 convention).
struct JointReaction {
  std::string joint;
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
};

// A <mechanism_sim:coupling> of the file (sum_i c_i q_i = c_0): its name and core
// constraint (Mechanism::addCoupling), or with backlash its limit (addBacklashCoupling).
struct CouplingInfo {
  std::string name;
  int constraint = -1;
  int limit = -1;
};

// A <transmission> the model simulates (doc/actuators.md): its maps (transmission.h), the
// dofs of its joints and its actuators, both in its roles' order.
struct TransmissionInfo {
  Transmission map;
  std::vector<int> dofs;
  std::vector<int> actuators;  // indices into MechanismModel::actuators()
  // map.velocityMap() and its inverse transpose, in the top-left size x size (what
  // actuatorState applies at every step, without allocating)
  Eigen::Matrix2d E = Eigen::Matrix2d::Zero(), E_inv_T = Eigen::Matrix2d::Zero();
};

// An actuator a simulated transmission names, with its ratings (0: not given).
struct Actuator {
  std::string name;
  int transmission = -1, k = 0;  // its transmission and its row there
  ActuatorRatings ratings;
};

// An actuator's operating point: motor-side position, velocity, torque and mechanical
// power (torque times velocity); with a torque_constant also its current, voltage and
// electrical power (actuator_sizing.h's electrical(); 0 otherwise).
struct ActuatorState {
  double position = 0.0, velocity = 0.0, torque = 0.0, power = 0.0;
  double current = 0.0, voltage = 0.0, electrical_power = 0.0;
  // In the saturating mode: how far its joint's drive is behind its profile (the joint
  // coordinate's units; Mechanism::driveLag) and whether the actuator is at its bound.
  double lag = 0.0;
  bool saturated = false;
};

class MechanismModel {
 public:
  // ---- what the model is
  const std::string& name() const { return name_; }
  const std::string& source() const { return source_; }  // the file (or the name given to a string)
  const std::string& rootLink() const { return root_link_; }
  const std::vector<Dof>& dofs() const { return dofs_; }  // tree joints in file order, then loops
  const std::vector<Link>& links() const { return links_; }
  const std::vector<TreeJoint>& treeJoints() const { return tree_; }
  const std::vector<LoopJoint>& loopJoints() const { return loops_; }
  int dofIndex(const std::string& name) const;   // -1 if there is none
  int linkIndex(const std::string& name) const;  // -1 if there is none
  int numMovingBodies() const;                   // rigid bodies (links joined by fixed joints are one)
  int numEquations() const;                      // constraint equations, dependent ones included
  // Dependent equations and the joints they belong to (found at assembly).
  const DependencyReport& dependencies() const;
  // Violations relative to the size of each equation's terms (scale-free).
  double relativePositionViolation() const { return mechanism_->relativePositionViolation(); }
  double relativeVelocityViolation() const { return mechanism_->relativeVelocityViolation(); }
  // Iterations that stopped short of their tolerance (SolverStats::describe() says which).
  SolverStats solverStats() const { return mechanism_->solverStats(); }
  const AssemblyReport& assembly() const { return assembly_; }
  const Eigen::Vector3d& gravity() const;
  // What loading changed or left out, one line each: "assembly moved ..." (dofs the
  // assembly moved onto the loop closures, old -> new), the actuated joints a file names.
  // Empty when the file ran as written.
  const std::vector<std::string>& notes() const { return notes_; }
  void setGravity(const Eigen::Vector3d& g);  // overrides the file's <mechanism_sim:gravity>
  // No moving body has mass: the model runs kinematically, each free dof driven or held
  // (a velocity drive of velocity 0), the rest solved from the loops and couplers
  // (doc/method.md, "Kinematic models"); a note says how many of each.
  bool kinematic() const { return kinematic_; }
  // The formulation that runs and why (Mechanism::formulationReason), or that the model runs
  // kinematically (simulate's summary, the node's log and diagnostics, Python).
  std::string formulationReason() const;

  const std::vector<TransmissionInfo>& transmissions() const { return transmissions_; }
  const std::vector<Actuator>& actuators() const { return actuators_; }
  const std::vector<CouplingInfo>& couplings() const { return couplings_; }
  // The saturating mode (doc/actuators.md): with `on`, each actuator of a simple transmission
  // whose ratings bound its torque (peak_torque, a torque-speed line) bounds the drive of its
  // joint (Mechanism::setActuatorLimits); off, every drive follows its profile (sizing).
  // Returns a note naming the rated actuators it cannot bound (those of differential and
  // four-bar transmissions), or that none bounds anything; empty otherwise.
  std::string setActuatorLimits(bool on);
  bool actuatorLimits() const { return actuator_limits_; }

  // ---- where it is now
  double time() const;
  // An actuator's operating point through its transmission's maps (transmission.h): position
  // and velocity from its joints'; torque from the joint efforts the actuators supply (the
  // commanded efforts and the drives' efforts, which include the rotors' reflected inertia,
  // not damping, friction or limits), E^-T, plus the motor's own damping and friction
  // (Actuator::ratings) at its speed.
  ActuatorState actuatorState(int actuator) const;
  // World pose of a link.
  Eigen::Isometry3d linkPose(int link) const;
  // Velocity of a link's frame origin and its angular velocity, both in world axes.
  std::pair<Eigen::Vector3d, Eigen::Vector3d> linkVelocity(int link) const;
  // Degree of freedom: position, rate, and the effort the joint applies along it
  // (commanded effort minus damping plus friction, plus a limit's reaction).
  double position(int dof) const;
  double velocity(int dof) const;
  double effort(int dof) const;
  // Its acceleration, solved with the state when it was reached (a step, an assembly) under
  // the inputs in force then (Mechanism::jointAcceleration).
  double acceleration(int dof) const;
  double kineticEnergy() const;
  double potentialEnergy() const;   // gravity and springs
  // The angles of a ball written as a gimbal (Dof::gimbal), each continued from the last
  // ones reported (whole turns kept; reset() starts them again at the file's zero).
  const Angles3& gimbalAngles(int gimbal) const;
  const std::vector<Gimbal>& gimbals() const { return gimbals_; }
  // Why a dof takes no effort command, drive or trajectory ("" if it takes them).
  std::string whyPassive(int dof) const;
  // Every joint with equations (tree joints that are not fixed or floating, and loop
  // closures; in the core's joint order; then each gimbal's J1 and J2, which pass on what its
  // ball carries, their links being massless): what it exerts on its child link, constraint,
  // limits, drive, mimic share and applied efforts together. Where equations are dependent
  // (two hinges on one axis, a planar loop) the least-norm reactions: the same state gives
  // the same reactions whatever the history.
  std::vector<JointReaction> jointReactions() const;
  // Per coupling (couplings()): its multiplier lambda; each coupled coordinate i carries
  // the effort -c_i lambda (Mechanism::couplingReaction).
  std::vector<double> couplingReactions() const;
  // World pose of the frame jointReactions() are given in: the joint frame on the child of
  // core joint j, then of each gimbal's J1 and J2 (the order of jointReactions()).
  Eigen::Isometry3d reactionFrame(int joint) const;
  double positionViolation() const;  // largest |Phi|
  double velocityViolation() const;  // largest |Phi_q v|
  // Over the equations a step can leave violated (Mechanism::stepPositionViolation): cheap
  // after a step.
  double stepPositionViolation() const;
  double stepVelocityViolation() const;

  // ---- running
  // Commanded effort along a dof, clamped to its effort limit; a velocity limit cuts the
  // command while it would drive the joint faster than the limit. Throws on a bad value.
  void setEffort(int dof, double tau);
  double commandedEffort(int dof) const { return command_[dof]; }
  // A velocity-driven dof moves to velocity v from now, at acceleration at most acc (> 0).
  // Throws UsageError naming the dof (not driven, a profile drive, bad value).
  void commandDriveVelocity(int dof, double v, double acc);
  // What the drive of a dof prescribes now (throws if the dof is not driven).
  double driveVelocity(int dof) const;
  // A free dof becomes velocity-driven from now on, going on at its current velocity until
  // commanded (Mechanism::addDrive after build; trajectory.h gives it a path); reset()
  // frees it again. Throws UsageError naming the dof (driven already, or its
  // motion follows from the other joints and drives), the model unchanged.
  void driveDof(int dof);
  // Frees a dof that driveDof() drove (the drives after it move down by one).
  void undriveDof(int dof);
  // One step of h seconds. Throws SimulationError "FILE: at t = T s: what" when the step
  // fails (the state stays at the last accepted step).
  void step(double h);
  // Back to the assembled initial state, commands zeroed, dofs driven by driveDof() free.
  void reset();

  // The core underneath (bodies, joints, reactions, body wrenches, integrator options).
  Mechanism& mechanism() { return *mechanism_; }
  const Mechanism& mechanism() const { return *mechanism_; }

 private:
  friend class ModelBuilder;
  std::unique_ptr<Mechanism> mechanism_;
  std::string name_, root_link_, source_;
  std::vector<Dof> dofs_;
  std::vector<Link> links_;
  std::vector<TreeJoint> tree_;
  std::vector<LoopJoint> loops_;
  std::vector<TransmissionInfo> transmissions_;
  std::vector<CouplingInfo> couplings_;
  std::vector<Actuator> actuators_;
  std::vector<Gimbal> gimbals_;
  int dofOfGimbal(size_t gimbal, int k) const;
  // A gimbal's ball's three values of `of` (jointPosition, jointVelocity, jointEffort, ...).
  Eigen::Vector3d ballVector(int gimbal, double (Mechanism::*of)(int, int) const) const;
  // The rates of a gimbal's angles from its ball's relative angular velocity (davenport.h).
  Angles3 gimbalRates(int gimbal) const;
  // per gimbal: the angles last reported and the rotation vector they were reported at
  mutable std::vector<std::pair<Angles3, Eigen::Vector3d>> gimbal_angles_;
  std::vector<Eigen::Isometry3d> reaction_frames_;  // per core joint: its file frame in its child's body
  std::vector<double> command_;
  AssemblyReport assembly_;
  std::vector<std::string> notes_;
  Mechanism::Snapshot initial_;
  std::vector<int> driven_after_load_;  // dofs driveDof() drove, in order
  bool kinematic_ = false;
  bool actuator_limits_ = false;
};

// Loads, builds and assembles. Throws LoadError naming the file, element and problem. A
// path ending in .xacro is expanded by ROS's xacro first (doc/xacro.md); its errors are
// "FILE: xacro: what", and the model's read "FILE (xacro expansion):LINE: ...".
std::unique_ptr<MechanismModel> loadModelFile(const std::string& path, const LoadOptions& options = {});
std::unique_ptr<MechanismModel> loadModelString(const std::string& xml, const std::string& source,
                                                const LoadOptions& options = {});

}  // namespace mechanism_sim
