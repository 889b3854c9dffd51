// Reading <transmission> elements (ros_control's transmission_interface and the PR2 form),
// <mechanism_sim:actuator> elements and an actuators YAML file (doc/actuators.md).
// Internal to the loader.
#pragma once
#include <map>
#include <string>
#include <vector>

#include <tinyxml2.h>

#include "mechanism_sim/core/model/transmission.h"
#include "xml_input.h"

namespace mechanism_sim {
namespace urdf_input {

struct TransmissionSpec {
  const tinyxml2::XMLElement* element = nullptr;
  Transmission map;                     // its type, reductions and offsets
  std::vector<std::string> joints, actuators;  // in the roles' order (joint1, joint2; actuator1, actuator2)
  std::string note;  // what the loader assumed (a missing reduction: the loader lists them), "" if nothing
};

struct ActuatorSpec {
  const tinyxml2::XMLElement* element = nullptr;  // its <mechanism_sim:actuator>, if any
  std::string source;                             // where its ratings were given ("" if nowhere)
  ActuatorRatings ratings;
};

struct Transmissions {
  std::vector<TransmissionSpec> simulated;
  // Types read but not simulated: type -> count (listed as ignored, as other elements)
  std::map<std::string, int> ignored;
  std::map<std::string, ActuatorSpec> actuators;  // by name: every actuator a simulated one names
  int repeated = 0;  // transmissions that repeat a simulated one exactly (read once)
};

// The robot's <transmission> children and <mechanism_sim:actuator> elements. Throws
// LoadError "FILE:LINE: element 'name': what" for a transmission of a simulated type that
// is incomplete or wrong (no joint, a zero reduction, roles missing) or an actuator element
// with a bad value or naming no actuator of a simulated transmission.
Transmissions readTransmissions(const tinyxml2::XMLElement* robot, const XmlReader& reader);

// Actuator ratings from a YAML file (simulate --actuators FILE):
//   actuators:
//     NAME: {rotor_inertia: 1.2e-5, rated_torque: 0.3, ...}
// replacing the file's values of the keys it gives. Throws LoadError "FILE:LINE: what" for
// an unknown key or actuator, or a value that is not a number.
void readActuatorsFile(const std::string& path, Transmissions& into);

}  // namespace urdf_input
}  // namespace mechanism_sim
