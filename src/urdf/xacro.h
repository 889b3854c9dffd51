// xacro files expanded to URDF by ROS's own xacro through scripts/xacro (doc/xacro.md), run
// as a child process. Internal to the loader: loadModelFile
// expands a path ending in .xacro with LoadOptions::xacro_args.
#pragma once
#include <string>
#include <utility>
#include <vector>

namespace mechanism_sim {

using XacroArgs = std::vector<std::pair<std::string, std::string>>;  // name:=value, in order

// The file is xacro: its name ends in ".xacro".
bool isXacroFile(const std::string& path);

// The URDF that `scripts/xacro PATH name:=value...` writes; the program is the source tree's
// scripts/xacro or $MECHANISM_SIM_XACRO. No shell; standard input is /dev/null; a run longer than
// timeout_s is killed. Throws LoadError "PATH: xacro: what is wrong" (one line).
std::string expandXacro(const std::string& path, const XacroArgs& args, double timeout_s = 60.0);

}  // namespace mechanism_sim
