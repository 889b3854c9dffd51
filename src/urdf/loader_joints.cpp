// The loader's core joints, couplers, transmissions, drives and springs (model_builder.h).
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include "mechanism_sim/core/kinematic.h"
#include "mechanism_sim/core/model/inertia.h"
#include "model_builder.h"

namespace mechanism_sim {

void ModelBuilder::addJoint(const JointSpec& s, const RigidBodies& bodies, bool tree) {
  if (s.type == "floating" || (tree && s.type == "fixed")) return;
  const int bi = bodyOf(bodies, s.parent), bj = bodyOf(bodies, s.child);
  if (bi == bj) fail(s.element, "joins links '" + s.parent + "' and '" + s.child + "' that are rigidly connected");
  std::unique_ptr<Joint> joint;
  try {
    joint = makeJoint(s.type, s.name, bi, frameOn(bodies, s.parent, s.P_J), bj, frameOn(bodies, s.child, s.C_J),
                      s.params);
  } catch (const ModelError& e) {  // an unknown type, a bad parameter
    fail(s.element, e.what());
  }
  const int index = mech().addJoint(std::move(joint));
  joint_index_[s.name] = index;
  model_->reaction_frames_.push_back(bodies.bodyTLink(s.child) * s.C_U);
  if (!tree)
    model_->loops_.push_back(LoopJoint{s.name, s.type, model_->linkIndex(s.parent), model_->linkIndex(s.child),
                                       s.P_J.translation(), s.C_J.translation()});
  const int dofs = static_cast<int>(dofNames(s).size());
  for (int k = 0; k < dofs; ++k) {
    Dof d;
    d.joint = s.name;
    d.name = dofName(s, k);
    d.joint_index = index;
    d.k = k;
    d.effort_limit = s.effort;
    d.velocity_limit = s.velocity;
    model_->dofs_.push_back(d);
    // a kinematic model has no forces: its joints' damping and friction do nothing
    if (s.damping > 0 && !kinematic_) mech().setJointDamping(index, k, s.damping);
    if (s.friction > 0 && !kinematic_) mech().setJointFriction(index, k, s.friction);
  }
  if (dofs == 1 && s.upper > s.lower) mech().setJointLimits(index, 0, s.lower, s.upper);
  if (s.sdf_no_limit) limit_notes_.push_back("joint '" + s.name + "': limits [-1e16, 1e16] (SDF's 'no limit') read as none");
}

void ModelBuilder::addGimbals(const std::vector<GimbalChain>& chains) {
  for (const GimbalChain& c : chains) {
    const JointSpec &j0 = c.joints[0], &j1 = c.joints[1], &j2 = c.joints[2];
    Gimbal g;
    g.joint = joint_index_.at(j0.name);
    // the axes in J0's joint frame (z) through the chain's zero pose, whose joint frames
    // share their origin (massless_gimbals.h)
    const Isometry3d A = j0.C_J.inverse() * j1.P_J, B = A * j1.C_J.inverse() * j2.P_J;
    g.axes = DavenportAxes(Eigen::Vector3d::UnitZ(), A.linear().col(2), B.linear().col(2));
    g.parent_link = model_->linkIndex(j0.parent);
    g.link1 = model_->linkIndex(j0.child);
    g.link2 = model_->linkIndex(j1.child);
    g.child_link = model_->linkIndex(j2.child);
    g.P_J = {j0.P_J, j1.P_J};
    g.C_J = {j0.C_J, j1.C_J};
    const int index = static_cast<int>(model_->gimbals_.size());
    model_->gimbals_.push_back(g);
    for (Dof& d : model_->dofs_)
      if (d.joint_index == g.joint) {
        d.gimbal = index;
        d.actuated = false;
        d.name = d.joint = c.joints[d.k].name;
      }
    for (TreeJoint& t : model_->tree_)
      if (t.name == j1.name || t.name == j2.name) t.fixed = false;
  }
  model_->gimbal_angles_.assign(model_->gimbals_.size(), {Angles3{0.0, 0.0, 0.0}, Eigen::Vector3d::Zero()});
}

void ModelBuilder::markPassive(const Extension& ext) {
  if (ext.actuated.empty()) return;
  const std::set<std::string> actuated(ext.actuated.begin(), ext.actuated.end());
  for (Dof& d : model_->dofs_) d.actuated = actuated.count(d.joint) > 0;
}

void ModelBuilder::addMimic(const JointSpec& s, const JointSpecs& specs) {
  if (s.mimic.empty()) return;
  if (s.type == "fixed") {  // no coordinate to couple; joint_state_publisher ignores it too
    limit_notes_.push_back("joint '" + s.name + "' is fixed: its <mimic> of '" + s.mimic + "' is ignored");
    return;
  }
  const auto a = joint_index_.find(s.name), b = joint_index_.find(s.mimic);
  for (const JointSpec& leader : specs.tree)
    if (leader.name == s.mimic && leader.type == "fixed")
      fail(s.element, "mimics '" + s.mimic + "', a fixed joint, which has no coordinate to follow: make '" +
                          s.name + "' fixed too (turned by its offset), or '" + s.mimic + "' movable");
  if (a == joint_index_.end() || b == joint_index_.end() || mech().joint(a->second).dof() != 1 ||
      mech().joint(b->second).dof() != 1)
    fail(s.element, "mimic needs two one-dof joints ('" + s.name + "', '" + s.mimic + "')");
  mech().addCoupler(s.name + " mimic", a->second, 0, b->second, 0, s.mimic_multiplier, s.mimic_offset);
  followers_.insert(s.name);
}

void ModelBuilder::addCoupling(const Coupling& c) {
  const auto a = joint_index_.find(c.follower), b = joint_index_.find(c.leader);
  if (a == joint_index_.end() || b == joint_index_.end() || mech().joint(a->second).dof() != 1 ||
      mech().joint(b->second).dof() != 1)
    fail(c.element, "a coupling needs two one-dof joints ('" + c.leader + "', '" + c.follower + "')");
  mech().addCoupler(c.name, a->second, 0, b->second, 0, c.ratio, 0.0);
  followers_.insert(c.follower);
}

void ModelBuilder::addTransmissions(const Transmissions& read) {
  std::string no_reduction;  // transmissions without a reduction, listed in one note
  if (read.repeated)
    limit_notes_.push_back(std::to_string(read.repeated) + " <transmission>s repeat another exactly (one per "
                           "hardware interface): each is read once");
  // A reduced model locks joints by making them fixed, or leaves them out, and keeps their
  // <transmission>s: those drive nothing and are not simulated, listed in one note each way
  // (ros_control's loader skips a transmission whose joint the URDF lacks, with an error).
  std::string on_fixed, on_missing;
  for (const TransmissionSpec& s : read.simulated) {
    bool fixed = false, missing = false;
    for (const std::string& joint : s.joints) {
      bool found = false;
      for (const TreeJoint& t : model_->tree_)
        if (t.name == joint) found = true, fixed = fixed || t.fixed;
      if (!found && joint_index_.find(joint) == joint_index_.end()) missing = true;
    }
    if (fixed || missing) {
      std::string& list = missing ? on_missing : on_fixed;
      list += (list.empty() ? "'" : ", '") + s.map.name + "'";
      continue;
    }
    TransmissionInfo info;
    info.map = s.map;
    const Eigen::MatrixXd E = s.map.velocityMap();
    info.E.topLeftCorner(E.rows(), E.cols()) = E;
    info.E_inv_T.topLeftCorner(E.rows(), E.cols()) = E.inverse().transpose();
    if (!s.note.empty()) no_reduction += (no_reduction.empty() ? "'" : ", '") + s.map.name + "'";
    RotorInertia rotor;
    rotor.name = s.map.name;
    for (const std::string& joint : s.joints) {
      const int d = model_->dofIndex(joint);
      const auto index = joint_index_.find(joint);
      if (index == joint_index_.end() || d < 0 || mech().joint(index->second).dof() != 1)
        fail(s.element, "joint '" + joint + "' is not a movable one-dof joint of the model" +
                            (index == joint_index_.end() && d < 0 ? " (no such joint)" : ""));
      info.dofs.push_back(d);
      rotor.coords.push_back({index->second, 0});
    }
    const int n = static_cast<int>(s.actuators.size());
    Eigen::VectorXd J(n), c(n), f(n);
    for (int k = 0; k < n; ++k) {
      Actuator a;
      a.name = s.actuators[k];
      a.transmission = static_cast<int>(model_->transmissions_.size());
      a.k = k;
      a.ratings = read.actuators.at(a.name).ratings;
      J[k] = a.ratings.rotor_inertia, c[k] = a.ratings.damping, f[k] = a.ratings.friction;
      info.actuators.push_back(static_cast<int>(model_->actuators_.size()));
      model_->actuators_.push_back(a);
    }
    const Eigen::MatrixXd B = s.map.reflectedInertia(J);
    rotor.B.topLeftCorner(B.rows(), B.cols()) = B;
    // The motors' damping acts on the motion through the transmission: D = E^T diag(c_m) E
    // (N^2 c_m for a simple one, as the rotor's inertia). Its diagonal joins the joints' own
    // damping, its coupling term (a differential's) stays with the rotor (transmission.h).
    const Eigen::MatrixXd D = E.transpose() * c.asDiagonal() * E;
    if (n == 2) rotor.damping_coupling = D(0, 1);
    // The motors' Coulomb friction acts on theta = E (q - q_0): where a motor turns one joint
    // alone (a simple transmission: theta = n q) it is that joint's friction of bound |n| f_m
    // (an effort f_m on theta is n f_m on q); a motor that turns two joints at once (a
    // differential's) has it on its own row, sum_i E_ki q_i (System::sum_friction).
    Eigen::Vector2d motor_friction = Eigen::Vector2d::Zero();  // per joint of the transmission
    std::vector<SumFriction> on_sums;
    for (int k = 0; k < n; ++k) {
      if (!(f[k] > 0)) continue;
      int on = -1;
      for (int i = 0; i < n; ++i)
        if (E(k, i) != 0.0) on = on < 0 ? i : n;
      if (on >= 0 && on < n) {
        motor_friction[on] += std::fabs(E(k, on)) * f[k];
        continue;
      }
      SumFriction F;
      F.name = s.actuators[k];
      F.f = f[k];
      for (int i = 0; i < n; ++i)
        if (E(k, i) != 0.0) F.terms.push_back({rotor.coords[i].first, rotor.coords[i].second, E(k, i)});
      on_sums.push_back(F);
    }
    // a kinematic model has no forces: its rotors and motors' losses do nothing (as joint damping)
    if (!kinematic_) {
      for (size_t i = 0; i < rotor.coords.size(); ++i) {
        const auto [joint, k] = rotor.coords[i];
        if (D(i, i) > 0.0) mech().setJointDamping(joint, k, mech().system().damping[joint][k] + D(i, i));
        if (motor_friction[i] > 0.0)
          mech().setJointFriction(joint, k, mech().system().friction[joint][k] + motor_friction[i]);
      }
      if (J.maxCoeff() > 0.0 || rotor.damping_coupling != 0.0) mech().addRotorInertia(rotor);
      for (const SumFriction& F : on_sums) mech().addSumFriction(F);
    }
    model_->transmissions_.push_back(info);
  }
  if (!on_missing.empty())
    limit_notes_.push_back("transmissions of joints the file does not have drive nothing and are not simulated: " +
                           on_missing);
  if (!on_fixed.empty())
    limit_notes_.push_back("transmissions of fixed joints drive nothing and are not simulated: " + on_fixed);
  if (!no_reduction.empty())
    limit_notes_.push_back("transmissions without a <mechanicalReduction> take 1, as gazebo_ros_control reads them: " +
                           no_reduction);
}

void ModelBuilder::addDrives(const JointSpecs& specs, const Extension& ext, const InitialValues& initial) {
  std::vector<std::pair<Coordinate, ExtDrive>> drives;
  auto put = [&](const Coordinate& at, const ExtDrive& d) {
    for (auto& existing : drives)
      if (existing.first == at) {
        if (d.element) fail(d.element, "dof '" + d.dof + "' is already driven");
        existing.second = d;  // the command line's drive replaces the file's
        return;
      }
    drives.push_back({at, d});
  };
  for (const ExtDrive& d : ext.drives) put(locate(specs, d.dof, d.element), d);
  for (const auto& o : options_.drives) {
    if (!std::isfinite(o.second)) fail("drive velocity of '" + o.first + "' is not finite");
    ExtDrive d;
    d.dof = o.first;
    d.velocity = o.second;
    d.profile = "velocity";
    put(locate(specs, o.first, nullptr), d);
  }
  for (const auto& entry : drives) {  // (no structured binding: lambdas below capture these)
    const Coordinate& at = entry.first;
    const ExtDrive& d = entry.second;
    auto refuse = [&](const std::string& what) {
      if (d.element) fail(d.element, what);  // both throw
      fail("drive of '" + d.dof + "': " + what);
    };
    const auto index = joint_index_.find(at.first);
    if (index == joint_index_.end()) {
      refuse("joint '" + at.first + "' has no coordinate to drive");
      continue;  // not reached
    }
    if (!ext.actuated.empty() && std::find(ext.actuated.begin(), ext.actuated.end(), at.first) == ext.actuated.end())
      refuse("dof '" + d.dof + "' is passive: only the actuated joints (" + ext.actuated_source +
             ") take a drive; drive one of those or add this joint to them");
    for (const JointSpec& s : specs.tree)
      if (!s.mimic.empty() && (s.name == at.first || s.mimic == at.first))
        refuse("dof '" + d.dof + "' is coupled by mimic ('" + s.name + "' mimics '" + s.mimic +
               "'); drive the joint it follows, or drop the mimic");
    // a command-line drive overrides the file's initial velocity of its dof; any other
    // pair contradicts itself
    if (initial.velocities.count(at) && (d.element || !initial.velocity_from_file.at(at)))
      refuse("dof '" + d.dof + "' is driven: its initial velocity is the drive's; remove the initial velocity");
    if (d.profile != "velocity" && initial.positions.count(at))
      refuse("dof '" + d.dof + "' follows a " + d.profile + " profile, which sets its position; remove the initial position");
    std::string error;
    try {
      DriveProfile profile;
      double q0 = 0.0;
      if (d.profile == "velocity") {
        profile = DriveProfile::velocity(d.velocity);
        const auto p = initial.positions.find(at);
        q0 = p != initial.positions.end() ? p->second : placedCoordinate(index->second, at.second);
      } else {
        profile = d.profile == "harmonic" ? DriveProfile::harmonic(d.offset, d.amplitude, d.frequency, d.phase)
                                          : DriveProfile::spline(d.t, d.position);
      }
      const int drive = mech().addDrive(index->second, at.second, profile, q0);
      for (Dof& dof : model_->dofs_)
        if (dof.joint_index == index->second && dof.k == at.second) dof.drive = drive;
    } catch (const UsageError& e) {  // a profile's points
      error = e.what();
    } catch (const ModelError& e) {
      error = e.what();
    }
    if (!error.empty()) refuse(error);
  }
}

void ModelBuilder::addSprings(const Extension& ext, const RigidBodies& bodies, const std::map<std::string, Isometry3d>& placed,
                const urdf::ModelInterface& urdf) {
  for (const ExtSpring& sp : ext.springs) {
    for (const std::string* l : {&sp.link1, &sp.link2})
      if (!urdf.getLink(*l)) fail(sp.element, "link '" + *l + "' does not exist");
    SpringDamper s;
    s.name = sp.name;
    s.body_i = bodyOf(bodies, sp.link1);
    s.body_j = bodyOf(bodies, sp.link2);
    s.sp_i = bodies.bodyTLink(sp.link1) * sp.p1;
    s.sp_j = bodies.bodyTLink(sp.link2) * sp.p2;
    s.k = sp.k, s.c = sp.c, s.f_act = sp.force;
    s.L0 = sp.rest_length ? *sp.rest_length : ((placed.at(sp.link2) * sp.p2) - (placed.at(sp.link1) * sp.p1)).norm();
    mech().addSpring(s);
  }
}

}  // namespace mechanism_sim
