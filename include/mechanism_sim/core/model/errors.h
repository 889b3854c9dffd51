// What the core reports, in one hierarchy: a message that names the thing at fault (joint,
// body, constraint) and what to change. The URDF loader adds the file (LoadError).
//   Error            everything the library throws on purpose
//   ModelError       a model that cannot be simulated (found when it is built or assembled)
//   SimulationError  a run that cannot go on (found while stepping)
//   StepFailure      a step that left the constraints beyond repair (retried halved first)
//   UsageError       a call the API does not allow: before or after build(), an index that
//                    names nothing, a non-finite or out-of-range argument, a snapshot of
//                    another mechanism, a drive profile or path with bad points
//   InternalError    an invariant of this code failed: a bug, not the model's fault
// The line between ModelError and UsageError: what describes the mechanism (a joint type,
// a joint's parameters, a body, the assembly targets) is a ModelError whenever it is found;
// what a caller passes to a call (an index, an effort, a step, a command) is a UsageError,
// before build() and while stepping alike. Nothing in src/core or src/urdf throws a bare
// std:: exception; a std::exception other than these reaching a caller is a bug.
#pragma once
#include <sstream>
#include <stdexcept>
#include <string>

namespace mechanism_sim {

// A number as error messages print it: `precision` significant digits.
inline std::string fmt(double x, int precision = 3) {
  std::ostringstream os;
  os.precision(precision);
  os << x;
  return os.str();
}

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

class UsageError : public Error {
 public:
  using Error::Error;
};

class InternalError : public Error {
 public:
  explicit InternalError(const std::string& what)
      : Error("internal error (a bug in mechanism_sim, not in the model; please report it with the model): " + what) {}
};

}  // namespace mechanism_sim
