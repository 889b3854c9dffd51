// The formulation choice (formulation.h).
#include "core/formulation.h"

#include "core/joint_space/joint_stepper.h"
#include "core/joint_space/tree.h"
#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/coupling.h"

namespace mechanism_sim {

Formulation chooseFormulation(const System& sys, Formulation asked, std::string* why) {
  if (asked == Formulation::kAbsolute) {
    if (why) *why = "absolute coordinates, as asked";
    return Formulation::kAbsolute;
  }
  const std::string unsupported = jointFormulationUnsupported(sys);
  if (asked == Formulation::kJoint) {
    if (!unsupported.empty())
      throw ModelError("the joint formulation cannot run this mechanism: " + unsupported + "; use formulation 'absolute'");
    if (why) *why = "joint coordinates, as asked";
    return Formulation::kJoint;
  }
  // The cost model (bench/RESULTS.md has the figures). On a tree with no equations besides
  // its joints' the joint formulation costs 2 to 5 times less a step. Limits and couplers on
  // tree coordinates are rows on q itself, solved sparsely (closure_solver.h: O(depth) a
  // row), or held by the recursions (TreeLink::tie). Drives, and couplers on spherical or
  // cut joints, go through their absolute equations: with one on every coordinate the joint
  // formulation costs more than the absolute one, so auto takes it while they are at most
  // one per 2 coordinates. Loops run in joint coordinates too: their closures cost less than
  // the absolute formulation a step, and the joint formulation converges through their
  // branches' flat passages, where the absolute one does not.
  int mapped = 0;  // always-on rows through the absolute equations
  int nv = 0;
  std::string loop;  // a joint that closes a loop, if any
  if (unsupported.empty()) {
    const TreeModel tree(sys);
    nv = tree.nv;
    if (!tree.cut_joints.empty()) loop = sys.joints[tree.cut_joints[0]]->name();
    auto onTree = [&](const Joint& J) {
      for (int j = 0; j < sys.numJoints(); ++j)
        if (&*sys.joints[j] == &J) {
          const int link = tree.joint_link[j];
          return link >= 0 && tree.links[link].quaternion < 0;
        }
      return false;
    };
    std::vector<char> tree_joint(sys.numConstraints(), 0);
    for (int c : sys.joint_constraint) tree_joint[c] = 1;
    for (int c = 0; c < sys.numConstraints(); ++c) {
      const Constraint& C = *sys.constraints[c];
      if (tree_joint[c] || C.limit() >= 0) continue;
      if (const auto* cc = dynamic_cast<const CoordinateCoupler*>(&C))
        if (onTree(cc->jointA()) && onTree(cc->jointB())) continue;
      if (const auto* lc = dynamic_cast<const LinearCoupling*>(&C)) {
        bool all = true;
        for (const CouplingTerm& t : lc->terms()) all = all && onTree(*t.joint);
        if (all) continue;
      }
      mapped += C.size();
    }
  }
  if (unsupported.empty() && 2 * mapped <= nv) {
    if (why)
      *why = !loop.empty()
                 ? "joint coordinates (auto: joint '" + loop +
                       "' closes a loop, a closure on the tree; drives at most one per 2 coordinates)"
             : mapped == 0 ? "joint coordinates (auto: a tree whose other equations are limits and couplers at most)"
                           : "joint coordinates (auto: a tree with few drives, at most one per 2 coordinates)";
    return Formulation::kJoint;
  }
  if (unsupported.empty()) {
    if (why) *why = "absolute coordinates (auto: more than one drive per 2 coordinates cost more as joint-space closures)";
    return Formulation::kAbsolute;
  }
  if (why) *why = "absolute coordinates (auto: " + unsupported + ")";
  return Formulation::kAbsolute;
}

}  // namespace mechanism_sim
