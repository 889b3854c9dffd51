// Reading a URDF file's XML with line numbers: validation of the standard elements and
// the mechanism_sim extension / Gazebo loop joints. Internal to the loader.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <tinyxml2.h>

#include "couplings.h"

namespace mechanism_sim {
namespace urdf_input {

// Text quoted from a file, made one line: control characters escaped (\n, \xNN) and at most
// `limit` characters kept (then "...").
std::string oneLine(const std::string& text, size_t limit = 200);

using Eigen::Isometry3d;
using Eigen::Vector3d;

// Error location and formatting: "FILE:LINE: element 'name': what".
struct XmlReader {
  std::string file;
  [[noreturn]] void fail(const tinyxml2::XMLElement* e, const std::string& what) const;
  std::string describe(const tinyxml2::XMLElement* e) const;
  // Attribute as a number; required or default. Rejects NaN, infinity and absurd sizes.
  double number(const tinyxml2::XMLElement* e, const char* attr, std::optional<double> def,
                double absurd = 1e6) const;
  std::vector<double> numbers(const tinyxml2::XMLElement* e, const char* attr, size_t count,
                              double absurd = 1e6) const;
  double parseNumber(const tinyxml2::XMLElement* e, const char* attr, const std::string& token,
                     const char* whole, double absurd) const;
  Vector3d vec3(const tinyxml2::XMLElement* e, const char* attr, const Vector3d& def,
                double absurd = 1e6) const;
  // <origin xyz rpy> child of e (identity if absent).
  Isometry3d origin(const tinyxml2::XMLElement* e, const char* child = "origin") const;
  // Non-zero finite direction from <child xyz>, normalized.
  Vector3d direction(const tinyxml2::XMLElement* e, const char* child, const Vector3d& def) const;
  std::string text(const tinyxml2::XMLElement* e, const char* child) const;  // required child text
  // Only these attributes are allowed on e.
  void onlyAttributes(const tinyxml2::XMLElement* e, std::initializer_list<const char*> allowed) const;
};

Isometry3d poseFromXyzRpy(const Vector3d& xyz, const Vector3d& rpy);

struct ExtJoint {
  const tinyxml2::XMLElement* element = nullptr;
  std::string name, type;
  bool loop = false;          // a loop closure between two links (else: overrides a URDF joint)
  bool sdf = false;           // from <gazebo><joint>: SDF pose and axis conventions
  bool axis_in_model = false; // SDF use_parent_model_frame / expressed_in="__model__"
  // SDF frames named by the joint's <pose relative_to> and its axes' expressed_in (a link
  // of the model; "" for the default: the child link, the joint frame)
  std::string pose_relative_to, axis_expressed_in;
  std::string parent, child;
  Isometry3d origin = Isometry3d::Identity();        // joint frame in the parent link (extension)
  Isometry3d child_origin = Isometry3d::Identity();  // joint frame in the child link
  Vector3d axis = Vector3d::UnitZ(), axis2 = Vector3d::UnitY();
  bool has_axis2 = false;
  // Overriding a URDF joint's type: axis and axis2 replace the URDF axis (an Extended-URDF
  // CARDAN joint's x and y); else the URDF axis stays unless the element gives <axis>.
  bool axes_given = false;
  double alpha = 0.0;  // screw lead per radian
  double damping = 0.0, friction = 0.0;
  // The child side's rotation is the one that makes the two frames coincide with every
  // tree joint at zero (Dojo's <loop_joint>); child_origin then gives only the translation.
  bool child_rotation_from_zero_pose = false;
};

// A URDF+ <coupling>: the successor's rate is ratio times the predecessor's. Each side
// names a joint, or a link meaning the joint above it (loop_dialects.h).
struct ExtCoupling {
  const tinyxml2::XMLElement* element = nullptr;
  std::string name;
  std::string predecessor, successor;  // joint names, or link names if *_is_link
  bool predecessor_is_link = false, successor_is_link = false;
  double ratio = 1.0;
};

struct ExtSpring {
  const tinyxml2::XMLElement* element = nullptr;
  std::string name, link1, link2;
  Vector3d p1 = Vector3d::Zero(), p2 = Vector3d::Zero();
  double k = 0, c = 0, force = 0;
  std::optional<double> rest_length;
};

struct ExtInitial {
  const tinyxml2::XMLElement* element = nullptr;
  std::string dof;
  std::optional<double> position, velocity;
};

// <mechanism_sim:drive joint dof? (velocity | profile="harmonic" offset amplitude
// frequency phase | profile="spline" with <point t position/>)>
struct ExtDrive {
  const tinyxml2::XMLElement* element = nullptr;
  std::string dof;  // "joint" or "joint.dof"
  std::string profile;  // "velocity", "harmonic", "spline"
  double velocity = 0, offset = 0, amplitude = 0, frequency = 0, phase = 0;
  std::vector<double> t, position;
};

struct Extension {
  std::vector<ExtJoint> joints;
  std::vector<ExtDrive> drives;
  std::vector<ExtSpring> springs;
  std::vector<ExtInitial> initial;
  std::optional<Vector3d> gravity;
  std::vector<ExtCoupling> couplings;  // URDF+ <coupling>
  std::vector<ExtLinearCoupling> linear_couplings;  // <mechanism_sim:coupling> (couplings.h)
  std::vector<std::string> notes;      // what was read but is not simulated (MechanismModel::notes)
  // The actuated joints when a file names them (Extended-URDF name_mot): every other dof is
  // passive (no effort command, no drive). Empty: every dof is actuated.
  std::vector<std::string> actuated;
  std::string actuated_source;  // where they are named, for messages
};

// What makes an inertia matrix (about a centre of mass) unphysical, or "" if it is physical:
// a negative principal moment, or one larger than the sum of the other two, by more than
// 1e-9 of `scale`: the body's own inertia scale (RigidGroup::inertiaScale, at least |J|),
// so that round-off in the moments of a point mass held away from its joint passes.
std::string inertiaFault(const Eigen::Matrix3d& J, double scale = 0.0);

// Checks the standard URDF elements the loader relies on, with line numbers. Returns the
// root links (no parent joint) in file order: one, or several (the loader floats the extra).
std::vector<std::string> validateStandard(const tinyxml2::XMLElement* robot, const XmlReader& reader);
// Reads <mechanism_sim:*> elements, <gazebo><joint> loop closures and the other tools'
// loop dialects (loop_dialects.h).
Extension readExtension(const tinyxml2::XMLElement* robot, const XmlReader& reader);

}  // namespace urdf_input
}  // namespace mechanism_sim
