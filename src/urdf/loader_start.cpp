// The loader's start: joints placed inside their limits, gravity and the integrator, the
// assembly and the degrees of freedom held (model_builder.h).
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include "mechanism_sim/core/kinematic.h"
#include "mechanism_sim/core/model/inertia.h"
#include "mechanism_sim/core/model/math.h"
#include "model_builder.h"

namespace mechanism_sim {

void ModelBuilder::startInsideLimits(const JointSpecs& specs, const Extension& ext, InitialValues& in) {
  std::set<std::string> driven;
  for (const ExtDrive& d : ext.drives) driven.insert(d.dof.substr(0, d.dof.find('.')));
  for (const auto& d : options_.drives) driven.insert(d.first.substr(0, d.first.find('.')));
  std::map<std::string, const JointSpec*> by_name;
  for (const JointSpec& s : specs.tree) by_name[s.name] = &s;
  auto limited = [](const JointSpec& s) { return s.upper > s.lower && dofNames(s).size() == 1; };
  auto given = [&](const std::string& joint) -> std::optional<double> {
    for (const auto* m : {&in.positions, &in.limit_starts}) {
      const auto it = m->find({joint, 0});
      if (it != m->end()) return it->second;
    }
    return std::nullopt;
  };
  auto note = [&](const JointSpec& s, double zero, double start) {
    std::ostringstream os;
    os << "joint '" << s.name << "': its zero pose (" << zero << ") lies outside its limits [" << s.lower << ", "
       << s.upper << "]; it starts at " << start;
    limit_notes_.push_back(os.str());
  };
  // leaders and unrelated joints first, then mimic followers
  for (const JointSpec& s : specs.tree) {
    if (!s.mimic.empty() || !limited(s) || driven.count(s.name) || given(s.name)) continue;
    if (0.0 >= s.lower && 0.0 <= s.upper) continue;
    const double start = 0.0 < s.lower ? s.lower : s.upper;
    in.limit_starts[{s.name, 0}] = start;
    note(s, 0.0, start);
  }
  for (const JointSpec& s : specs.tree) {
    if (s.mimic.empty() || given(s.name)) continue;
    const auto leader = by_name.find(s.mimic);
    if (leader == by_name.end() || dofNames(*leader->second).size() != 1) continue;
    const double q_leader = given(s.mimic).value_or(0.0);
    double q = s.mimic_multiplier * q_leader + s.mimic_offset;
    if (limited(s) && (q < s.lower || q > s.upper) && s.mimic_multiplier != 0.0 && !driven.count(s.mimic) &&
        !in.positions.count({s.mimic, 0})) {
      const double target = q < s.lower ? s.lower : s.upper;
      const double q_new = (target - s.mimic_offset) / s.mimic_multiplier;
      const JointSpec& l = *leader->second;
      if (!limited(l) || (q_new >= l.lower && q_new <= l.upper)) {
        in.limit_starts[{s.mimic, 0}] = q_new;
        note(s, q, target);
        q = target;
      }
    }
    in.followers[{s.name, 0}] = q;
  }
}

double ModelBuilder::placedCoordinate(int joint, int k) {
  const Joint& j = mech().joint(joint);
  auto kin = [&](int b) {
    BodyKin kb;
    if (b != Mechanism::kGround) {
      kb.r = mech().body(b).r;
      kb.A_Oi = mech().body(b).p.normalized().toRotationMatrix();
    }
    return kb;
  };
  Row rows[kMaxJointDofs];
  j.coordinates(kin(j.bodyI()), kin(j.bodyJ()), j.initialTracked(), rows);
  return rows[k].Phi;
}

void ModelBuilder::setGravityAndIntegrator(const Extension& ext) {
  if (ext.gravity) mech().setGravity(*ext.gravity);
  IntegratorOptions io = mech().integrator();
  if (!options_.integrator.empty()) io.method = options_.integrator;
  // a URDF's mechanism runs in the formulation auto picks unless asked (doc/method.md,
  // "Formulations"); the core's own default stays the seed's absolute coordinates
  io.formulation = options_.formulation.empty() ? "auto" : options_.formulation;
  // a kinematic model runs in absolute coordinates: the joint formulation's tree has no
  // inertia to factor (holdFreeDofs)
  if (kinematic_ && io.formulation == "joint")
    fail("no moving body has mass, so the model runs kinematically, in the absolute formulation; drop "
         "formulation 'joint'");
  if (kinematic_) io.formulation = "absolute";
  try {
    mech().setIntegrator(io);
  } catch (const ModelError& e) {
    throw LoadError(e.what());
  }
}

void ModelBuilder::assemble(const InitialValues& initial) {
  if (kinematic_) holdFreeDofs(initial);
  std::vector<CoordinateTarget> positions, velocities;
  for (const auto& p : initial.positions) positions.push_back({joint_index_.at(p.first.first), p.first.second, p.second});
  for (const auto& v : initial.velocities) {
    const int joint = joint_index_.at(v.first.first);
    if (mech().driveOf(joint, v.first.second) < 0) velocities.push_back({joint, v.first.second, v.second});
  }
  std::vector<double> placed(model_->dofs_.size());
  for (size_t d = 0; d < placed.size(); ++d) {
    const Dof& dof = model_->dofs_[d];
    placed[d] = placedCoordinate(dof.joint_index, dof.k);
    if (dof.gimbal < 0) continue;
    // a gimbal's angles (MechanismModel::gimbalAngles) where its ball was placed
    Eigen::Vector3d rotation_vector;
    for (int k = 0; k < 3; ++k) rotation_vector(k) = placedCoordinate(dof.joint_index, k);
    const Eigen::Matrix3d R = expRotation(rotation_vector).toRotationMatrix();
    placed[d] = model_->gimbals_[dof.gimbal].axes.angles(R, {0.0, 0.0, 0.0})[dof.k];
  }
  try {
    mech().build();
    model_->assembly_ = mech().assemble(positions, velocities);
  } catch (const ModelError& e) {
    fail(e.what());
  }
  noteAssemblyMoves(placed);
  if (model_->assembly_.position_residual > 1e-9) {
    // (past assembly's own failure residual: dependent equations that disagree at the
    // file's precision, which assembly accepts)
    std::ostringstream os;
    os.precision(3);
    os << "the loops' dependent equations disagree by " << model_->assembly_.position_residual
       << " (relative) at the closest pose: the file's precision (axes or points that should meet miss by a "
          "rounding); the independent ones are held";
    model_->notes_.push_back(os.str());
  }
  model_->command_.assign(model_->dofs_.size(), 0.0);
  model_->initial_ = mech().snapshot();
}

void ModelBuilder::holdFreeDofs(const InitialValues& initial) {
  std::vector<int> order;
  std::set<std::string> tree(tree_joints_.begin(), tree_joints_.end());
  for (int pass = 0; pass < 3; ++pass)
    for (size_t d = 0; d < model_->dofs_.size(); ++d) {
      const Dof& dof = model_->dofs_[d];
      if (!tree.count(dof.joint)) continue;
      const bool given = initial.positions.count({dof.joint, dof.k}) > 0, follower = followers_.count(dof.joint) > 0;
      if ((pass == 0 && given) || (pass == 1 && !given && !follower) || (pass == 2 && !given && follower))
        order.push_back(static_cast<int>(d));
    }
  int held = 0, driven = 0, solved = 0;
  std::vector<std::pair<int, int>> candidates;
  std::vector<int> candidate_dof;
  for (const int d : order) {
    const Dof& dof = model_->dofs_[d];
    if (dof.drive >= 0) {
      ++driven;
      continue;
    }
    candidates.push_back({dof.joint_index, dof.k});
    candidate_dof.push_back(d);
  }
  std::vector<char> free;
  try {
    free = independentCoordinates(mech().system(), candidates);
  } catch (const ModelError&) {
    return;  // the model is invalid: build() names why
  }
  for (size_t i = 0; i < free.size(); ++i) {
    Dof& dof = model_->dofs_[candidate_dof[i]];
    if (!free[i]) {  // its motion follows from the loops, couplers and drives
      ++solved;
      continue;
    }
    dof.drive = mech().addDrive(dof.joint_index, dof.k, DriveProfile::velocity(0.0),
                                placedCoordinate(dof.joint_index, dof.k));
    ++held;
    if (initial.velocities.count({dof.joint, dof.k}))
      fail("dof '" + dof.name + "' is held (no moving body has mass, so the model runs kinematically): its initial "
           "velocity would be lost; drive it instead (--drive " + dof.name + "=VELOCITY)");
  }
  model_->kinematic_ = true;
  model_->notes_.push_back("kinematic: no moving body has mass; " + std::to_string(held) + " dofs held, " +
                           std::to_string(driven) + " driven, " + std::to_string(solved) +
                           " solved from the loops and couplers");
}

void ModelBuilder::noteAssemblyMoves(const std::vector<double>& placed) {
  std::ostringstream os;
  os.precision(4);
  int moved = 0;
  for (size_t d = 0; d < placed.size(); ++d) {
    const double now = model_->position(static_cast<int>(d));
    if (!(std::fabs(now - placed[d]) > 1e-6 * std::max(1.0, std::fabs(placed[d])))) continue;
    os << (moved++ ? ", " : "") << model_->dofs_[d].name << " " << placed[d] << " -> " << now;
  }
  if (moved)
    model_->notes_.push_back("assembly moved " + std::to_string(moved) + " of " + std::to_string(placed.size()) +
                             " dofs (the file's pose does not close its loops): " + os.str());
}

}  // namespace mechanism_sim
