// Rank of Phi_q (dependencies.h).
//
// The test is made on Phi_q in coordinates of the joints' own geometry, which leaves its
// rank as it is: a body's position is taken at the centroid c of its joints' points (body
// frame) rather than at its centre of mass, delta r = delta r_c + A tilde(c) delta theta'
// (so J_theta gains J_r A tilde(c)), and rotations are measured by the displacement they
// make at l, the largest distance of a joint point from its body's centroid
// (delta theta' = delta phi / l, one l for all bodies, so that rows between two bodies'
// rotations keep their balance). Rows taken at the centre of mass carry the lever arm from
// it: with a rod's centre of mass 425 km from its joints 0.35 m apart, a slider-crank's loop
// looks dependent at 1e-9 and loses all five equations of its wrist pin, and a double
// pendulum whose second link's centre of mass lies 100 km off loses two of its joint's five.
// In the joints' geometry the loop keeps the three dependent equations of a planar loop and
// the pendulum none, in metres or in millimetres alike.
#include "core/absolute/dependencies.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "mechanism_sim/core/model/errors.h"
#include "mechanism_sim/core/model/math.h"
#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

std::string DependencyReport::describe() const {
  std::ostringstream os;
  if (dependent == 0) {
    os << "all " << equations << " constraint equations are independent";
    return os.str();
  }
  os << dependent << " of " << equations << " constraint equations are dependent (";
  bool first = true;
  for (const auto& e : by_constraint) {
    os << (first ? "" : ", ") << "'" << e.first << "' " << e.second;
    first = false;
  }
  os << ")";
  return os.str();
}

void DependencyAnalyzer::init(const System& sys) {
  const int nc = sys.numConstraints(), m = sys.m;
  for (int ci = 1; ci < nc; ++ci)
    if (sys.layout[ci].row < sys.layout[ci - 1].row || sys.layout[ci].size > 6)
      throw InternalError("dependency analysis: constraint rows out of order");
  limit_of_.assign(nc, -1);
  for (size_t l = 0; l < sys.limits.size(); ++l) limit_of_[sys.limits[l].constraint] = static_cast<int>(l);
  Jn_.resize(nc);
  for (int ci = 0; ci < nc; ++ci) Jn_[ci].setZero(6, 6 * static_cast<int>(sys.layout[ci].bodies.size()));
  // each body's joint points: their centroid c; l: the largest distance of a joint point
  // from the centroid of its body's (the mechanism's size without its centres of mass)
  centroid_.assign(sys.bodies.size(), Eigen::Vector3d::Zero());
  size_ = 0;
  std::vector<std::vector<Eigen::Vector3d>> points(sys.bodies.size());
  for (const Joint* j : sys.joints) {
    if (j->bodyI() != System::kGround) points[j->bodyI()].push_back(j->frameI().sp_B);
    if (j->bodyJ() != System::kGround) points[j->bodyJ()].push_back(j->frameJ().sp_B);
  }
  for (size_t b = 1; b < points.size(); ++b) {
    for (const Eigen::Vector3d& p : points[b]) centroid_[b] += p / static_cast<double>(points[b].size());
    for (const Eigen::Vector3d& p : points[b]) size_ = std::max(size_, (p - centroid_[b]).norm());
  }
  if (!(size_ > 0)) size_ = sys.length_scale;  // every body has one joint
  // the Gram matrix's upper triangle: entry (row i, row j), i <= j, numbered in columns
  std::vector<std::vector<std::pair<int, int>>> at_body(sys.nb);  // (constraint, slot)
  for (int ci = 0; ci < nc; ++ci) {
    const auto& bs = sys.layout[ci].bodies;
    for (size_t k = 0; k < bs.size(); ++k)
      if (bs[k] >= 0) at_body[bs[k]].push_back({ci, static_cast<int>(k)});
  }
  std::map<std::pair<int, int>, int> entry;  // (column j, row i) -> position
  auto touch = [&](int i, int j) { entry.emplace(std::make_pair(j, i), 0); };
  for (int e = 0; e < m; ++e) touch(e, e);
  for (const auto& list : at_body)
    for (const auto& a : list)
      for (const auto& c : list) {
        const ConstraintLayout &La = sys.layout[a.first], &Lc = sys.layout[c.first];
        if (La.row > Lc.row) continue;
        for (int i = 0; i < La.size; ++i)
          for (int j = 0; j < Lc.size; ++j)
            if (La.row + i <= Lc.row + j) touch(La.row + i, Lc.row + j);
      }
  std::vector<int> Gp(m + 1, 0), Gi;
  Gi.reserve(entry.size());
  int position = 0;
  for (auto& [key, pos] : entry) {
    pos = position++;
    Gi.push_back(key.second);
    ++Gp[key.first + 1];
  }
  for (int j = 0; j < m; ++j) Gp[j + 1] += Gp[j];
  diagonal_.assign(m, 0);
  for (int e = 0; e < m; ++e) diagonal_[e] = entry.at({e, e});
  contributions_.clear();
  index_.clear();
  for (const auto& list : at_body)
    for (const auto& a : list)
      for (const auto& c : list) {
        const ConstraintLayout &La = sys.layout[a.first], &Lc = sys.layout[c.first];
        if (La.row > Lc.row) continue;
        contributions_.push_back({a.first, a.second, c.first, c.second, static_cast<int>(index_.size())});
        for (int i = 0; i < 6; ++i)
          for (int j = 0; j < 6; ++j)
            index_.push_back(i < La.size && j < Lc.size && La.row + i <= Lc.row + j
                                 ? entry.at({Lc.row + j, La.row + i})
                                 : -1);
      }
  Gx_.assign(entry.size(), 0.0);
  gram_.analyze(m, Gp, Gi, {});
  ready_ = true;
}

