#include "mechanism_sim/core/joint.h"

#include <stdexcept>

namespace mechanism_sim {

JointGeometry Joint::geometry(const BodyKin& ki, const BodyKin& kj) const {
  const Matrix3d& Ri = frame_i_.Rp;
  const Matrix3d& Rj = frame_j_.Rp;
  return JointGeometry{fixedVector(ki, Ri.col(0)), fixedVector(ki, Ri.col(1)),
                       fixedVector(ki, Ri.col(2)), fixedVector(kj, Rj.col(0)),
                       fixedVector(kj, Rj.col(1)), fixedVector(kj, Rj.col(2)),
                       gap(ki, frame_i_.sp_B, kj, frame_j_.sp_B)};
}

void Joint::putPoint(const JointGeometry& g, RowWriter& out) {
  const Rows3 p = Cpoint(g.d);
  for (int k = 0; k < 3; ++k) {
    Row row;
    row.Phi = p.Phi(k);
    row.J = p.J.row(k);
    row.gamma = p.gamma(k);
    out.put(row);
  }
}

}  // namespace mechanism_sim
