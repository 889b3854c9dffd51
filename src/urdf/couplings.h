// <mechanism_sim:coupling>: a linear coupling sum_i c_i q_i = c_0 among joint coordinates
// (gears, racks, belts, differentials, planetary trains; coupling.h, doc/model_format.md).
// Internal to the loader.
#pragma once
#include <map>
#include <string>
#include <vector>

#include <tinyxml2.h>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
class Mechanism;
namespace urdf_input {
struct XmlReader;
struct JointSpecs;

struct ExtLinearCoupling {
  const tinyxml2::XMLElement* element = nullptr;
  std::string name;
  double c0 = 0.0;  // attribute constant
  double backlash = 0.0;  // attribute backlash (0: none, the equation exact)
  struct Term {
    const tinyxml2::XMLElement* element = nullptr;
    std::string joint, dof;  // dof: a multi-dof joint's coordinate name (dofNames), or ""
    double c = 0.0;          // attribute coefficient
  };
  std::vector<Term> terms;
};

// Reads one <mechanism_sim:coupling> element: its attributes and <joint> children, with
// one-line errors naming file, line and element.
ExtLinearCoupling readLinearCoupling(const tinyxml2::XMLElement* e, const XmlReader& reader);

// Adds the couplings to the Mechanism (Mechanism::addCoupling, or addBacklashCoupling for
// one with backlash), each joint resolved among the file's joints (joint_index: the core
// joint of each joint that has one); returns each one's name and constraint or limit, in
// order. Errors name the element at fault.
std::vector<CouplingInfo> addLinearCouplings(const std::vector<ExtLinearCoupling>& couplings, const JointSpecs& specs,
                                    const std::map<std::string, int>& joint_index, Mechanism& mech,
                                    const XmlReader& reader);

}  // namespace urdf_input
}  // namespace mechanism_sim
