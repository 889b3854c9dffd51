// What the core reports, in one hierarchy: a message that names the thing at fault (joint,
// body, constraint) and what to change. The URDF loader adds the file (LoadError).
//   Error            everything the library throws on purpose
//   ModelError       a model that cannot be simulated (found when it is built or assembled)
//   SimulationError  a run that cannot go on (found while stepping)
//   StepFailure      a step that left the constraints beyond repair (retried halved first)
//   InternalError    an invariant of this code failed: a bug, not the model's fault
#pragma once
#include <stdexcept>
#include <string>

namespace mechanism_sim {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ModelError : public Error {
 public:
  using Error::Error;
};

class SimulationError : public Error {
 public:
  using Error::Error;
};

class StepFailure : public SimulationError {
 public:
  using SimulationError::SimulationError;
};

class InternalError : public Error {
 public:
  explicit InternalError(const std::string& what)
      : Error("internal error (a bug in mechanism_sim, not in the model; please report it with the model): " + what) {}
};

}  // namespace mechanism_sim
