// What the core reports about a run's linear algebra, for the user and the tests: the
// solves' and projections' counts and shortfalls (SolverStats), and which equations depend
// on others (DependencyReport). Both formulations fill them; the Mechanism hands them out.
#pragma once
#include <algorithm>
#include <string>
#include <utility>
#include <vector>

namespace mechanism_sim {

// Iterations that met their tolerance and those that stopped short (with the worst
// relative residual they left).
struct SolverStats {
  long solves = 0, solve_shortfalls = 0;
  long position_projections = 0, position_shortfalls = 0;
  long velocity_projections = 0, velocity_shortfalls = 0;
  long evaluations = 0, factorizations = 0, solve_passes = 0;
  long halved_steps = 0;  // steps retaken as two half steps (a projection failed, the error estimate leapt)
  double worst_solve = 0, worst_position = 0, worst_velocity = 0;
  long shortfalls() const { return solve_shortfalls + position_shortfalls + velocity_shortfalls; }
  // One projection counted; one that missed its tolerance also as a shortfall, with its
  // relative residual.
  void countPositionProjection(bool met, double residual) {
    ++position_projections;
    if (!met) ++position_shortfalls, worst_position = std::max(worst_position, residual);
  }
  void countVelocityProjection(bool met, double residual) {
    ++velocity_projections;
    if (!met) ++velocity_shortfalls, worst_velocity = std::max(worst_velocity, residual);
  }
  // Another's solves, projections, halved steps and worst residuals with these (the
  // evaluations, factorizations and solve passes stay the stepper's own work counts).
  void add(const SolverStats& o) {
    solves += o.solves, solve_shortfalls += o.solve_shortfalls;
    position_projections += o.position_projections, position_shortfalls += o.position_shortfalls;
    velocity_projections += o.velocity_projections, velocity_shortfalls += o.velocity_shortfalls;
    halved_steps += o.halved_steps;
    worst_solve = std::max(worst_solve, o.worst_solve);
    worst_position = std::max(worst_position, o.worst_position);
    worst_velocity = std::max(worst_velocity, o.worst_velocity);
  }
  std::string describe() const;  // one line
};

// What an analysis found, for the user: equality equations and how many depend on others.
struct DependencyReport {
  int equations = 0, dependent = 0;
  std::vector<std::pair<std::string, int>> by_constraint;  // (name, dependent count)
  std::string describe() const;
};

}  // namespace mechanism_sim
