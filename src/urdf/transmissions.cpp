// <transmission>, <mechanism_sim:actuator> and actuators YAML files (transmissions.h).
#include "transmissions.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "yaml_file.h"

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace urdf_input {
namespace {

using tinyxml2::XMLElement;

// The actuator properties, as attribute and YAML key names.
struct Property {
  const char* key;
  double ActuatorRatings::*field;
};
constexpr Property kProperties[] = {
    {"rotor_inertia", &ActuatorRatings::rotor_inertia},     {"rated_torque", &ActuatorRatings::rated_torque},
    {"peak_torque", &ActuatorRatings::peak_torque},         {"stall_torque", &ActuatorRatings::stall_torque},
    {"no_load_speed", &ActuatorRatings::no_load_speed},     {"max_speed", &ActuatorRatings::max_speed},
    {"torque_constant", &ActuatorRatings::torque_constant}, {"resistance", &ActuatorRatings::resistance},
    {"friction", &ActuatorRatings::friction},               {"damping", &ActuatorRatings::damping}};

// The type a <transmission> declares: its <type> child (ros_control), else its type
// attribute (the PR2 form).
std::string typeOf(const XMLElement* t) {
  if (const XMLElement* c = t->FirstChildElement("type"); c && c->GetText()) {
    std::string s = c->GetText();
    s.erase(0, s.find_first_not_of(" \t\r\n"));
    s.erase(s.find_last_not_of(" \t\r\n") + 1);
    return s;
  }
  return t->Attribute("type") ? t->Attribute("type") : "";
}

bool typeFor(const std::string& type, TransmissionType* out) {
  if (type == "transmission_interface/SimpleTransmission" || type == "pr2_mechanism_model/SimpleTransmission" ||
      type == "SimpleTransmission")
    *out = TransmissionType::kSimple;
  else if (type == "transmission_interface/DifferentialTransmission")
    *out = TransmissionType::kDifferential;
  else if (type == "transmission_interface/FourBarLinkageTransmission")
    *out = TransmissionType::kFourBar;
  else
    return false;
  return true;
}

// The number in child `tag` of e, or def when there is none.
double childNumber(const XMLElement* e, const char* tag, double def, const XmlReader& r) {
  const XMLElement* c = e->FirstChildElement(tag);
  if (!c) return def;
  const char* text = c->GetText();
  char* end = nullptr;
  const double v = text ? std::strtod(text, &end) : 0.0;
  if (!text || end == text || *(end + std::strspn(end, " \t\r\n")) != '\0' || !std::isfinite(v))
    r.fail(e, std::string("<") + tag + "> is not a finite number: '" + (text ? text : "") + "'");
  return v;
}

// A core error's text without the "kind 'name': " it starts with (the element names it).
std::string withoutName(const std::string& what) {
  const size_t at = what.find("': ");
  return at == std::string::npos ? what : what.substr(at + 3);
}

std::string nameOf(const XMLElement* e, const XmlReader& r) {
  const char* n = e->Attribute("name");
  if (!n || !*n) r.fail(e, "has no name");
  return n;
}

// The elements of a two-joint transmission in role order (<role>joint1</role>, joint2;
// actuator1, actuator2), as ros_control's loaders take them.
std::vector<const XMLElement*> byRole(const XMLElement* t, const char* tag, const XmlReader& r) {
  std::vector<const XMLElement*> out(2, nullptr);
  int count = 0;
  for (const XMLElement* e = t->FirstChildElement(tag); e; e = e->NextSiblingElement(tag)) {
    ++count;
    const XMLElement* role = e->FirstChildElement("role");
    const std::string text = role && role->GetText() ? role->GetText() : "";
    const std::string want1 = std::string(tag) + "1", want2 = std::string(tag) + "2";
    const int k = text == want1 ? 0 : text == want2 ? 1 : -1;
    if (k < 0) r.fail(e, std::string("needs <role>") + want1 + "</role> or <role>" + want2 + "</role>");
    if (out[k]) r.fail(e, "a second " + text);
    out[k] = e;
  }
  if (count != 2 || !out[0] || !out[1]) r.fail(t, std::string("needs two <") + tag + "> elements, roles " + tag + "1 and " + tag + "2");
  return out;
}

TransmissionSpec readOne(const XMLElement* t, TransmissionType type, const XmlReader& r) {
  TransmissionSpec s;
  s.element = t;
  s.map.name = nameOf(t, r);
  s.map.type = type;
  if (type == TransmissionType::kSimple) {
    const XMLElement* j = t->FirstChildElement("joint");
    const XMLElement* a = t->FirstChildElement("actuator");
    if (!j || j->NextSiblingElement("joint")) r.fail(t, "a SimpleTransmission names one <joint>");
    if (!a || a->NextSiblingElement("actuator")) r.fail(t, "a SimpleTransmission names one <actuator>");
    // ros_control: <mechanicalReduction> in the actuator; the PR2 form: in the transmission
    // (none: 1, as gazebo_ros_control's transmission parser reads it, with a note)
    const bool in_actuator = a->FirstChildElement("mechanicalReduction") != nullptr;
    if (!in_actuator && !t->FirstChildElement("mechanicalReduction"))
      s.note = "transmission '" + s.map.name + "' gives no <mechanicalReduction>: 1, as gazebo_ros_control reads it";
    s.map.actuator_reduction = {in_actuator ? childNumber(a, "mechanicalReduction", 1.0, r)
                                            : childNumber(t, "mechanicalReduction", 1.0, r)};
    s.map.joint_reduction = {1.0};
    s.map.joint_offset = {childNumber(j, "offset", 0.0, r)};
    s.joints = {nameOf(j, r)};
    s.actuators = {nameOf(a, r)};
  } else {
    const std::vector<const XMLElement*> js = byRole(t, "joint", r), as = byRole(t, "actuator", r);
    for (int k = 0; k < 2; ++k) {
      if (!as[k]->FirstChildElement("mechanicalReduction")) r.fail(as[k], "has no <mechanicalReduction>");
      s.map.actuator_reduction.push_back(childNumber(as[k], "mechanicalReduction", 1.0, r));
      s.map.joint_reduction.push_back(childNumber(js[k], "mechanicalReduction", 1.0, r));
      s.map.joint_offset.push_back(childNumber(js[k], "offset", 0.0, r));
      s.joints.push_back(nameOf(js[k], r));
      s.actuators.push_back(nameOf(as[k], r));
    }
    if (s.joints[0] == s.joints[1]) r.fail(t, "names joint '" + s.joints[0] + "' twice");
    if (s.actuators[0] == s.actuators[1]) r.fail(t, "names actuator '" + s.actuators[0] + "' twice");
  }
  try {
    s.map.validate();
  } catch (const ModelError& e) {
    r.fail(t, withoutName(e.what()));
  }
  return s;
}

}  // namespace

Transmissions readTransmissions(const XMLElement* robot, const XmlReader& r) {
  Transmissions out;
  std::map<std::string, const XMLElement*> actuator_of;  // actuator -> its transmission
  std::map<std::string, const XMLElement*> joint_of;
  for (const XMLElement* t = robot->FirstChildElement("transmission"); t; t = t->NextSiblingElement("transmission")) {
    const std::string type = typeOf(t);
    TransmissionType tt;
    if (!typeFor(type, &tt)) {
      ++out.ignored[type.empty() ? "(no type)" : type];
      continue;
    }
    TransmissionSpec s = readOne(t, tt, r);
    // the same transmission again (files write one per hardware interface: franka_ros's
    // position, velocity and effort ones) is read once; a different one on the same
    // joints or actuators contradicts it
    bool repeated = false;
    for (const TransmissionSpec& o : out.simulated)
      repeated = repeated || (o.map.type == s.map.type && o.joints == s.joints && o.actuators == s.actuators &&
                              o.map.actuator_reduction == s.map.actuator_reduction &&
                              o.map.joint_reduction == s.map.joint_reduction && o.map.joint_offset == s.map.joint_offset);
    if (repeated) {
      ++out.repeated;
      continue;
    }
    for (const std::string& a : s.actuators) {
      if (actuator_of.count(a)) r.fail(t, "actuator '" + a + "' is in another transmission already");
      actuator_of[a] = t;
      out.actuators[a] = ActuatorSpec();
    }
    for (const std::string& j : s.joints) {
      if (joint_of.count(j)) r.fail(t, "joint '" + j + "' is in another transmission already");
      joint_of[j] = t;
    }
    out.simulated.push_back(std::move(s));
  }
  for (const XMLElement* e = robot->FirstChildElement("mechanism_sim:actuator"); e;
       e = e->NextSiblingElement("mechanism_sim:actuator")) {
    const std::string name = nameOf(e, r);
    std::vector<const char*> allowed{"name"};
    for (const Property& p : kProperties) allowed.push_back(p.key);
    for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next()) {
      bool known = false;
      for (const char* k : allowed) known = known || std::string(a->Name()) == k;
      if (!known) r.fail(e, std::string("unknown attribute '") + a->Name() + "' (rotor_inertia, rated_torque, peak_torque, "
                                "stall_torque, no_load_speed, max_speed, torque_constant, resistance, friction, damping)");
    }
    const auto it = out.actuators.find(name);
    if (it == out.actuators.end())
      r.fail(e, "no transmission of a simulated type names actuator '" + name + "'");
    if (it->second.element) r.fail(e, "actuator '" + name + "' is described twice");
    ActuatorSpec& spec = it->second;
    spec.element = e;
    spec.source = r.file + ":" + std::to_string(e->GetLineNum());
    for (const Property& p : kProperties)
      if (e->Attribute(p.key)) spec.ratings.*p.field = r.number(e, p.key, std::nullopt, 1e12);
    try {
      spec.ratings.validate(name);
    } catch (const ModelError& err) {
      r.fail(e, withoutName(err.what()));
    }
  }
  return out;
}

