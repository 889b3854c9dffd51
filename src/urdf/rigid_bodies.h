// Links joined by fixed tree joints move as one rigid body. Each group of links becomes one
// body of the core: its reference point is the group's centre of mass, its axes are those
// of the group's first link (the one nearest the root), and its mass properties combine
// the links' <inertial>s about that point. The root link's group is ground. Internal to
// the loader.
#pragma once
#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <urdf_model/model.h>

#include "joint_specs.h"

namespace mechanism_sim {
namespace urdf_input {

struct RigidGroup {
  std::string first_link;                           // nearest the root (names the body)
  double mass = 0.0;
  Matrix3d Jp = Matrix3d::Zero();                   // about the centre of mass, body axes
  Isometry3d link_T_body = Isometry3d::Identity();  // body frame in the first link's frame
  // The body's own size: the largest distance from its centre of mass to its links' frames,
  // the joints on them and their masses. mass extent^2 is the inertia scale its moments are
  // judged against (inertiaFault): a point mass at distance L from its joint turns with
  // m L^2 about it, so round-off in its own moments (a parallel-axis sum leaves -5e-20
  // kg m^2) is not a fault.
  double extent = 0.0;
  double inertiaScale() const { return std::max(Jp.cwiseAbs().maxCoeff(), mass * extent * extent); }
};

// A link's <inertia> as a matrix (about its centre of mass, in its <inertial> frame).
Matrix3d inertiaOf(const urdf::Inertial& in);

class RigidBodies {
 public:
  RigidBodies(const LinkTree& tree, const urdf::ModelInterface& urdf);
  // Groups in depth-first order from the root along the file's joint order; [0] is ground.
  const std::vector<RigidGroup>& groups() const { return groups_; }
  int groupOf(const std::string& link) const { return group_of_.at(link); }
  // A link's pose in its group's body frame.
  const Isometry3d& bodyTLink(const std::string& link) const { return body_T_link_.at(link); }
  // Moving links whose <inertial> has mass 0 and a non-zero inertia: the inertia is dropped
  // (doc/robots.md "Conventions, and what other tools do": a body without mass has no
  // rotational inertia; MuJoCo drops it too).
  const std::vector<std::string>& massless() const { return massless_; }

 private:
  std::vector<RigidGroup> groups_;
  std::map<std::string, int> group_of_;
  std::map<std::string, Isometry3d> body_T_link_;
  std::vector<std::string> massless_;
};

}  // namespace urdf_input
}  // namespace mechanism_sim
