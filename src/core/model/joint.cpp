#include "mechanism_sim/core/model/joint.h"

#include <stdexcept>

namespace mechanism_sim {

JointGeometry Joint::geometry(const BodyKin& ki, const BodyKin& kj, unsigned parts) const {
  const Matrix3d& Ri = frame_i_.Rp;
  const Matrix3d& Rj = frame_j_.Rp;
  const bool rates = !(parts & kNoRates);
  JointGeometry g;
  if (parts & kBxI) fixedVector(ki, Ri.col(0), g.bx_i, rates);
  if (parts & kByI) fixedVector(ki, Ri.col(1), g.by_i, rates);
  if (parts & kBzI) fixedVector(ki, Ri.col(2), g.bz_i, rates);
  if (parts & kBxJ) fixedVector(kj, Rj.col(0), g.bx_j, rates);
  if (parts & kByJ) fixedVector(kj, Rj.col(1), g.by_j, rates);
  if (parts & kBzJ) fixedVector(kj, Rj.col(2), g.bz_j, rates);
  if (parts & kGap) gap(ki, frame_i_.sp_B, kj, frame_j_.sp_B, g.d, rates);
  return g;
}

double Joint::relativeAngleValueOf(const BodyKin& ki, const BodyKin& kj, double phi_ref) const {
  const Vector3d bxp_i = frame_i_.Rp.col(0), byp_i = frame_i_.Rp.col(1), bxp_j = frame_j_.Rp.col(0);
  const Vector3d bx_i = ki.A_Oi * bxp_i, by_i = ki.A_Oi * byp_i, bx_j = kj.A_Oi * bxp_j;  // (fixedVector's a)
  return relativeAngleValue(bx_i, by_i, bx_j, phi_ref);
}

void Joint::track(const BodyKin* const* kin, const EvalContext&, Tracked& t, Tracked& rate) const {
  rate = Tracked{};
  Row rows[kMaxJointDofs];
  if (!trackedRows(*kin[0], *kin[1], t, rows)) return;
  for (int k = 0; k < dof(); ++k)
    if (trackedSlot(k) >= 0) {
      t[trackedSlot(k)] = rows[k].Phi;  // unwrapped near the old value
      rate[trackedSlot(k)] = rows[k].Phi_dot;
    }
}

void Joint::trackAngles(const BodyKin* const* kin, const EvalContext&, Tracked& t) const {
  bool any = false;
  for (int k = 0; k < dof(); ++k) any = any || trackedSlot(k) >= 0;
  if (!any) return;
  double q[kMaxJointDofs];
  coordinateValues(*kin[0], *kin[1], t, q);  // (reads t: written after)
  for (int k = 0; k < dof(); ++k)
    if (trackedSlot(k) >= 0) t[trackedSlot(k)] = q[k];  // unwrapped near the old value
}

void Joint::coordinateValues(const BodyKin& ki, const BodyKin& kj, const Tracked& t, double* q) const {
  Row rows[kMaxJointDofs];
  coordinates(ki, kj, t, rows);
  for (int k = 0; k < dof(); ++k) q[k] = rows[k].Phi;
}

void Joint::treePositions(const BodyKin& ki, const BodyKin& kj, const Tracked& t, double* q) const {
  Row rows[kMaxJointDofs];
  coordinates(ki, kj, t, rows);
  for (int k = 0; k < dof(); ++k) q[k] = rows[k].Phi;
}

void Joint::trackedRates(const BodyKin* const* kin, const EvalContext& ctx, Tracked& rate) const {
  rate = Tracked{};
  Row rows[kMaxJointDofs];
  if (!trackedRows(*kin[0], *kin[1], ctx.tracked[id()], rows)) return;
  for (int k = 0; k < dof(); ++k)
    if (trackedSlot(k) >= 0) rate[trackedSlot(k)] = rows[k].Phi_dot;
}

bool Joint::trackedRows(const BodyKin& ki, const BodyKin& kj, const Tracked& t, Row* rows) const {
  bool any = false;
  for (int k = 0; k < dof(); ++k) any = any || trackedSlot(k) >= 0;
  if (any) coordinates(ki, kj, t, rows);
  return any;
}

void Joint::putPoint(const JointGeometry& g, RowWriter& out) {
  if (!out.wants(3)) return out.skip(3);  // (evaluateRows: none of the three read)
  out.put(Cpoint(g.d));
}

}  // namespace mechanism_sim
