// CSV rows of a running model: time, each dof's position/velocity/effort, the largest
// constraint violations, and (optionally) each joint's reaction on its child link (force
// and torque in the joint frame on the child) and each link's world pose.
#pragma once
#include <ostream>
#include <string>

#include "mechanism_sim/urdf/model.h"
#include "mechanism_sim/urdf/run_loop.h"

namespace mechanism_sim {

class CsvWriter {
 public:
  CsvWriter(std::ostream& out, const MechanismModel& model, bool poses, bool reactions);
  void header();
  void row(const Sample& sample);

 private:
  std::ostream& out_;
  const MechanismModel& model_;
  bool poses_, reactions_;
  std::string line_;  // a row, formatted before it is written
};

}  // namespace mechanism_sim
