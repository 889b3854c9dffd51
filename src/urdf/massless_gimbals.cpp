#include "massless_gimbals.h"

#include "couplings.h"

#include <cmath>
#include <set>

namespace mechanism_sim {
namespace urdf_input {
namespace {

// Axes perpendicular to this (|cos| of their angle): a file's rounded rpy leaves ~1e-16.
constexpr double kPerpendicular = 1e-9;

// No mass (RigidBodies drops a mass-0 link's inertia: such a link moves no mass).
bool massless(const urdf::ModelInterface& urdf, const std::string& link) {
  const urdf::LinkConstSharedPtr l = urdf.getLink(link);
  return l && (!l->inertial || l->inertial->mass == 0.0);
}

// The one tree joint below `link`, or nullptr if there are none or several.
JointSpec* onlyJointBelow(std::vector<JointSpec>& tree, const std::string& link) {
  JointSpec* below = nullptr;
  for (JointSpec& s : tree)
    if (s.parent == link) {
      if (below) return nullptr;
      below = &s;
    }
  return below;
}

bool freeRevolute(const JointSpec& s) {
  return s.type == "revolute" && !(s.lower < s.upper) && s.damping == 0.0 && s.friction == 0.0 && s.mimic.empty();
}

// Joint names and link names something other than the tree names (a file's elements, the
// options): a chain holding any of them stays as written. A dof is named as its joint when
// the joint has one ("J1"); "J0.x" names the ball a chain becomes, and keeps it.
struct Named {
  std::set<std::string> joints, links;
  void dof(const std::string& name) { joints.insert(name); }
};

Named namedElsewhere(const JointSpecs& specs, const Extension& ext, const Transmissions& transmissions,
                     const LoadOptions& options) {
  Named n;
  for (const JointSpec& s : specs.tree)
    if (!s.mimic.empty()) n.joints.insert(s.mimic);
  for (const JointSpec& s : specs.loops) n.links.insert(s.parent), n.links.insert(s.child);
  for (const ExtJoint& e : ext.joints)
    if (!e.loop) n.joints.insert(e.name);
  for (const ExtDrive& d : ext.drives) n.dof(d.dof);
  for (const ExtInitial& i : ext.initial) n.dof(i.dof);
  for (const ExtSpring& s : ext.springs) n.links.insert(s.link1), n.links.insert(s.link2);
  for (const ExtCoupling& c : ext.couplings) {
    (c.predecessor_is_link ? n.links : n.joints).insert(c.predecessor);
    (c.successor_is_link ? n.links : n.joints).insert(c.successor);
  }
  for (const ExtLinearCoupling& c : ext.linear_couplings)
    for (const auto& t : c.terms) n.joints.insert(t.joint);
  for (const std::string& a : ext.actuated) n.joints.insert(a);
  for (const TransmissionSpec& t : transmissions.simulated) n.joints.insert(t.joints.begin(), t.joints.end());
  for (const auto& p : options.positions) n.dof(p.first);
  for (const auto& v : options.velocities) n.dof(v.first);
  for (const auto& d : options.drives) n.dof(d.first);
  return n;
}

}  // namespace

MergedGimbals mergeMasslessGimbals(JointSpecs* specs, const urdf::ModelInterface& urdf, const Extension& ext,
                                   const Transmissions& transmissions, const LoadOptions& options) {
  MergedGimbals out;
  bool has_mass = false;
  for (const auto& l : urdf.links_) has_mass = has_mass || (l.second->inertial && l.second->inertial->mass > 0.0);
  if (!has_mass) return out;
  const Named named = namedElsewhere(*specs, ext, transmissions, options);
  auto untouched = [&](const JointSpec& s) { return freeRevolute(s) && !named.joints.count(s.name); };
  auto bare = [&](const std::string& link) { return massless(urdf, link) && !named.links.count(link); };
  std::string merged;
  for (JointSpec& j0 : specs->tree) {
    if (!untouched(j0) || !bare(j0.child)) continue;
    JointSpec* j1 = onlyJointBelow(specs->tree, j0.child);
    if (!j1 || !untouched(*j1) || !bare(j1->child)) continue;
    JointSpec* j2 = onlyJointBelow(specs->tree, j1->child);
    if (!j2 || !untouched(*j2)) continue;
    // the axes meet at J0's origin: J1's and J2's origins are their parents' frames (a tree
    // joint's child frame is its joint frame), to round-off of the chain's own placement
    const double at = 1e-12 + 1e-9 * j0.P_J.translation().norm();
    if (j1->P_J.translation().norm() > at || j2->P_J.translation().norm() > at) continue;
    // each axis perpendicular to the next, in the link between them (z is a joint's axis)
    const Vector3d a0 = j0.C_J.linear().col(2), a1_in_l1 = j1->P_J.linear().col(2);
    const Vector3d a1_in_l2 = j1->C_J.linear().col(2), a2 = j2->P_J.linear().col(2);
    if (std::fabs(a0.dot(a1_in_l1)) > kPerpendicular || std::fabs(a1_in_l2.dot(a2)) > kPerpendicular) continue;
    out.chains.push_back(GimbalChain{{j0, *j1, *j2}});
    // J0's joint frame stays where it is on both sides: at the ball's zero the child sits
    // where the chain's zero put it, and J1, J2 fixed at zero weld the links as it did
    j0.type = "spherical";
    j0.effort = j0.velocity = 0.0;
    for (JointSpec* j : {j1, j2}) {
      j->type = "fixed";
      j->effort = j->velocity = 0.0;
    }
    merged += (merged.empty() ? "'" : ", '") + j0.name + "' (" + j1->name + ", " + j2->name + ")";
  }
  if (merged.empty()) return out;
  out.note = "balls written as three revolute joints through links without mass are simulated as spherical joints, "
             "the same motion without the gimbal's lock, and reported by the three joints' angles: " +
             merged;
  return out;
}

}  // namespace urdf_input
}  // namespace mechanism_sim
