// loadYamlFile (yaml_file.h).
#include "yaml_file.h"

#include <fstream>
#include <sstream>

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {

YAML::Node loadYamlFile(const std::string& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw LoadError(path + ": cannot open the " + what + " file");
  try {
    return YAML::Load(in);
  } catch (const YAML::Exception& e) {
    std::ostringstream os;
    os << path << ":" << e.mark.line + 1 << ": malformed YAML: " << e.msg;
    throw LoadError(os.str());
  }
}

}  // namespace mechanism_sim
