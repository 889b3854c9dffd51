// The joints of a URDF file, tree joints and loop closures, gathered from urdfdom's model
// and the extension into one form with their frames resolved once: each joint's frame in
// its parent link and in its child link, z along the axis (x and y along a universal
// joint's two axes), SDF poses included. Internal to the loader.
#pragma once
#include <map>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <urdf_model/model.h>

#include "mechanism_sim/core/model/joint.h"
#include "xml_input.h"

namespace mechanism_sim {
namespace urdf_input {

struct JointSpec {
  std::string name;
  std::string type;  // a core joint type (jointTypeInfo), or "floating"
  const tinyxml2::XMLElement* element = nullptr;  // where errors point
  std::string parent, child;                      // links
  Isometry3d P_J = Isometry3d::Identity();        // joint frame in the parent link
  Isometry3d C_J = Isometry3d::Identity();        // joint frame in the child link
  // The joint frame as the file defines it, in the child link (a URDF joint's is the child
  // link's frame; a loop closure's its child_origin): C_J without the turn to the axis.
  // Joint reactions are reported in it.
  Isometry3d C_U = Isometry3d::Identity();
  JointParams params;                             // the screw's alpha
  double damping = 0.0, friction = 0.0;
  double lower = 0.0, upper = 0.0;    // position limits of a revolute or prismatic joint (none unless lower < upper)
  bool sdf_no_limit = false;          // the file wrote SDF's "no limit", [-1e16, 1e16]: none
  double effort = 0.0, velocity = 0.0;  // effort and velocity limits (0: none)
  std::string mimic;                    // the joint this one mimics, if any
  double mimic_multiplier = 1.0, mimic_offset = 0.0;
};

struct JointSpecs {
  std::vector<JointSpec> tree;   // the URDF's <joint>s, in file order
  std::vector<JointSpec> loops;  // loop closures (extension, then Gazebo, as in the file)
};

Isometry3d toEigen(const urdf::Pose& p);

// Joint coordinates by joint name (missing joints and coordinates: zero).
using JointValues = std::map<std::string, std::vector<double>>;

// The degrees of freedom of a joint's type, from the core's registry ("" for a one-dof
// joint; none for fixed and floating joints), and a dof's name: "joint" or "joint.dof".
const std::vector<std::string>& dofNames(const JointSpec& s);
std::string dofName(const JointSpec& s, int k);

// Checks what only the whole model can tell (overrides of existing joints, unique names,
// existing links) and fails with the element at fault.
JointSpecs collectJointSpecs(const tinyxml2::XMLElement* robot, const urdf::ModelInterface& urdf,
                             const Extension& ext, const XmlReader& reader);

// The URDF tree: the joints below each link, and the pose of every link.
class LinkTree {
 public:
  // `tree` must outlive the LinkTree, unchanged.
  LinkTree(const std::vector<JointSpec>& tree, const std::string& root);
  const std::string& root() const { return root_; }
  const std::vector<const JointSpec*>& below(const std::string& link) const;
  // Every link's pose in the root link's frame, with the tree joints at coordinates q.
  std::map<std::string, Isometry3d> poses(const JointValues& q = {}) const;

 private:
  std::string root_;
  std::map<std::string, std::vector<const JointSpec*>> below_;
};

}  // namespace urdf_input
}  // namespace mechanism_sim
