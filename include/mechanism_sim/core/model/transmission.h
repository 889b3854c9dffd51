// Transmissions between actuators and joints, as ros_control's transmission_interface
// writes them (SimpleTransmission, DifferentialTransmission, FourBarLinkageTransmission),
// and the rotor inertia they reflect onto the joints (doc/actuators.md). ROS-free.
//
// Every one of the three is linear: with theta the actuator positions, q the joint
// positions, n_a the actuator reductions, n_j the joint reductions and q_0 the joint offsets,
//   theta = E (q - q_0),   theta_dot = E q_dot,
//   simple:        E = [n_a]
//   differential:  E = [n_a1 n_j1,  n_a1 n_j2;  n_a2 n_j1, -n_a2 n_j2]
//   four-bar:      E = [n_a1 n_j1,  0;          n_a2,       n_a2 n_j2]
// (ros_control's jointToActuatorPosition and jointToActuatorVelocity). Efforts follow from
// virtual work, tau_q = E^T tau_theta (power in equals power out): for the simple and the
// differential transmission that is ros_control's own effort map; for the four-bar it is
// ros2_control's corrected one (ros_control issue #523, ros2_control #1746), ros_control's
// being the inverse of a different velocity map.
//
// A rotor of inertia J_a on each actuator adds the kinetic energy
//   T_r = 1/2 theta_dot^T diag(J) theta_dot = 1/2 q_dot^T (E^T diag(J) E) q_dot,
// the reflected inertia B = E^T diag(J) E on the joint coordinates (N^2 J for a simple
// transmission: MuJoCo's armature, Drake's reflected inertia); a differential's is a full
// 2x2 matrix.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace mechanism_sim {

class System;

enum class TransmissionType { kSimple, kDifferential, kFourBar };
const char* transmissionTypeName(TransmissionType t);

// What a motor and its rotor are (0: not given). SI units: kg m^2, N m, rad/s, N m/A, ohm;
// friction and damping act on the motor shaft (N m, N m s/rad).
struct ActuatorRatings {
  double rotor_inertia = 0.0;
  double rated_torque = 0.0, peak_torque = 0.0;     // continuous (RMS) and peak
  double stall_torque = 0.0, no_load_speed = 0.0;   // a DC motor's torque-speed line
  double max_speed = 0.0;
  double torque_constant = 0.0, resistance = 0.0;
  double friction = 0.0, damping = 0.0;
  // Throws ModelError "actuator 'name': what" for a negative, non-finite or incomplete value
  // (a torque-speed line needs both ends).
  void validate(const std::string& name) const;
};

struct Transmission {
  std::string name;
  TransmissionType type = TransmissionType::kSimple;
  std::vector<double> actuator_reduction, joint_reduction, joint_offset;  // 1 or 2 each
  int size() const { return type == TransmissionType::kSimple ? 1 : 2; }
  // Throws ModelError "transmission 'name': what" for a zero or non-finite reduction or
  // offset, or sizes that do not fit the type.
  void validate() const;
  // theta_dot = E q_dot (size() x size()).
  Eigen::MatrixXd velocityMap() const;
  // The maps between joint space (q: positions, velocities, efforts of the joints in the
  // transmission's order) and actuator space.
  Eigen::VectorXd actuatorPosition(const Eigen::VectorXd& q) const;   // E (q - q_0)
  Eigen::VectorXd actuatorVelocity(const Eigen::VectorXd& q_dot) const;  // E q_dot
  Eigen::VectorXd actuatorEffort(const Eigen::VectorXd& tau_q) const;    // E^-T tau_q
  Eigen::VectorXd jointPosition(const Eigen::VectorXd& theta) const;     // E^-1 theta + q_0
  Eigen::VectorXd jointVelocity(const Eigen::VectorXd& theta_dot) const;  // E^-1 theta_dot
  Eigen::VectorXd jointEffort(const Eigen::VectorXd& tau_theta) const;   // E^T tau_theta
  // B = E^T diag(J) E, J the actuators' rotor inertias.
  Eigen::MatrixXd reflectedInertia(const Eigen::VectorXd& rotor_inertia) const;
};

// The reflected rotor inertia of one transmission on joint coordinates of a System: the
// kinetic energy 1/2 q_dot^T B q_dot, with q_dot the rates of coords (joint, k) in order
// (at most two). Both formulations take it into their equations of motion (doc/actuators.md).
struct RotorInertia {
  std::string name;
  std::vector<std::pair<int, int>> coords;
  Eigen::Matrix2d B = Eigen::Matrix2d::Zero();  // the top-left coords.size() square is used
  // The off-diagonal term D_01 of the motors' reflected damping D = E^T diag(c_m) E (a
  // differential's; D's diagonal is the joints' own damping, System::damping, where both
  // formulations' damping rules take it): the efforts -D_01 q_dot_1 along coords[0] and
  // -D_01 q_dot_0 along coords[1], dissipating with the diagonal q_dot^T D q_dot.
  double damping_coupling = 0.0;
  // Whether B or the damping couples two coordinates (an off-diagonal term).
  bool coupled() const { return coords.size() > 1 && (B(0, 1) != 0.0 || damping_coupling != 0.0); }
};

// Throws ModelError naming the rotor for a coordinate the System lacks, a joint that is not
// a one-dof holonomic one, a B that is not symmetric positive semidefinite or not finite,
// (two rotors on one coordinate add up).
void validateRotors(const System& sys);
// Body pairs (moving indices, i < j) the rotors' inertia couples: the bodies of their joints.
void addRotorEdges(const System& sys, std::vector<std::pair<int, int>>& edges);

}  // namespace mechanism_sim
