#include "core/assembly/mass_check.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

#include <Eigen/Eigenvalues>

#include "core/absolute/projection.h"

namespace mechanism_sim {
namespace {

// The moving bodies that the motions moving no mass move. Such a motion v has each body's
// part v_b in the null space of the body's mass block diag(m I, Jp) (all of it for a body
// with neither mass nor inertia, the rotations of a point mass), and meets Phi_q v = 0 with
// every other body still: the null space of W^1/2 Phi_q N, N the bases of those null
// spaces, gives every such motion and every body it moves (dense, on the bodies with a
// singular mass block only, and only when assembly refuses the model).
std::vector<int> bodiesMovingNoMass(const System& sys, const Evaluation& ev) {
  std::vector<Eigen::MatrixXd> basis(sys.nb + 1);  // N_b, 6 x k_b (k_b = 0: the body's motions all move mass)
  std::vector<int> column(sys.nb + 1, 0);
  int k = 0;
  for (int b = 1; b <= sys.nb; ++b) {
    const Body& B = sys.bodies[b];
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(B.Jp);
    std::vector<Eigen::Matrix<double, 6, 1>> free;
    if (!(B.m > 1e-12 * sys.mass_scale))
      for (int i = 0; i < 3; ++i) free.push_back(Eigen::Matrix<double, 6, 1>::Unit(i));
    for (int i = 0; i < 3; ++i)
      if (!(eig.eigenvalues()(i) > 1e-12 * sys.inertia_scale)) {
        Eigen::Matrix<double, 6, 1> v = Eigen::Matrix<double, 6, 1>::Zero();
        v.tail<3>() = eig.eigenvectors().col(i);
        free.push_back(v);
      }
    basis[b].resize(6, static_cast<int>(free.size()));
    for (size_t i = 0; i < free.size(); ++i) basis[b].col(static_cast<int>(i)) = free[i];
    column[b] = k;
    k += static_cast<int>(free.size());
  }
  std::vector<int> moved;
  if (k == 0) return moved;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(sys.m, k);
  for (int ci = 0; ci < sys.numConstraints(); ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    for (size_t slot = 0; slot < L.bodies.size(); ++slot) {
      const int b = L.bodies[slot] + 1;
      if (b < 1 || basis[b].cols() == 0) continue;
      for (int r = 0; r < L.size; ++r)
        A.row(L.row + r).segment(column[b], basis[b].cols()) +=
            std::sqrt(ev.W(L.row + r)) * ev.J[ci].row(r).segment<6>(6 * static_cast<int>(slot)) * basis[b];
    }
  }
  const Eigen::MatrixXd AtA = A.transpose() * A;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(AtA);
  const double largest = std::max(eig.eigenvalues().cwiseAbs().maxCoeff(), 1e-300);
  std::vector<char> moves(sys.nb + 1, 0);
  for (int i = 0; i < k; ++i) {
    if (eig.eigenvalues()(i) > 1e-10 * largest && largest > 1e-300) continue;
    const Eigen::VectorXd z = eig.eigenvectors().col(i);
    for (int b = 1; b <= sys.nb; ++b)
      if (basis[b].cols() > 0 && z.segment(column[b], basis[b].cols()).norm() > 1e-6) moves[b] = 1;
  }
  for (int b = 1; b <= sys.nb; ++b)
    if (moves[b]) moved.push_back(b);
  return moved;
}

// M + Phi_q^T W Phi_q (W: row weights, so the matrix is well conditioned) must be positive
// definite: every motion the joints allow moves some mass. Otherwise the message names
// every body that a motion moving no mass moves (bodiesMovingNoMass), or, should that find
// none (a matrix singular by its condition alone), the bodies of the zero pivots.
}  // namespace

void checkMassRank(const System& sys, Evaluation& ev, PenaltyForm& H) {
  rowWeights(sys, ev, sys.all_constraints);
  H.assemble(sys, ev, 1.0, 1.0, 0.0);
  if (H.factorize(1e-10, true) == 0) return;
  std::vector<int> moved = bodiesMovingNoMass(sys, ev);
  if (moved.empty())
    for (int b = 1; b <= sys.nb; ++b) {
      bool zero = false;
      for (int r = 0; r < 6; ++r) zero = zero || H.zeroPivot(b - 1, r);
      if (zero) moved.push_back(b);
    }
  std::ostringstream os;
  os << "bodies that can move without moving any mass:";
  for (const int b : moved) os << " '" << sys.bodies[b].name << "'";
  os << " (give them mass and inertia, or joints that fix every direction they can move in)";
  throw ModelError(os.str());
}

}  // namespace mechanism_sim
