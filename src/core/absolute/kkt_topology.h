// The absolute formulation's block layout of the KKT matrix for a tree of joints
// (kkt_topology.cpp): which joints its factorization holds exactly and where each
// constraint's blocks sit. The System knows nothing of it.
#pragma once
#include <utility>
#include <vector>

#include "mechanism_sim/core/model/system.h"

namespace mechanism_sim {

// The spanning tree (forest) of joints that the tree KKT solver holds exactly
// (kkt_topology.cpp), computed once per solver (makeSolver). Block rows of the KKT matrix: 0..nb-1
// the moving bodies, nb + k the k-th tree joint (its equations, then the drives and limits
// of its coordinates that fit in 6 rows). Empty (tree false) for a mechanism with loop
// closures or couplers: its equations are all in penalty form.
struct KktTopology {
  bool tree = false;
  // The spanning forest (also where tree is false: the loops' cut joints are off it)
  std::vector<int> parent;         // per moving body: its parent (moving index), -1 the ground
  std::vector<int> parent_joint;   // per moving body: the constraint tying it to its parent, -1
  std::vector<int> node;           // per constraint: its KKT block row, -1 when penalized
  struct NodeRow {
    int row, constraint, e;        // global row; its constraint and row there
  };
  std::vector<std::vector<NodeRow>> node_rows;  // per tree block (row nb + k): its rows
  std::vector<int> penalized;      // constraints in penalty form
  int nodes = 0;                   // block rows
  std::vector<int> order;          // elimination order (post-order: leaves first)
  std::vector<signed char> signs;  // per block row: +1 body, -1 joint
  std::vector<std::pair<int, int>> edges;  // block pattern
  // Per constraint: KKT blocks of its slot pairs (penalized: body-body as in
  // ConstraintLayout; tree: (node, slot) per slot, the node's diagonal last).
  std::vector<std::vector<int>> address;
  std::vector<std::vector<char>> transposed;
  std::vector<int> added;          // off-diagonal blocks the penalized equations add to
};

// The topology of sys (tree false, every constraint penalized, where sys is not a tree of
// definite bodies with at most their joints' drives and limits beside the joints).
KktTopology kktTopology(const System& sys);

}  // namespace mechanism_sim