void readActuatorsFile(const std::string& path, Transmissions& into) {
  if (path.empty()) return;
  const YAML::Node doc = loadYamlFile(path, "actuators");
  auto fail = [&](const YAML::Node& n, const std::string& what) {
    std::ostringstream os;
    os << path;
    if (n.Mark().line >= 0) os << ":" << n.Mark().line + 1;
    throw LoadError(os.str() + ": " + oneLine(what, 400));
  };
  const YAML::Node list = doc.IsMap() ? doc["actuators"] : YAML::Node();
  if (!list || !list.IsMap()) fail(doc, "an actuators file is a map 'actuators:' of NAME: {rotor_inertia: ..., ...}");
  for (const auto& entry : list) {
    const std::string name = entry.first.as<std::string>();
    const auto it = into.actuators.find(name);
    if (it == into.actuators.end()) fail(entry.first, "no transmission of a simulated type names actuator '" + name + "'");
    if (!entry.second.IsMap()) fail(entry.second, "actuator '" + name + "': a map of properties is needed");
    ActuatorSpec& spec = it->second;
    for (const auto& kv : entry.second) {
      const std::string key = kv.first.as<std::string>();
      const Property* p = nullptr;
      for (const Property& q : kProperties)
        if (key == q.key) p = &q;
      if (!p) fail(kv.first, "actuator '" + name + "': unknown property '" + key + "'");
      double v = 0;
      try {
        v = kv.second.as<double>();
      } catch (const YAML::Exception&) {
        fail(kv.second, "actuator '" + name + "': " + key + " is not a number");
      }
      spec.ratings.*(p->field) = v;
    }
    spec.source = path;
    try {
      spec.ratings.validate(name);
    } catch (const ModelError& err) {
      fail(entry.first, err.what());
    }
  }
}

}  // namespace urdf_input
}  // namespace mechanism_sim
