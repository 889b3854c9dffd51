// Transmissions' maps and the validation of rotor inertias (transmission.h).
#include "mechanism_sim/core/model/transmission.h"

#include <cmath>
#include <sstream>

#include <Eigen/LU>

#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

const char* transmissionTypeName(TransmissionType t) {
  switch (t) {
    case TransmissionType::kSimple: return "SimpleTransmission";
    case TransmissionType::kDifferential: return "DifferentialTransmission";
    case TransmissionType::kFourBar: return "FourBarLinkageTransmission";
  }
  return "?";
}

void ActuatorRatings::validate(const std::string& name) const {
  const std::pair<const char*, double> values[] = {
      {"rotor_inertia", rotor_inertia}, {"rated_torque", rated_torque},       {"peak_torque", peak_torque},
      {"stall_torque", stall_torque},   {"no_load_speed", no_load_speed},     {"max_speed", max_speed},
      {"torque_constant", torque_constant}, {"resistance", resistance},      {"friction", friction},
      {"damping", damping}};
  for (const auto& [what, v] : values)
    if (!std::isfinite(v) || v < 0.0)
      throw ModelError("actuator '" + name + "': " + what + " must be finite and not negative");
  if ((stall_torque > 0.0) != (no_load_speed > 0.0))
    throw ModelError("actuator '" + name + "': a torque-speed line needs both stall_torque and no_load_speed");
  if (resistance > 0.0 && !(torque_constant > 0.0))
    throw ModelError("actuator '" + name + "': resistance needs torque_constant (the current follows from it)");
  if (rated_torque > 0.0 && peak_torque > 0.0 && rated_torque > peak_torque)
    throw ModelError("actuator '" + name + "': rated_torque exceeds peak_torque");
}

void Transmission::validate() const {
  const size_t n = static_cast<size_t>(size());
  if (actuator_reduction.size() != n || joint_reduction.size() != n || joint_offset.size() != n)
    throw ModelError("transmission '" + name + "': a " + transmissionTypeName(type) + " has " + std::to_string(n) +
                     (n == 1 ? " actuator and joint" : " actuators and joints"));
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(actuator_reduction[i]) || actuator_reduction[i] == 0.0 || !std::isfinite(joint_reduction[i]) ||
        joint_reduction[i] == 0.0)
      throw ModelError("transmission '" + name + "': a mechanical reduction must be finite and not zero");
    if (!std::isfinite(joint_offset[i])) throw ModelError("transmission '" + name + "': an offset must be finite");
  }
}

Eigen::MatrixXd Transmission::velocityMap() const {
  const std::vector<double>& a = actuator_reduction;
  const std::vector<double>& j = joint_reduction;
  Eigen::MatrixXd E(size(), size());
  switch (type) {
    case TransmissionType::kSimple:
      E << a[0];
      break;
    case TransmissionType::kDifferential:
      E << a[0] * j[0], a[0] * j[1], a[1] * j[0], -a[1] * j[1];
      break;
    case TransmissionType::kFourBar:
      E << a[0] * j[0], 0.0, a[1], a[1] * j[1];
      break;
  }
  return E;
}

namespace {
Eigen::VectorXd offsets(const Transmission& t) {
  return Eigen::Map<const Eigen::VectorXd>(t.joint_offset.data(), static_cast<int>(t.joint_offset.size()));
}
}  // namespace

Eigen::VectorXd Transmission::actuatorPosition(const Eigen::VectorXd& q) const {
  return velocityMap() * (q - offsets(*this));
}
Eigen::VectorXd Transmission::actuatorVelocity(const Eigen::VectorXd& q_dot) const { return velocityMap() * q_dot; }
Eigen::VectorXd Transmission::actuatorEffort(const Eigen::VectorXd& tau_q) const {
  return velocityMap().transpose().partialPivLu().solve(tau_q);
}
Eigen::VectorXd Transmission::jointPosition(const Eigen::VectorXd& theta) const {
  return velocityMap().partialPivLu().solve(theta) + offsets(*this);
}
Eigen::VectorXd Transmission::jointVelocity(const Eigen::VectorXd& theta_dot) const {
  return velocityMap().partialPivLu().solve(theta_dot);
}
Eigen::VectorXd Transmission::jointEffort(const Eigen::VectorXd& tau_theta) const {
  return velocityMap().transpose() * tau_theta;
}
Eigen::MatrixXd Transmission::reflectedInertia(const Eigen::VectorXd& rotor_inertia) const {
  const Eigen::MatrixXd E = velocityMap();
  return E.transpose() * rotor_inertia.asDiagonal() * E;
}

void validateRotors(const System& sys) {
  for (const RotorInertia& r : sys.rotors) {
    const int n = static_cast<int>(r.coords.size());
    if (n < 1 || n > 2) throw ModelError("rotor inertia '" + r.name + "': one or two joint coordinates");
    for (const auto& [joint, k] : r.coords) {
      if (joint < 0 || joint >= sys.numJoints() || k < 0 || k >= sys.joints[joint]->dof())
        throw ModelError("rotor inertia '" + r.name + "': no such joint coordinate");
      if (!sys.joints[joint]->holonomicCoordinates())
        throw ModelError("rotor inertia '" + r.name + "': joint '" + sys.joints[joint]->name() +
                         "' has no position coordinate to reflect an inertia on");
    }
    if (n == 2 && r.coords[0] == r.coords[1])
      throw ModelError("rotor inertia '" + r.name + "': its two coordinates are the same");
    const Eigen::MatrixXd B = r.B.topLeftCorner(n, n);
    const double scale = B.cwiseAbs().maxCoeff();
    if (!B.allFinite() || std::fabs(B(0, n - 1) - B(n - 1, 0)) > 1e-12 * scale)
      throw ModelError("rotor inertia '" + r.name + "': not finite or not symmetric");
    if (!std::isfinite(r.damping_coupling) || (n < 2 && r.damping_coupling != 0.0))
      throw ModelError("rotor inertia '" + r.name + "': a damping coupling needs two coordinates and a finite value");
    // positive semidefinite: the diagonal and the determinant (2 x 2) not negative, to round-off
    if (B(0, 0) < 0.0 || B(n - 1, n - 1) < 0.0 || (n == 2 && B.determinant() < -1e-12 * scale * scale))
      throw ModelError("rotor inertia '" + r.name + "': negative (a kinetic energy below zero)");
  }
}

void addRotorEdges(const System& sys, std::vector<std::pair<int, int>>& edges) {
  for (const RotorInertia& r : sys.rotors) {
    std::vector<int> bodies;
    for (const auto& c : r.coords)
      for (int b : sys.joints[c.first]->bodies())
        if (b > 0) bodies.push_back(b - 1);
    for (int b1 : bodies)
      for (int b2 : bodies)
        if (b1 < b2) edges.push_back({b1, b2});
  }
}

}  // namespace mechanism_sim
