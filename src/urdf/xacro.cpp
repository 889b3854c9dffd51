// Runs scripts/xacro (ROS's xacro, tools/xacro/run_xacro.py) and returns its standard output
// (xacro.h).
#include "xacro.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "mechanism_sim/urdf/model.h"
#include "xml_input.h"

// Builds outside catkin (the fuzz target) compile no script path in: $MECHANISM_SIM_XACRO.
#ifndef MECHANISM_SIM_XACRO_SCRIPT
#define MECHANISM_SIM_XACRO_SCRIPT ""
#endif

namespace mechanism_sim {

namespace {

constexpr size_t kMaxOutput = 256u << 20;  // a URDF larger than this is a runaway expansion

std::string fromEnv(const char* name, const std::string& otherwise) {
  const char* v = std::getenv(name);
  return v && *v ? v : otherwise;
}

// The line of the script's standard error that says what is wrong ("xacro: FILE: what"),
// without "xacro: FILE: " when FILE is the file expanded.
std::string reason(const std::string& err, const std::string& path) {
  std::string first, tagged;
  size_t start = 0;
  while (start < err.size()) {
    size_t end = err.find('\n', start);
    if (end == std::string::npos) end = err.size();
    const std::string line = err.substr(start, end - start);
    if (first.empty() && line.find_first_not_of(" \t\r") != std::string::npos) first = line;
    if (line.rfind("xacro: ", 0) == 0) tagged = line.substr(7);
    start = end + 1;
  }
  std::string r = !tagged.empty() ? tagged : first;
  if (r.rfind(path + ": ", 0) == 0) r = r.substr(path.size() + 2);
  return r;
}

struct Fd {
  int fd = -1;
  ~Fd() { reset(); }
  void reset() {
    if (fd >= 0) close(fd);
    fd = -1;
  }
};

}  // namespace

bool isXacroFile(const std::string& path) {
  static const std::string ext = ".xacro";
  return path.size() > ext.size() && path.compare(path.size() - ext.size(), ext.size(), ext) == 0;
}

std::string expandXacro(const std::string& path, const XacroArgs& args, double timeout_s) {
  auto fail = [&](const std::string& what) -> LoadError {
    return LoadError(path + ": xacro: " + urdf_input::oneLine(what, 400));
  };
  const std::string script = fromEnv("MECHANISM_SIM_XACRO", MECHANISM_SIM_XACRO_SCRIPT);
  if (access(script.c_str(), X_OK) != 0) throw fail("no program '" + script + "' to run (MECHANISM_SIM_XACRO)");

  std::vector<std::string> argv = {script, path};
  for (const auto& a : args) argv.push_back(a.first + ":=" + a.second);
  std::vector<char*> cargv;
  for (std::string& a : argv) cargv.push_back(a.data());
  cargv.push_back(nullptr);

  // Everything the child needs is made before fork: it only duplicates, execs and writes.
  int out[2], err[2], exec_err[2];
  if (pipe2(out, O_CLOEXEC) != 0) throw fail(std::string("pipe: ") + std::strerror(errno));
  Fd out_r{out[0]}, out_w{out[1]};
  if (pipe2(err, O_CLOEXEC) != 0) throw fail(std::string("pipe: ") + std::strerror(errno));
  Fd err_r{err[0]}, err_w{err[1]};
  if (pipe2(exec_err, O_CLOEXEC) != 0) throw fail(std::string("pipe: ") + std::strerror(errno));
  Fd exec_r{exec_err[0]}, exec_w{exec_err[1]};
  Fd null_in{open("/dev/null", O_RDONLY | O_CLOEXEC)};
  if (null_in.fd < 0) throw fail(std::string("/dev/null: ") + std::strerror(errno));

  const pid_t pid = fork();
  if (pid < 0) throw fail(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) {
    dup2(null_in.fd, STDIN_FILENO);
    dup2(out_w.fd, STDOUT_FILENO);
    dup2(err_w.fd, STDERR_FILENO);
    execv(cargv[0], cargv.data());
    const int e = errno;
    (void)!write(exec_w.fd, &e, sizeof e);
    _exit(127);
  }
  out_w.reset(), err_w.reset(), exec_w.reset(), null_in.reset();

  auto reap = [&] {
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    return status;
  };
  // exec failed: the child wrote its errno before the pipe closed on exec
  int exec_errno = 0;
  ssize_t n;
  while ((n = read(exec_r.fd, &exec_errno, sizeof exec_errno)) < 0 && errno == EINTR) {
  }
  if (n == static_cast<ssize_t>(sizeof exec_errno)) {
    reap();
    throw fail("cannot run '" + script + "': " + std::strerror(exec_errno));
  }

  std::string stdout_text, stderr_text;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  pollfd fds[2] = {{out_r.fd, POLLIN, 0}, {err_r.fd, POLLIN, 0}};
  std::string* sinks[2] = {&stdout_text, &stderr_text};
  int open_pipes = 2;
  bool timed_out = false, too_large = false;
  while (open_pipes > 0) {
    const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) {
      timed_out = true;
      break;
    }
    const int ready = poll(fds, 2, static_cast<int>(std::min(left * 1000.0, 1000.0)) + 1);
    if (ready < 0 && errno != EINTR) break;
    for (int i = 0; i < 2 && ready > 0; ++i) {
      if (fds[i].fd < 0 || !(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      char buf[65536];
      const ssize_t got = read(fds[i].fd, buf, sizeof buf);
      if (got > 0) {
        sinks[i]->append(buf, static_cast<size_t>(got));
        if (sinks[i]->size() > kMaxOutput) too_large = true;
      } else if (got == 0 || errno != EINTR) {
        fds[i].fd = -1;  // closed (the Fd guards close it)
        --open_pipes;
      }
    }
    if (too_large) break;
  }
  if (timed_out || too_large) {
    kill(pid, SIGKILL);
    reap();
    char limit[32];
    std::snprintf(limit, sizeof limit, "%g", timeout_s);
    if (timed_out) throw fail("no result from '" + script + "' within " + limit + " s (killed)");
    throw fail("the expansion is larger than " + std::to_string(kMaxOutput >> 20) + " MB");
  }
  const int status = reap();
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return stdout_text;
  std::string why = reason(stderr_text, path);
  if (why.empty())
    why = WIFSIGNALED(status)  ? "xacro was killed by signal " + std::to_string(WTERMSIG(status))
                              : "xacro exited with status " + std::to_string(WEXITSTATUS(status)) + " and no message";
  throw fail(why);
}

}  // namespace mechanism_sim
