// libFuzzer target for the loader (doc/testing.md "Fuzzing and sanitizers"): bytes ->
// loadModelString; what loads is stepped 100 times. A clean refusal is a LoadError whose
// message is one line starting with the file name; a step may refuse with ModelError (a
// std::runtime_error). Anything else is a finding: another exception escaping, a bad
// message, a non-finite state after a step that did not refuse, or what the sanitizers and
// libFuzzer catch (crash, hang, leak). A finding prints "FINDING: ..." and aborts, so
// libFuzzer keeps the input.
// MECHANISM_SIM_FUZZ_IGNORE (an ECMAScript regex; scripts/fuzz --ignore) lets findings
// already written down pass, so a campaign looks past them for new ones.
// MECHANISM_SIM_FUZZ_VERBOSE=1 says what became of each input (to read a reproduction).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <regex>
#include <string>
#include <typeinfo>

#include <cxxabi.h>

#include "mechanism_sim/urdf/model.h"

namespace {

const char* const kSource = "fuzz.urdf";
const bool kVerbose = std::getenv("MECHANISM_SIM_FUZZ_VERBOSE") != nullptr;

void say(const std::string& what) {
  if (kVerbose) std::fprintf(stderr, "fuzz_loader: %s\n", what.c_str());
}

struct Ignored {};  // a known finding (MECHANISM_SIM_FUZZ_IGNORE): the input ends quietly

// One line, control characters escaped, for scripts/fuzz's triage.
[[noreturn]] void finding(const std::string& what) {
  std::string line;
  for (const char c : what) {
    if (c == '\n') line += "\\n";
    else if (static_cast<unsigned char>(c) >= 0x20) line += c;
    else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      line += hex;
    }
  }
  static const char* ignore = std::getenv("MECHANISM_SIM_FUZZ_IGNORE");
  static const std::regex known(ignore ? ignore : "$^");
  if (ignore && *ignore && std::regex_search(line, known)) throw Ignored();
  std::fprintf(stderr, "FINDING: %s\n", line.c_str());
  std::fflush(stderr);
  std::abort();
}

std::string typeName(const std::exception& e) {
  int status = 0;
  char* name = abi::__cxa_demangle(typeid(e).name(), nullptr, nullptr, &status);
  std::string out = status == 0 && name ? name : typeid(e).name();
  std::free(name);
  return out;
}

// The promise of doc/model_format.md "Bad input": one line,
// "FILE:LINE: element 'name': what" or "FILE: what".
void checkMessage(const std::string& msg) {
  const std::string prefix = std::string(kSource) + ":";
  if (msg.rfind(prefix, 0) != 0) finding("LoadError does not start with the file: " + msg);
  if (msg.find('\n') != std::string::npos) finding("LoadError is not one line: " + msg);
}

int fuzzOne(const uint8_t* data, size_t size) {
  const std::string xml(reinterpret_cast<const char*>(data), size);
  std::unique_ptr<mechanism_sim::MechanismModel> model;
  try {
    model = mechanism_sim::loadModelString(xml, kSource);
  } catch (const mechanism_sim::LoadError& e) {
    say(std::string("refused: ") + e.what());
    checkMessage(e.what());
    return 0;
  } catch (const std::exception& e) {
    finding("load: " + typeName(e) + " escaped: " + e.what());
  } catch (...) {
    finding("load: a non-std exception escaped");
  }
  for (int s = 0; s < 100; ++s) {
    try {
      model->step(1e-3);
    } catch (const mechanism_sim::ModelError& e) {
      say("loaded; step " + std::to_string(s + 1) + " refused: " + e.what());
      return 0;
    } catch (const std::runtime_error& e) {
      say("loaded; step " + std::to_string(s + 1) + " refused: " + e.what());
      return 0;
    } catch (const std::exception& e) {
      finding("step: " + typeName(e) + " escaped: " + e.what());
    }
    const double p = model->mechanism().positionViolation(), v = model->mechanism().velocityViolation();
    if (!std::isfinite(p) || !std::isfinite(v))
      finding("step: non-finite state without an error (violation " + std::to_string(p) + ", " +
              std::to_string(v) + ")");
    // a silently wrong answer: the step went on with the constraints visibly broken
    // (relative to each equation's own terms, so scale-free)
    const double rp = model->relativePositionViolation(), rv = model->relativeVelocityViolation();
    if (rp > 1e-6 || rv > 1e-6)
      finding("step: constraints left broken without an error (relative violation " + std::to_string(rp) + ", " +
              std::to_string(rv) + ")");
  }
  say("loaded; 100 steps taken");
  return 0;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    return fuzzOne(data, size);
  } catch (const Ignored&) {
    return 0;
  }
}
