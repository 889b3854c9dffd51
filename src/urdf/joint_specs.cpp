#include "joint_specs.h"

#include <cmath>
#include <functional>
#include <set>

namespace mechanism_sim {
namespace urdf_input {

namespace {

Isometry3d rotation(const Matrix3d& R) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = R;
  return T;
}

// Joint-frame axes for a joint's axis (and axis2): z along the axis; a universal joint's x
// along axis and y along axis2, which must be perpendicular.
Matrix3d frameAxes(const std::string& type, const Vector3d& axis, const Vector3d& axis2,
                   const tinyxml2::XMLElement* e, const XmlReader& reader) {
  if (type != "universal") return Quaterniond::FromTwoVectors(Vector3d::UnitZ(), axis).toRotationMatrix();
  if (std::fabs(axis.dot(axis2)) > 1e-6) reader.fail(e, "universal joint axes must be perpendicular");
  Matrix3d R;
  R.col(0) = axis;
  R.col(1) = (axis2 - axis.dot(axis2) * axis).normalized();
  R.col(2) = R.col(0).cross(R.col(1));
  return R;
}

std::string coreType(const std::string& type) { return type == "continuous" ? "revolute" : type; }

// <mechanism_sim:joint name=...> without parent and child gives a URDF joint another type.
std::map<std::string, const ExtJoint*> typeOverrides(const urdf::ModelInterface& urdf, const Extension& ext,
                                                     const XmlReader& reader) {
  std::map<std::string, const ExtJoint*> overrides;
  std::set<std::string> names;
  for (const auto& j : urdf.joints_) names.insert(j.first);
  for (const ExtJoint& e : ext.joints) {
    if (e.loop) {
      if (!names.insert(e.name).second) reader.fail(e.element, "a joint named '" + e.name + "' already exists");
      continue;
    }
    const auto it = urdf.joints_.find(e.name);
    if (it == urdf.joints_.end())
      reader.fail(e.element, "no URDF joint '" + e.name + "' to give this type to (a loop closure needs <parent> and <child>)");
    if (it->second->type == urdf::Joint::FIXED || it->second->type == urdf::Joint::FLOATING)
      reader.fail(e.element, "cannot change the type of a fixed or floating URDF joint");
    if (!overrides.emplace(e.name, &e).second) reader.fail(e.element, "joint type given twice");
  }
  return overrides;
}

// A URDF <joint>: its frame is the joint origin in the parent link and the child link's
// frame in the child, turned so that z lies along the axis.
JointSpec treeJoint(const urdf::Joint& j, const tinyxml2::XMLElement* element, const ExtJoint* override,
                    const XmlReader& reader) {
  JointSpec s;
  s.name = j.name;
  s.element = element;
  s.parent = j.parent_link_name;
  s.child = j.child_link_name;
  Vector3d axis(j.axis.x, j.axis.y, j.axis.z), axis2 = Vector3d::UnitY();
  if (axis.norm() > 0) axis.normalize(); else axis = Vector3d::UnitX();
  switch (j.type) {
    case urdf::Joint::REVOLUTE: case urdf::Joint::CONTINUOUS: s.type = "revolute"; break;
    case urdf::Joint::PRISMATIC: s.type = "prismatic"; break;
    case urdf::Joint::PLANAR: s.type = "planar"; break;
    case urdf::Joint::FLOATING: s.type = "floating"; break;
    default: s.type = "fixed";
  }
  if (j.limits && j.type != urdf::Joint::CONTINUOUS) s.lower = j.limits->lower, s.upper = j.limits->upper;
  if (j.limits) s.effort = j.limits->effort, s.velocity = j.limits->velocity;
  if (j.dynamics) s.damping = j.dynamics->damping, s.friction = j.dynamics->friction;
  if (j.mimic) s.mimic = j.mimic->joint_name, s.mimic_multiplier = j.mimic->multiplier, s.mimic_offset = j.mimic->offset;
  if (override) {
    s.type = coreType(override->type);
    s.params.alpha = override->alpha;
    if (override->axes_given || (override->element && override->element->FirstChildElement("axis"))) axis = override->axis;
    axis2 = override->axis2;
    if (override->damping > 0) s.damping = override->damping;
    if (override->friction > 0) s.friction = override->friction;
    if (s.type != "revolute" && s.type != "prismatic") s.lower = s.upper = 0;
  }
  const Matrix3d R = frameAxes(s.type, axis, axis2, element, reader);
  s.P_J = toEigen(j.parent_to_joint_origin_transform) * rotation(R);
  s.C_J = rotation(R);
  return s;
}

// A loop closure. Extension: <origin> in the parent link, <child_origin> in the child, the
// axes in the joint frame. SDF: the pose in the child link, the axes in the joint frame or
// the model frame, and the parent side where the joint frame sits in the URDF's zero
// configuration (`nominal`: every link's pose with the tree joints at zero).
JointSpec loopJoint(const ExtJoint& e, const urdf::ModelInterface& urdf,
                    const std::map<std::string, Isometry3d>& nominal, const XmlReader& reader) {
  JointSpec s;
  s.name = e.name;
  s.type = coreType(e.type);
  s.element = e.element;
  s.parent = e.parent;
  s.child = e.child;
  // SDF's <parent>world</parent>: the world, where the URDF's root link is fixed
  if (e.sdf && e.parent == "world" && !urdf.getLink("world")) s.parent = urdf.getRoot()->name;
  s.params.alpha = e.alpha;
  s.damping = e.damping;
  s.friction = e.friction;
  if (!urdf.getLink(s.parent)) reader.fail(e.element, "parent link '" + e.parent + "' does not exist");
  if (!urdf.getLink(e.child)) reader.fail(e.element, "child link '" + e.child + "' does not exist");
  if (s.parent == e.child) reader.fail(e.element, "joint's parent is its child ('" + e.parent + "')");
  if (!e.sdf) {
    Isometry3d child_origin = e.child_origin;
    if (e.child_rotation_from_zero_pose)  // the frames' rotations coincide at the zero pose
      child_origin.linear() = (nominal.at(e.child).inverse() * nominal.at(e.parent) * e.origin).linear();
    const Matrix3d R = frameAxes(s.type, e.axis, e.axis2, e.element, reader);
    s.P_J = e.origin * rotation(R);
    s.C_J = child_origin * rotation(R);
    s.C_U = child_origin;
    return s;
  }
  // an SDF frame named by relative_to or expressed_in: a link (at the zero configuration),
  // __model__ (the root link's frame) or the world
  auto frame = [&](const std::string& name) -> Isometry3d {
    if (name == "__model__" || (name == "world" && !urdf.getLink("world"))) return Isometry3d::Identity();
    const auto it = nominal.find(name);
    if (it == nominal.end())
      reader.fail(e.element, "SDF frame '" + name + "' is not a link of the model (a link, __model__ or world)");
    return it->second;
  };
  const Isometry3d W_J = e.pose_relative_to.empty() ? nominal.at(e.child) * e.child_origin
                                                    : frame(e.pose_relative_to) * e.child_origin;
  const Isometry3d child_origin = nominal.at(e.child).inverse() * W_J;  // the joint frame in the child link
  auto inJoint = [&](const Vector3d& a) -> Vector3d {
    if (e.axis_in_model) return W_J.linear().transpose() * a;
    if (!e.axis_expressed_in.empty()) return W_J.linear().transpose() * frame(e.axis_expressed_in).linear() * a;
    return a;
  };
  const Matrix3d R = frameAxes(s.type, inJoint(e.axis), inJoint(e.axis2), e.element, reader);
  s.C_J = child_origin * rotation(R);
  s.C_U = child_origin;
  s.P_J = nominal.at(s.parent).inverse() * nominal.at(e.child) * s.C_J;
  return s;
}

}  // namespace

Isometry3d toEigen(const urdf::Pose& p) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().toRotationMatrix();
  T.translation() = Vector3d(p.position.x, p.position.y, p.position.z);
  return T;
}

