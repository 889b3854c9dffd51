// What the closures of a tree are (ClosureRows, loop_closure.h): every System constraint the
// tree does not hold, the rows taken directly on q, and the rows' layout. Built once; the
// evaluations and solves that read it are LoopClosures' (loop_closure.cpp and the files it
// names).
#include <algorithm>
#include <cmath>

#include "core/joint_space/loop_closure.h"
#include "mechanism_sim/core/model/couplers.h"
#include "mechanism_sim/core/model/coupling.h"

namespace mechanism_sim {

ClosureRows::ClosureRows(const TreeModel& model, const System& sys) {
  nv = model.nv;
  // Every constraint the tree does not hold, in System order: cut joints, couplers, drives,
  // limits (the layout's order, so sys_row ascends).
  std::vector<char> tree_joint(sys.numConstraints(), 0);
  for (int j = 0; j < sys.numJoints(); ++j)
    if (model.joint_link[j] >= 0) tree_joint[sys.joint_constraint[j]] = 1;
  for (int k : model.ties) tree_joint[model.links[k].tie_coupler] = 1;  // (couplers the tree holds)
  // A held slave's limit that its master's limit implies (q_s = r q_m + o within the
  // slave's bounds wherever q_m is within the master's: a parallel gripper's fingers with
  // the same limits) is left out: it could only ever bind together with the master's, as
  // a row dependent on it (the master's multiplier then carries the stop).
  implied_.assign(sys.limits.size(), 0);
  for (int k : model.ties) {
    const TreeLink& S = model.links[k];
    const TreeLink& M = model.links[S.tie];
    bool driven = false;  // (a driven slave's limit stays: drivenAtLimit names it)
    for (const DriveSpec& d : sys.drives) driven = driven || (d.joint == S.joint && d.k == 0);
    for (size_t ls = 0; ls < sys.limits.size() && !driven; ++ls) {
      if (!sys.limits[ls].single() || sys.limits[ls].joint != S.joint || sys.limits[ls].k != 0) continue;
      double lo = (sys.limits[ls].lower - S.tie_offset) / S.tie_mult, hi = (sys.limits[ls].upper - S.tie_offset) / S.tie_mult;
      if (lo > hi) std::swap(lo, hi);
      const double slack = 1e-12 * std::max({std::fabs(lo), std::fabs(hi), 1e-300});
      for (const LimitSpec& lm : sys.limits)
        if (lm.single() && lm.joint == M.joint && lm.k == 0 && lm.lower >= lo - slack && lm.upper <= hi + slack) {
          implied_[ls] = 1;
          tree_joint[sys.limits[ls].constraint] = 1;
        }
    }
  }
  for (int c = 0; c < sys.numConstraints(); ++c)
    if (!tree_joint[c]) constraints.push_back(c);
  // per velocity coordinate: the length that makes its rate a speed (the length scale for
  // an angle, 1 for a length), for the direct rows' residual floor
  unit_.setOnes(nv);
  angle_.assign(nv, 0);
  for (const TreeLink& L : model.links) {
    for (int k = 0; k < L.nv; ++k) {
      bool angle = false;
      if (L.quaternion >= 0) angle = k >= L.quaternion && k < L.quaternion + 3;  // (its rates)
      else if (L.ptr) angle = L.ptr->trackedSlot(k) >= 0;
      if (angle) unit_(L.iv + k) = sys.length_scale;
      angle_[L.iv + k] = angle;
    }
  }
  // limits and couplers on tree coordinates: rows directly on q
  direct_.assign(constraints.size(), DirectRow());
  auto coordinate = [&](const Joint& J, int k, DirectRow& d, int slot) {
    int link = -1;
    for (int j = 0; j < sys.numJoints(); ++j)
      if (&*sys.joints[j] == &J) link = model.joint_link[j];
    if (link < 0) return false;
    const TreeLink& L = model.links[link];
    if (L.quaternion >= 0 || L.ptr != &J) return false;
    d.col[slot] = L.iv + k;
    d.qcol[slot] = L.iq + k;
    d.angle[slot] = J.trackedSlot(k) >= 0;
    return true;
  };
  for (size_t i = 0; i < constraints.size(); ++i) {
    const Constraint& C = *sys.constraints[constraints[i]];
    DirectRow d;
    if (const auto* lim = dynamic_cast<const LimitConstraint*>(&C)) {  // sum_i c_i q_i - bound
      const auto& terms = lim->terms();
      bool all = true;
      for (size_t t = 0; t < terms.size() && all; ++t) {
        all = coordinate(*terms[t].joint, terms[t].k, d, static_cast<int>(t));
        d.coef[t] = terms[t].c;
      }
      if (all) d.n = static_cast<int>(terms.size()), d.limit = C.limit();
    } else if (const auto* cc = dynamic_cast<const CoordinateCoupler*>(&C)) {
      if (coordinate(cc->jointA(), cc->coordinateA(), d, 0) && coordinate(cc->jointB(), cc->coordinateB(), d, 1))
        d.n = 2, d.coef[0] = 1.0, d.coef[1] = -cc->multiplier(), d.offset = cc->offset();
    } else if (const auto* lc = dynamic_cast<const LinearCoupling*>(&C)) {
      const auto& terms = lc->terms();
      bool all = true;
      for (size_t t = 0; t < terms.size() && all; ++t) {
        all = coordinate(*terms[t].joint, terms[t].k, d, static_cast<int>(t));
        d.coef[t] = terms[t].c;
      }
      if (all) d.n = static_cast<int>(terms.size()), d.offset = lc->constant();
    }
    direct_[i] = d;
  }
  only_limits_ = true;
  for (int c : constraints) {
    limits_.push_back(sys.constraints[c]->limit());
    only_limits_ = only_limits_ && limits_.back() >= 0;
  }
  limit_direct_.assign(sys.limits.size(), -1);
  for (size_t i = 0; i < constraints.size(); ++i) {
    const int l = sys.constraints[constraints[i]]->limit();
    if (l >= 0 && direct_[i].n > 0) limit_direct_[l] = static_cast<int>(i);
  }
}

void ClosureRows::layOut(const System& sys, const std::vector<std::vector<char>>& idle) {
  row.clear(), sys_row.clear(), nrows_.clear(), sel_.assign(constraints.size(), {}), idle_sys_rows_.clear();
  sel_mask_.assign(constraints.size(), 0u), sel_joint_.assign(constraints.size(), nullptr);
  m = 0;
  for (size_t i = 0; i < constraints.size(); ++i) {
    const int c = constraints[i];
    const int n = sys.constraints[c]->size();
    const int r0 = c < static_cast<int>(sys.layout.size()) ? sys.layout[c].row : -1;
    row.push_back(m);
    for (int e = 0; e < n; ++e) {
      if (!idle.empty() && idle[i][e]) {
        idle_sys_rows_.push_back(r0 < 0 ? -1 : r0 + e);
        continue;
      }
      sel_[i].push_back(e);
      sys_row.push_back(r0 < 0 ? -1 : r0 + e);
    }
    int kept = static_cast<int>(sel_[i].size());
    if (kept == 0) {  // (a closure no motion moves at all: kept whole, its rows dropped as round-off)
      idle_sys_rows_.resize(idle_sys_rows_.size() - n);
      for (int e = 0; e < n; ++e) sys_row.push_back(r0 < 0 ? -1 : r0 + e);
      kept = n;
    }
    if (kept == n) sel_[i].clear();  // (every row: evaluated in place)
    sel_mask_[i] = 0u;
    for (int e : sel_[i]) sel_mask_[i] |= e < 32 ? 1u << e : 0u;
    sel_joint_[i] = !sel_[i].empty() && n <= 32 ? dynamic_cast<const Joint*>(sys.constraints[c].get()) : nullptr;
    nrows_.push_back(kept);
    m += kept;
  }
  idle_ = static_cast<int>(idle_sys_rows_.size());
}

}  // namespace mechanism_sim
