// The joint types by name: adding a joint type is one line here.
#include <stdexcept>
#include <utility>

#include "mechanism_sim/core/joints/cylindrical.h"
#include "mechanism_sim/core/joints/fixed.h"
#include "mechanism_sim/core/joints/planar.h"
#include "mechanism_sim/core/joints/prismatic.h"
#include "mechanism_sim/core/joints/revolute.h"
#include "mechanism_sim/core/joints/screw.h"
#include "mechanism_sim/core/joints/spherical.h"
#include "mechanism_sim/core/joints/universal.h"

namespace mechanism_sim {
namespace {

const std::pair<const char*, JointFactory> kJointTypes[] = {
    {"spherical", &SphericalJoint::make},
    {"revolute", &RevoluteJoint::make},
    {"cylindrical", &CylindricalJoint::make},
    {"prismatic", &PrismaticJoint::make},
    {"screw", &ScrewJoint::make},
    {"universal", &UniversalJoint::make},
    {"fixed", &FixedJoint::make},
    {"planar", &PlanarJoint::make},
};

}  // namespace

std::unique_ptr<Joint> makeJoint(const std::string& type, const std::string& name, int body_i,
                                 const JointFrame& frame_i, int body_j,
                                 const JointFrame& frame_j, const JointParams& params) {
  for (const auto& entry : kJointTypes)
    if (type == entry.first) return entry.second(name, body_i, frame_i, body_j, frame_j, params);
  throw std::invalid_argument("joint '" + name + "': unknown joint type '" + type + "'");
}

std::vector<std::string> jointTypes() {
  std::vector<std::string> names;
  for (const auto& entry : kJointTypes) names.emplace_back(entry.first);
  return names;
}

}  // namespace mechanism_sim
