// Runs a shell command for the CLI tests and captures its standard output (redirect
// stderr in the command to capture it too).
#pragma once
#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace mechanism_sim {
namespace testing_util {

struct CommandResult {
  int code;         // exit status, -1 if it did not exit normally
  std::string out;  // what it wrote to the pipe
};

inline CommandResult runCommand(const std::string& command) {
  FILE* p = popen(command.c_str(), "r");
  if (!p) return {-1, ""};
  std::string out;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  const int status = pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

}  // namespace testing_util
}  // namespace mechanism_sim