const std::vector<std::string>& dofNames(const JointSpec& s) {
  static const std::vector<std::string> none;
  return s.type == "floating" ? none : jointTypeInfo(s.type).dof_names;
}

std::string dofName(const JointSpec& s, int k) {
  const std::vector<std::string>& names = dofNames(s);
  return names.size() == 1 ? s.name : s.name + "." + names.at(k);
}

JointSpecs collectJointSpecs(const tinyxml2::XMLElement* robot, const urdf::ModelInterface& urdf,
                             const Extension& ext, const XmlReader& reader) {
  const std::map<std::string, const ExtJoint*> overrides = typeOverrides(urdf, ext, reader);
  JointSpecs specs;
  for (auto* e = robot->FirstChildElement("joint"); e; e = e->NextSiblingElement("joint")) {
    const char* name = e->Attribute("name");
    const auto found = urdf.joints_.find(name ? name : "");
    if (found == urdf.joints_.end() || !found->second)  // tinyxml2 and urdfdom's TinyXML disagree
      reader.fail(e, "urdfdom reads this joint's name differently (an unescaped '&' or '<'? write &amp; or &lt;)");
    const urdf::Joint& j = *found->second;
    const auto o = overrides.find(j.name);
    specs.tree.push_back(treeJoint(j, e, o == overrides.end() ? nullptr : o->second, reader));
  }
  const std::map<std::string, Isometry3d> nominal = LinkTree(specs.tree, urdf.getRoot()->name).poses();
  for (const ExtJoint& e : ext.joints)
    if (e.loop) specs.loops.push_back(loopJoint(e, urdf, nominal, reader));
  return specs;
}

LinkTree::LinkTree(const std::vector<JointSpec>& tree, const std::string& root) : root_(root) {
  for (const JointSpec& s : tree) below_[s.parent].push_back(&s);
}

const std::vector<const JointSpec*>& LinkTree::below(const std::string& link) const {
  static const std::vector<const JointSpec*> none;
  const auto it = below_.find(link);
  return it == below_.end() ? none : it->second;
}

std::map<std::string, Isometry3d> LinkTree::poses(const JointValues& q) const {
  std::map<std::string, Isometry3d> out;
  const std::vector<double> zero(3, 0.0);
  std::function<void(const std::string&, const Isometry3d&)> visit = [&](const std::string& link, const Isometry3d& T) {
    out[link] = T;
    for (const JointSpec* j : below(link)) {
      const auto it = q.find(j->name);
      const double* values = (it == q.end() ? zero : it->second).data();
      const Isometry3d J_J = j->type == "floating" ? Isometry3d::Identity()
                                                   : jointTypeInfo(j->type).relativePose(values, j->params);
      visit(j->child, T * j->P_J * J_J * j->C_J.inverse());
    }
  };
  visit(root_, Isometry3d::Identity());
  return out;
}

}  // namespace urdf_input
}  // namespace mechanism_sim
