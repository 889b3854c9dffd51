// The spanning tree of joints the tree KKT solver holds exactly (kkt_topology.h).
#include <algorithm>
#include <utility>

#include <Eigen/Eigenvalues>

#include "core/absolute/kkt_topology.h"
#include "core/linalg/block_cholesky.h"

namespace mechanism_sim {

// The spanning tree (forest) of joints held exactly by the KKT factorization: from the
// ground outwards (depth first), a joint joins the tree when it ties a body not yet
// reached (which must have a positive definite mass matrix: its pivot is then definite)
// to one that is; bodies left over start trees of their own. Block rows are eliminated
// leaves first: each body, then the joint to its parent, before the parent. A joint's
// drives and limits are rows of its block; a mechanism with loop closures or couplers
// keeps H for everything (below).
KktTopology kktTopology(const System& sys) {
  KktTopology T;
  const int nc = sys.numConstraints();
  T.node.assign(nc, -1);
  auto definite = [&](int body) {  // moving-body index
    const Body& B = sys.bodies[body + 1];
    const double tr = B.Jp.trace();
    return B.m > 0 && tr > 0 && Eigen::SelfAdjointEigenSolver<Matrix3d>(B.Jp).eigenvalues().minCoeff() > 1e-6 * tr;
  };
  std::vector<int>& parent_joint = T.parent_joint;
  std::vector<int>& parent = T.parent;
  parent_joint.assign(sys.nb, -1), parent.assign(sys.nb, -1);
  std::vector<char> reached(sys.nb, 0);
  std::vector<int> roots;  // bodies no tree joint ties to the ground (floating ones)
  std::vector<int> joint_cs;
  for (int j = 0; j < sys.numJoints(); ++j)
    if (sys.joints[j]->size() > 0 && sys.joints[j]->bodies().size() == 2) joint_cs.push_back(sys.joint_constraint[j]);
  std::vector<std::vector<int>> incident(sys.nb + 1);  // [nb]: the ground's
  for (int ci : joint_cs)
    for (int b : sys.layout[ci].bodies) incident[b < 0 ? sys.nb : b].push_back(ci);
  std::vector<std::pair<int, size_t>> path;
  auto grow = [&](int top) {  // top: a moving body or -1 (the ground)
    path.assign(1, {top, 0});
    while (!path.empty()) {
      auto& [x, next] = path.back();
      const std::vector<int>& js = incident[x < 0 ? sys.nb : x];
      if (next == js.size()) {
        path.pop_back();
        continue;
      }
      const int ci = js[next++];
      if (T.node[ci] >= 0) continue;
      const int a = sys.layout[ci].bodies[0], b = sys.layout[ci].bodies[1];
      const int y = a == x ? b : a;
      if (y < 0 || reached[y] || !definite(y)) continue;
      reached[y] = 1;
      parent[y] = x;
      parent_joint[y] = ci;
      T.node[ci] = 0;  // numbered below
      path.push_back({y, 0});
    }
  };
  grow(-1);
  for (int b = 0; b < sys.nb; ++b)
    if (!reached[b]) reached[b] = 1, roots.push_back(b), grow(b);
  // Trees only: besides the tree's joints there may be drives and limits of tree joints
  // (rows of the joint's block, or weighted when they do not fit: no fill either way, they
  // couple the body pair of a tree joint), not loop closures or couplers. Near
  // a configuration where a loop's equations become dependent (a parallelogram passing
  // flat) the exact tree rows push all of the inconsistency into the loop's penalized
  // rows, and its solves fall short by orders of magnitude more than in penalty form,
  // which spreads it over every equation by its weight. A loop's passes stay in either
  // form, so mechanisms with loops keep H.
  std::vector<char> allowed(nc, 0);
  for (const DriveSpec& D : sys.drives) allowed[D.constraint] = T.node[sys.joint_constraint[D.joint]] >= 0;
  for (const LimitSpec& L : sys.limits) allowed[L.constraint] = L.single() && T.node[sys.joint_constraint[L.joint]] >= 0;
  bool tree = false;
  for (int ci = 0; ci < nc; ++ci) {
    if (T.node[ci] >= 0) tree = true;
    else if (sys.layout[ci].size > 0 && !allowed[ci]) {
      tree = false;
      break;
    }
  }
  // Rotor inertias (transmission.h) add body-pair blocks to M: the penalty form holds them.
  if (!sys.rotors.empty()) tree = false;
  if (!tree) {
    std::fill(T.node.begin(), T.node.end(), -1);
    T.penalized = sys.all_constraints;
    return T;
  }
  // post-order: children before parents, each body followed by its parent joint
  std::vector<std::vector<int>> children(sys.nb + 1);  // [nb]: the ground's
  for (int b = 0; b < sys.nb; ++b)
    if (parent_joint[b] >= 0) children[parent[b] < 0 ? sys.nb : parent[b]].push_back(b);
  std::vector<int> order;
  std::vector<int> tree_cs;
  std::vector<std::pair<int, size_t>> stack;
  auto visit = [&](int top) {  // iterative post-order of the subtree of body `top`
    stack.push_back({top, 0});
    while (!stack.empty()) {
      auto& [b, next] = stack.back();
      if (next < children[b].size()) {
        const int c = children[b][next++];
        stack.push_back({c, 0});
        continue;
      }
      order.push_back(b);
      if (parent_joint[b] >= 0) tree_cs.push_back(parent_joint[b]), order.push_back(-1 - parent_joint[b]);
      stack.pop_back();
    }
  };
  for (int b : children[sys.nb]) visit(b);
  for (int r : roots) visit(r);
  for (size_t k = 0; k < tree_cs.size(); ++k) T.node[tree_cs[k]] = sys.nb + static_cast<int>(k);
  for (int& o : order)
    if (o < 0) o = T.node[-1 - o];
  const int nodes = sys.nb + static_cast<int>(tree_cs.size());
  // The rows of each tree block: its joint's equations, then the drives and limits of
  // that joint while they fit in 6 (a coordinate has at most one of each; the rest stay
  // weighted). An inactive limit's row is zero: then, like padding, it is decoupled.
  T.node_rows.assign(tree_cs.size(), {});
  for (size_t k = 0; k < tree_cs.size(); ++k) {
    const ConstraintLayout& L = sys.layout[tree_cs[k]];
    for (int e = 0; e < L.size; ++e) T.node_rows[k].push_back({L.row + e, tree_cs[k], e});
  }
  std::vector<char> merged(nc, 0);
  auto attach = [&](int c, int joint) {
    const int node = T.node[sys.joint_constraint[joint]];
    if (node < 0) return;
    std::vector<KktTopology::NodeRow>& rows = T.node_rows[node - sys.nb];
    const ConstraintLayout& L = sys.layout[c];
    if (static_cast<int>(rows.size()) + L.size > 6) return;
    for (int e = 0; e < L.size; ++e) rows.push_back({L.row + e, c, e});
    merged[c] = 1;
  };
  for (const DriveSpec& D : sys.drives) attach(D.constraint, D.joint);
  for (const LimitSpec& L : sys.limits)
    if (L.single()) attach(L.constraint, L.joint);
  std::vector<signed char> signs(nodes, 1);
  for (int k = sys.nb; k < nodes; ++k) signs[k] = -1;
  std::vector<std::pair<int, int>> edges;
  T.penalized.clear();
  for (int ci = 0; ci < nc; ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    if (T.node[ci] >= 0) {
      for (int b : L.bodies)
        if (b >= 0) edges.push_back({T.node[ci], b});
      continue;
    }
    if (merged[ci]) continue;  // rows of its joint's block
    T.penalized.push_back(ci);
    for (int b1 : L.bodies)
      for (int b2 : L.bodies)
        if (b1 >= 0 && b2 >= 0 && b1 < b2) edges.push_back({b1, b2});
  }
  // the block pattern as the solver analyzes it (TreeKktSolver), here for the addresses
  BlockCholesky pattern;
  pattern.analyze(nodes, edges, order, signs);
  T.tree = true;
  T.nodes = nodes;
  T.order = order;
  T.signs = signs;
  T.edges = edges;
  T.address.assign(nc, {});
  T.transposed.assign(nc, {});
  for (int ci = 0; ci < nc; ++ci) {
    const ConstraintLayout& L = sys.layout[ci];
    const int k = static_cast<int>(L.bodies.size());
    bool t = false;
    if (T.node[ci] >= 0) {
      for (int s = 0; s < k; ++s) {
        const int a = L.bodies[s] < 0 ? -1 : pattern.address(T.node[ci], L.bodies[s], &t);
        T.address[ci].push_back(a);
        T.transposed[ci].push_back(t);
      }
      T.address[ci].push_back(pattern.address(T.node[ci], T.node[ci], &t));
      continue;
    }
    // A drive or limit merged into its joint's block has no blocks of its own: its body
    // pair is coupled through the joint's block row, not directly (a tree has no
    // body-body block). Asking for one failed for every limited joint below a moving body.
    if (merged[ci]) continue;
    T.address[ci].assign(k * k, -1);
    T.transposed[ci].assign(k * k, 0);
    for (int k1 = 0; k1 < k; ++k1)
      for (int k2 = k1; k2 < k; ++k2) {
        if (L.bodies[k1] < 0 || L.bodies[k2] < 0) continue;
        T.address[ci][k1 * k + k2] = pattern.address(L.bodies[k1], L.bodies[k2], &t);
        T.transposed[ci][k1 * k + k2] = t;
      }
  }
  T.added.clear();
  for (int ci : T.penalized)
    for (size_t k = 0; k < T.address[ci].size(); ++k) {
      const int a = T.address[ci][k];
      if (a >= nodes) T.added.push_back(a);  // off the diagonal (the diagonal is assigned)
    }
  std::sort(T.added.begin(), T.added.end());
  return T;
  T.added.erase(std::unique(T.added.begin(), T.added.end()), T.added.end());
  for (auto& e : edges)
    if (e.first > e.second) std::swap(e.first, e.second);
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  if (pattern.offDiagonalBlocks() != static_cast<int>(edges.size()))  // (no fill in a tree)
    throw InternalError("the tree KKT factorization has fill");
}


}  // namespace mechanism_sim
