// xacro files expanded to URDF by tools/xacro/xacro.js (the npm package xacro-parser on
// Node.js; doc/xacro.md), run as a child process. Internal to the loader: loadModelFile
// expands a path ending in .xacro with LoadOptions::xacro_args.
#pragma once
#include <string>
#include <utility>
#include <vector>

namespace mechanism_sim {

using XacroArgs = std::vector<std::pair<std::string, std::string>>;  // name:=value, in order

// The file is xacro: its name ends in ".xacro".
bool isXacroFile(const std::string& path);

// The URDF that `node xacro.js PATH name:=value...` writes. Node is `node` (else `nodejs`)
// on PATH or $MECHANISM_SIM_NODE; the script is the source tree's tools/xacro/xacro.js or
// $MECHANISM_SIM_XACRO. No shell; standard input is /dev/null; a run longer than
// timeout_s is killed. Throws LoadError "PATH: xacro: what is wrong" (one line).
std::string expandXacro(const std::string& path, const XacroArgs& args, double timeout_s = 60.0);

}  // namespace mechanism_sim
