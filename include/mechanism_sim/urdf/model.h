// A URDF mechanism for the core: loaded with urdfdom, plus the mechanism_sim extension
// and Gazebo <gazebo><joint> loop closures (README "Model format"). ROS-free.
#pragma once
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "mechanism_sim/core/mechanism.h"

namespace mechanism_sim {

// A file that cannot be simulated: "FILE:LINE: element 'name': what is wrong".
class LoadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct LoadOptions {
  // Initial positions / velocities by degree-of-freedom name ("joint" or "joint.dof"),
  // overriding the file's <mechanism_sim:initial>.
  std::vector<std::pair<std::string, double>> positions, velocities;
  std::string integrator;  // empty: the core's default
};

// One degree of freedom of a joint, tree or loop closure.
struct Dof {
  std::string name;       // "joint" for one-dof joints, "joint.rotation" etc. otherwise
  std::string joint;      // the joint's name
  int joint_index = -1;   // Mechanism joint index
  int k = 0;              // coordinate of that joint
  double effort_limit = 0.0, velocity_limit = 0.0;  // 0: none
};

struct Link {
  std::string name;
  int body = 0;                                          // Mechanism body (0: ground)
  Eigen::Isometry3d body_T_link = Eigen::Isometry3d::Identity();
};

// A URDF tree joint, as tf publishes it (parent link -> child link).
struct TreeJoint {
  std::string name, parent, child;
  bool fixed = false;
};

class MechanismModel {
 public:
  Mechanism& mechanism() { return *mechanism_; }
  const Mechanism& mechanism() const { return *mechanism_; }
  const std::string& name() const { return name_; }
  const std::string& rootLink() const { return root_link_; }
  const std::vector<Dof>& dofs() const { return dofs_; }
  const std::vector<Link>& links() const { return links_; }
  const std::vector<TreeJoint>& treeJoints() const { return tree_; }
  int dofIndex(const std::string& name) const;
  int linkIndex(const std::string& name) const;
  const AssemblyReport& assembly() const { return assembly_; }

  // World pose of a link in the current state.
  Eigen::Isometry3d linkPose(int link) const;
  double position(int dof) const;
  double velocity(int dof) const;
  double effort(int dof) const;

  // Commanded effort along a dof, clamped to its effort limit; a velocity limit cuts the
  // command while it would drive the joint faster than the limit. Throws on a bad value.
  void setEffort(int dof, double tau);
  double commandedEffort(int dof) const { return command_[dof]; }
  void step(double h);
  void reset();

 private:
  friend class ModelBuilder;
  std::unique_ptr<Mechanism> mechanism_;
  std::string name_, root_link_;
  std::vector<Dof> dofs_;
  std::vector<Link> links_;
  std::vector<TreeJoint> tree_;
  std::vector<double> command_;
  AssemblyReport assembly_;
  Mechanism::Snapshot initial_;
};

// Loads, builds and assembles. Throws LoadError naming the file, element and problem.
std::unique_ptr<MechanismModel> loadModelFile(const std::string& path, const LoadOptions& options = {});
std::unique_ptr<MechanismModel> loadModelString(const std::string& xml, const std::string& source,
                                                const LoadOptions& options = {});

}  // namespace mechanism_sim
