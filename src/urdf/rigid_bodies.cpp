#include "rigid_bodies.h"

#include <functional>

namespace mechanism_sim {
namespace urdf_input {

Matrix3d inertiaOf(const urdf::Inertial& in) {
  Matrix3d I;
  I << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
  return I;
}

RigidBodies::RigidBodies(const LinkTree& tree, const urdf::ModelInterface& urdf) {
  // 1. Groups: a fixed joint keeps its child in the parent's group, any other starts a
  //    group. group_T_link: each link in the frame of its group's first link.
  std::map<std::string, Isometry3d> group_T_link;
  std::function<void(const std::string&, int, const Isometry3d&)> visit =
      [&](const std::string& link, int group, const Isometry3d& G_L) {
        group_of_[link] = group;
        group_T_link[link] = G_L;
        for (const JointSpec* j : tree.below(link)) {
          if (j->type == "fixed") {
            visit(j->child, group, G_L * j->P_J * j->C_J.inverse());
          } else {
            groups_.push_back(RigidGroup{j->child});
            visit(j->child, static_cast<int>(groups_.size()) - 1, Isometry3d::Identity());
          }
        }
      };
  groups_.push_back(RigidGroup{tree.root()});
  visit(tree.root(), 0, Isometry3d::Identity());

  // 2. Mass, centre of mass and inertia of each group (in its first link's frame), then
  //    the inertia about the centre of mass by the parallel axis theorem.
  const size_t n = groups_.size();
  std::vector<Vector3d> first(n, Vector3d::Zero());
  std::vector<std::vector<std::pair<double, std::pair<Vector3d, Matrix3d>>>> parts(n);
  for (const auto& entry : urdf.links_) {
    const urdf::Link& l = *entry.second;
    const int g = group_of_.at(l.name);
    if (!l.inertial || g == 0) continue;  // ground's links carry no mass that moves
    const Isometry3d G_I = group_T_link.at(l.name) * toEigen(l.inertial->origin);
    Matrix3d I = inertiaOf(*l.inertial);
    // A rotational inertia is mass times squared distance: without mass there is none. Real
    // files give frame links mass 0 with inertia 0.1 (a hand's frames): kept, that inertia
    // (of a 0.8 kg hand's order) turned an arm 0.7 rad away from MuJoCo in 1 s, which drops
    // it as pybullet does by default. Noted once per link (the loader says so).
    if (l.inertial->mass == 0.0 && !I.isZero(0.0)) {
      massless_.push_back(l.name);
      I.setZero();
    }
    parts[g].push_back({l.inertial->mass, {G_I.translation(), G_I.linear() * I * G_I.linear().transpose()}});
    groups_[g].mass += l.inertial->mass;
    first[g] += l.inertial->mass * G_I.translation();
  }
  for (size_t g = 1; g < n; ++g) {
    RigidGroup& b = groups_[g];
    const Vector3d c = b.mass > 0 ? Vector3d(first[g] / b.mass) : Vector3d::Zero();
    for (const auto& p : parts[g]) {
      const Vector3d d = p.second.first - c;
      b.Jp += p.second.second + p.first * (d.squaredNorm() * Matrix3d::Identity() - d * d.transpose());
    }
    b.Jp = 0.5 * (b.Jp + b.Jp.transpose());
    b.link_T_body.translation() = c;
    for (const auto& p : parts[g]) b.extent = std::max(b.extent, (p.second.first - c).norm());
  }
  for (const auto& entry : group_T_link) {
    RigidGroup& b = groups_[group_of_.at(entry.first)];
    const Vector3d c = b.link_T_body.translation();
    b.extent = std::max(b.extent, (entry.second.translation() - c).norm());
    for (const JointSpec* j : tree.below(entry.first))
      b.extent = std::max(b.extent, (entry.second * j->P_J.translation() - c).norm());
  }

  // 3. Each link in its body's frame.
  for (const auto& entry : group_T_link)
    body_T_link_[entry.first] = groups_[group_of_.at(entry.first)].link_T_body.inverse() * entry.second;
}

}  // namespace urdf_input
}  // namespace mechanism_sim
