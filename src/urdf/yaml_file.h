// A YAML file the loader reads beside a description (an Extended-URDF closures file, an
// actuators file): its document, or a LoadError naming the file and the line.
#pragma once
#include <string>

#include <yaml-cpp/yaml.h>

namespace mechanism_sim {

// what: the kind of file, for the message ("closures", "actuators").
YAML::Node loadYamlFile(const std::string& path, const std::string& what);

}  // namespace mechanism_sim