int DependencyAnalyzer::finish(const System& sys, const std::vector<BodyKin>& kin, const signed char* limit_side,
                               std::vector<char>& dropped, DependencyReport* report) {
  const int nc = sys.numConstraints();
  for (int ci = 0; ci < nc; ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    auto& Jn = Jn_[ci];
    for (int e = L.size; e < 6; ++e) Jn.row(e).setZero();
    for (size_t k = 0; k < L.bodies.size(); ++k) {
      if (L.bodies[k] < 0) continue;
      auto Jb = Jn.middleCols<6>(6 * k);
      const Eigen::Matrix3d shift = kin[L.bodies[k] + 1].A_Oi * tilde(centroid_[L.bodies[k] + 1]);
      Jb.rightCols<3>() = (Jb.rightCols<3>() + Jb.leftCols<3>() * shift) / size_;
    }
    for (int e = 0; e < L.size; ++e) {
      const double norm = Jn.row(e).norm();
      if (norm > 0) Jn.row(e) /= norm;
    }
  }
  std::fill(Gx_.begin(), Gx_.end(), 0.0);
  for (const Contribution& k : contributions_) {
    const Mat6 P = Jn_[k.a].middleCols<6>(6 * k.slot_a) * Jn_[k.c].middleCols<6>(6 * k.slot_c).transpose();
    const int* at = index_.data() + k.first;
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j)
        if (at[i * 6 + j] >= 0) Gx_[at[i * 6 + j]] += P(i, j);
  }
  gram_.factorize(Gx_.data(), kPivotTol, true);
  if (report) {
    *report = DependencyReport();
    report->equations = sys.m_eq;
  }
  int total = 0;
  for (int ci = 0; ci < nc; ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    int count = 0;
    for (int e = 0; e < L.size; ++e) count += gram_.zeroPivot(L.row + e);
    // Which of its rows: the pivoted Cholesky of the constraint's Schur complement keeps
    // the rows with the most left outside the span of the others, largest first.
    char keep[6] = {1, 1, 1, 1, 1, 1};
    if (count > 0 && L.size > 1) {
      gram_.schurBlock(L.row, L.size, S_.data(), 6);
      for (int e = 0; e < L.size; ++e) keep[e] = 0;
      for (int pass = 0; pass < L.size; ++pass) {
        int best = -1;
        double best_ratio = 0.0;
        for (int e = 0; e < L.size; ++e) {
          const double a = Gx_[diagonal_[L.row + e]];
          if (keep[e] || !(a > 0)) continue;
          const double ratio = S_(e, e) / a;
          if (ratio > best_ratio) best_ratio = ratio, best = e;
        }
        if (best < 0 || !(best_ratio > kPivotTol)) break;
        keep[best] = 1;
        const double d = S_(best, best);
        for (int a = 0; a < L.size; ++a)
          for (int b = 0; b < L.size; ++b)
            if (a != best && b != best) S_(a, b) -= S_(a, best) * S_(best, b) / d;
        for (int e = 0; e < L.size; ++e) S_(e, best) = S_(best, e) = 0.0;
        S_(best, best) = d;
      }
      count = 0;
      for (int e = 0; e < L.size; ++e) count += !keep[e];
    } else {
      for (int e = 0; e < L.size; ++e) keep[e] = !gram_.zeroPivot(L.row + e);
    }
    // an inactive limit's row is zero: not an equation at all
    const bool limit = L.row >= sys.m_eq;
    const bool inactive = limit_of_[ci] >= 0 && limit_side[limit_of_[ci]] == 0;
    for (int e = 0; e < L.size; ++e) dropped[L.row + e] = inactive ? 0 : !keep[e];
    if (inactive) count = 0;
    total += count;
    if (report && count && !limit) {
      report->by_constraint.push_back({sys.constraints[ci]->name(), count});
      report->dependent += count;
    }
  }
  return total;
}

}  // namespace mechanism_sim
