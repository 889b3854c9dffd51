// The joint types by name: adding a joint type is one line here (registerJoint<ItsClass>()).
#include <stdexcept>
#include <string>
#include <utility>

#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/model/joints/cylindrical.h"
#include "mechanism_sim/core/model/joints/fixed.h"
#include "mechanism_sim/core/model/joints/planar.h"
#include "mechanism_sim/core/model/joints/prismatic.h"
#include "mechanism_sim/core/model/joints/revolute.h"
#include "mechanism_sim/core/model/joints/screw.h"
#include "mechanism_sim/core/model/joints/spherical.h"
#include "mechanism_sim/core/model/joints/universal.h"

namespace mechanism_sim {
namespace {

// A joint type's entry, from what its class declares: kType, make, kDofNames ("" for a
// one-dof joint), relativePose (the pose of frame j in frame i), treeModel (its joint-space
// tree calculation).
template <class JointType>
JointTypeInfo registerJoint() {
  static_assert(JointType::kDofNames.size() <= kMaxJointDofs, "more degrees of freedom than kMaxJointDofs");
  return {JointType::kType, &JointType::make,
          std::vector<std::string>(JointType::kDofNames.begin(), JointType::kDofNames.end()),
          &JointType::relativePose, JointType::treeModel()};
}

const JointTypeInfo kJointTypes[] = {
    registerJoint<SphericalJoint>(),
    registerJoint<RevoluteJoint>(),
    registerJoint<CylindricalJoint>(),
    registerJoint<PrismaticJoint>(),
    registerJoint<ScrewJoint>(),
    registerJoint<UniversalJoint>(),
    registerJoint<FixedJoint>(),
    registerJoint<PlanarJoint>(),
};

}  // namespace

const JointTypeInfo& jointTypeInfo(const std::string& type) {
  for (const auto& entry : kJointTypes)
    if (type == entry.name) return entry;
  throw ModelError("unknown joint type '" + type + "'");
}

const TreeJointModel* treeJointModel(const std::string& type) {
  for (const auto& entry : kJointTypes)
    if (type == entry.name) return entry.tree.calc ? &entry.tree : nullptr;
  return nullptr;
}

const TreeJointModel& treeJointModel(TreeJointKind kind) {
  for (const auto& entry : kJointTypes)
    if (entry.tree.calc && entry.tree.kind == kind) return entry.tree;
  throw ModelError("no joint type has the tree model of tag " + std::to_string(static_cast<int>(kind)));
}

std::string Joint::dofName(int k) const { return jointTypeInfo(type()).dof_names.at(k); }

std::unique_ptr<Joint> makeJoint(const std::string& type, const std::string& name, int body_i,
                                 const JointFrame& frame_i, int body_j,
                                 const JointFrame& frame_j, const JointParams& params) {
  for (const auto& entry : kJointTypes)
    if (type == entry.name) return entry.make(name, body_i, frame_i, body_j, frame_j, params);
  throw ModelError("joint '" + name + "': unknown joint type '" + type + "'");
}

std::vector<std::string> jointTypes() {
  std::vector<std::string> names;
  for (const auto& entry : kJointTypes) names.push_back(entry.name);
  return names;
}

}  // namespace mechanism_sim
