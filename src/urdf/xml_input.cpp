#include "xml_input.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <cstring>
#include <map>
#include <set>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "loop_dialects.h"
#include "mechanism_sim/core/model/joint.h"
#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace urdf_input {

using tinyxml2::XMLElement;

namespace {
constexpr const char* kPrefix = "mechanism_sim:";
const std::set<std::string> kUrdfTypes = {"fixed", "revolute", "continuous", "prismatic", "floating", "planar"};
}  // namespace

std::string XmlReader::describe(const XMLElement* e) const {
  std::string s = e->Name();
  if (const char* n = e->Attribute("name")) s += std::string(" '") + n + "'";
  return s;
}

std::string oneLine(const std::string& text, size_t limit) {
  std::string out;
  for (unsigned char c : text) {
    if (out.size() >= limit) return out + "...";
    if (c == '\n') out += "\\n";
    else if (c == '\t') out += "\\t";
    else if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

void XmlReader::fail(const XMLElement* e, const std::string& what) const {
  std::ostringstream os;
  os << file;
  if (e) os << ":" << e->GetLineNum() << ": " << oneLine(describe(e));
  os << ": " << oneLine(what, 400);
  throw LoadError(os.str());
}

// One number of attribute attr of e (text `token`, taken from the attribute text `whole`):
// finite and no larger than absurd, or a one-line error naming the attribute.
double XmlReader::parseNumber(const XMLElement* e, const char* attr, const std::string& token,
                              const char* whole, double absurd) const {
  const std::string where = std::string("attribute '") + attr + "' ";
  char* end = nullptr;
  const double x = std::strtod(token.c_str(), &end);
  if (token.empty() || *end != '\0') fail(e, where + "is not a number: '" + whole + "'");
  if (!std::isfinite(x)) fail(e, where + "is not finite: '" + whole + "'");
  if (std::fabs(x) > absurd)
    fail(e, where + "is absurdly large: '" + whole + "' (limit " + std::to_string(absurd) + ")");
  return x;
}

double XmlReader::number(const XMLElement* e, const char* attr, std::optional<double> def,
                         double absurd) const {
  const char* s = e->Attribute(attr);
  if (!s) {
    if (def) return *def;
    fail(e, std::string("missing attribute '") + attr + "'");
  }
  std::string text(s);
  text.erase(0, text.find_first_not_of(" \t\n\r"));
  text.erase(text.find_last_not_of(" \t\n\r") + 1);
  return parseNumber(e, attr, text, s, absurd);
}

std::vector<double> XmlReader::numbers(const XMLElement* e, const char* attr, size_t count,
                                       double absurd) const {
  const char* s = e->Attribute(attr);
  if (!s) fail(e, std::string("missing attribute '") + attr + "'");
  std::istringstream is(s);
  std::vector<double> out;
  std::string tok;
  while (is >> tok) out.push_back(parseNumber(e, attr, tok, s, absurd));
  if (count && out.size() != count)
    fail(e, std::string("attribute '") + attr + "' needs " + std::to_string(count) + " numbers: '" + s + "'");
  return out;
}

Vector3d XmlReader::vec3(const XMLElement* e, const char* attr, const Vector3d& def, double absurd) const {
  if (!e->Attribute(attr)) return def;
  const auto v = numbers(e, attr, 3, absurd);
  return Vector3d(v[0], v[1], v[2]);
}

Isometry3d poseFromXyzRpy(const Vector3d& xyz, const Vector3d& rpy) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(rpy.z(), Vector3d::UnitZ()) * Eigen::AngleAxisd(rpy.y(), Vector3d::UnitY()) *
                Eigen::AngleAxisd(rpy.x(), Vector3d::UnitX())).toRotationMatrix();
  T.translation() = xyz;
  return T;
}

Isometry3d XmlReader::origin(const XMLElement* e, const char* child) const {
  const XMLElement* o = e->FirstChildElement(child);
  if (!o) return Isometry3d::Identity();
  return poseFromXyzRpy(vec3(o, "xyz", Vector3d::Zero()), vec3(o, "rpy", Vector3d::Zero(), 1e3));
}

Vector3d XmlReader::direction(const XMLElement* e, const char* child, const Vector3d& def) const {
  const XMLElement* a = e->FirstChildElement(child);
  if (!a) return def;
  const Vector3d v = vec3(a, "xyz", def);
  if (v.norm() < 1e-12) fail(a, "axis is zero");
  return v.normalized();
}

std::string XmlReader::text(const XMLElement* e, const char* child) const {
  const XMLElement* c = e->FirstChildElement(child);
  if (!c || !c->GetText()) fail(e, std::string("missing <") + child + ">");
  std::string s = c->GetText();
  s.erase(0, s.find_first_not_of(" \t\n\r"));
  s.erase(s.find_last_not_of(" \t\n\r") + 1);
  return s;
}

void XmlReader::onlyAttributes(const XMLElement* e, std::initializer_list<const char*> allowed) const {
  for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next()) {
    bool ok = false;
    for (const char* name : allowed) ok = ok || std::strcmp(name, a->Name()) == 0;
    if (!ok) fail(e, std::string("unknown attribute '") + a->Name() + "'");
  }
}

// ---- standard URDF

namespace {

void checkInertial(const XMLElement* link, const XmlReader& r) {
  const XMLElement* in = link->FirstChildElement("inertial");
  if (!in) return;
  r.origin(in);
  const XMLElement* mass = in->FirstChildElement("mass");
  if (!mass) r.fail(in, "missing <mass>");
  const double m = r.number(mass, "value", std::nullopt, 1e8);
  if (m < 0) r.fail(mass, "mass is negative");
  const XMLElement* I = in->FirstChildElement("inertia");
  if (!I) r.fail(in, "missing <inertia>");
  Eigen::Matrix3d J;
  const double xx = r.number(I, "ixx", 0.0, 1e10), yy = r.number(I, "iyy", 0.0, 1e10),
               zz = r.number(I, "izz", 0.0, 1e10), xy = r.number(I, "ixy", 0.0, 1e10),
               xz = r.number(I, "ixz", 0.0, 1e10), yz = r.number(I, "iyz", 0.0, 1e10);
  J << xx, xy, xz, xy, yy, yz, xz, yz, zz;
  (void)J;  // whether it is physical is judged on the rigid body it merges into (inertiaFault)
}

}  // namespace

std::string inertiaFault(const Eigen::Matrix3d& J, double scale) {
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(J).eigenvalues();
  const double tol = 1e-9 * std::max({1e-300, scale, J.cwiseAbs().maxCoeff()});
  if (ev(0) < -tol) return "inertia has a negative principal moment";
  if (ev(2) > ev(0) + ev(1) + tol)
    return "inertia violates the triangle inequality (a principal moment exceeds the sum of the other two)";
  return "";
}

std::vector<std::string> validateStandard(const XMLElement* robot, const XmlReader& r) {
  std::map<std::string, const XMLElement*> links, joints;
  std::map<std::string, std::string> parent_of;  // child link -> joint
  for (const XMLElement* e = robot->FirstChildElement(); e; e = e->NextSiblingElement()) {
    const std::string tag = e->Name();
    if (tag == "link") {
      const char* name = e->Attribute("name");
      if (!name || !*name) r.fail(e, "link without a name");
      if (links.count(name)) r.fail(e, "duplicate link (first on line " + std::to_string(links[name]->GetLineNum()) + ")");
      links[name] = e;
      checkInertial(e, r);
    }
  }
  if (links.empty()) r.fail(robot, "the robot has no <link>");
  if (links.size() > 100000) r.fail(robot, "absurd number of links");
  for (const XMLElement* e = robot->FirstChildElement("joint"); e; e = e->NextSiblingElement("joint")) {
    const char* name = e->Attribute("name");
    if (!name || !*name) r.fail(e, "joint without a name");
    if (joints.count(name)) r.fail(e, "duplicate joint (first on line " + std::to_string(joints[name]->GetLineNum()) + ")");
    joints[name] = e;
    const char* type = e->Attribute("type");
    if (!type) r.fail(e, "missing attribute 'type'");
    if (!kUrdfTypes.count(type))
      r.fail(e, std::string("unknown joint type '") + type +
                    "' (URDF: fixed, revolute, continuous, prismatic, floating, planar; others go in <mechanism_sim:joint>)");
    const XMLElement* p = e->FirstChildElement("parent");
    const XMLElement* c = e->FirstChildElement("child");
    if (!p || !p->Attribute("link")) r.fail(e, "missing <parent link=...>");
    if (!c || !c->Attribute("link")) r.fail(e, "missing <child link=...>");
    const std::string pl = p->Attribute("link"), cl = c->Attribute("link");
    if (!links.count(pl)) r.fail(p, "parent link '" + pl + "' does not exist");
    if (!links.count(cl)) r.fail(c, "child link '" + cl + "' does not exist");
    if (pl == cl) r.fail(e, "joint's parent is its child ('" + pl + "')");
    if (parent_of.count(cl)) r.fail(e, "link '" + cl + "' already has parent joint '" + parent_of[cl] + "' (close loops with <mechanism_sim:joint>)");
    parent_of[cl] = name;
    r.origin(e);
    const std::string t = type;
    if (t == "revolute" || t == "continuous" || t == "prismatic" || t == "planar") r.direction(e, "axis", Vector3d::UnitX());
    if (const XMLElement* lim = e->FirstChildElement("limit")) {
      // any finite value: SDF's "no limit", +-1e16, is read by the loader (joint_specs.cpp)
      const double big = std::numeric_limits<double>::max();
      const double lo = r.number(lim, "lower", 0.0, big), hi = r.number(lim, "upper", 0.0, big);
      // A fixed or continuous joint has no bounds (URDF reads lower and upper for revolute and
      // prismatic joints only; urdfdom parses and ignores them)
      if (lo > hi && t != "fixed" && t != "continuous") r.fail(lim, "lower limit exceeds upper limit");
      // URDF requires both (urdfdom refuses the file without them, naming no joint)
      if (t == "revolute" || t == "prismatic")
        for (const char* a : {"effort", "velocity"})
          if (!lim->Attribute(a))
            r.fail(lim, std::string("missing attribute '") + a + "' (URDF requires effort and velocity in <limit>)");
      if (r.number(lim, "effort", 0.0, 1e9) < 0) r.fail(lim, "effort limit is negative");
      if (r.number(lim, "velocity", 0.0, 1e9) < 0) r.fail(lim, "velocity limit is negative");
    } else if (t == "revolute" || t == "prismatic") {
      r.fail(e, "a " + t + " joint needs <limit> (use 'continuous' for an unlimited revolute)");
    }
    if (const XMLElement* dyn = e->FirstChildElement("dynamics")) {
      if (r.number(dyn, "damping", 0.0, 1e9) < 0) r.fail(dyn, "damping is negative");
      if (r.number(dyn, "friction", 0.0, 1e9) < 0) r.fail(dyn, "friction is negative");
    }
  }
  for (const XMLElement* e = robot->FirstChildElement("joint"); e; e = e->NextSiblingElement("joint"))
    if (const XMLElement* mimic = e->FirstChildElement("mimic")) {
      const char* j = mimic->Attribute("joint");
      if (!j || !joints.count(j)) r.fail(mimic, std::string("mimics unknown joint '") + (j ? j : "") + "'");
      if (std::string(j) == e->Attribute("name")) r.fail(mimic, "a joint cannot mimic itself");
      r.number(mimic, "multiplier", 1.0);
      r.number(mimic, "offset", 0.0);
    }
  // Exactly one root, and every link reachable from it (no cycles).
  std::vector<std::string> roots;  // in file order
  for (const XMLElement* e = robot->FirstChildElement("link"); e; e = e->NextSiblingElement("link"))
    if (!parent_of.count(e->Attribute("name"))) roots.push_back(e->Attribute("name"));
  if (roots.empty()) r.fail(robot, "the joints form a cycle: no root link");
  for (const auto& l : links) {
    std::string at = l.first;
    size_t hops = 0;
    while (parent_of.count(at) && hops++ <= links.size())
      at = joints[parent_of[at]]->FirstChildElement("parent")->Attribute("link");
    if (hops > links.size()) r.fail(links[l.first], "link is on a cycle of joints");
  }
  return roots;
}

// ---- extension

namespace {

ExtJoint readExtJoint(const XMLElement* e, const XmlReader& r) {
  r.onlyAttributes(e, {"name", "type", "lead"});
  ExtJoint j;
  j.element = e;
  if (!e->Attribute("name")) r.fail(e, "missing attribute 'name'");
  if (!e->Attribute("type")) r.fail(e, "missing attribute 'type'");
  j.name = e->Attribute("name");
  j.type = e->Attribute("type");
  try {
    jointTypeInfo(j.type == "continuous" ? "revolute" : j.type);  // the core's joint types
  } catch (const ModelError&) {
    r.fail(e, "unknown joint type '" + j.type + "'");
  }
  if (j.type == "screw") {
    const double lead = r.number(e, "lead", std::nullopt, 1e3);
    if (lead == 0.0) r.fail(e, "screw lead is zero (a screw of zero lead is a revolute joint)");
    j.alpha = lead / (2.0 * M_PI);
  } else if (e->Attribute("lead")) {
    r.fail(e, "attribute 'lead' belongs to screw joints");
  }
  for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
    const std::string tag = c->Name();
    if (tag == "parent" || tag == "child") {
      r.onlyAttributes(c, {"link"});
      if (!c->Attribute("link")) r.fail(c, "missing attribute 'link'");
      (tag == "parent" ? j.parent : j.child) = c->Attribute("link");
    } else if (tag == "origin" || tag == "child_origin") {
      r.onlyAttributes(c, {"xyz", "rpy"});
    } else if (tag == "axis" || tag == "axis2") {
      r.onlyAttributes(c, {"xyz"});
    } else if (tag == "dynamics") {
      r.onlyAttributes(c, {"damping", "friction"});
      j.damping = r.number(c, "damping", 0.0, 1e9);
      j.friction = r.number(c, "friction", 0.0, 1e9);
      if (j.damping < 0 || j.friction < 0) r.fail(c, "damping and friction must be >= 0");
    } else {
      r.fail(c, "unknown element in <mechanism_sim:joint>");
    }
  }
  j.loop = !j.parent.empty() || !j.child.empty();
  if (j.loop && (j.parent.empty() || j.child.empty())) r.fail(e, "a loop-closure joint needs both <parent> and <child>");
  j.origin = r.origin(e, "origin");
  j.child_origin = r.origin(e, "child_origin");
  j.axis = r.direction(e, "axis", Vector3d::UnitZ());
  j.has_axis2 = e->FirstChildElement("axis2") != nullptr;
  j.axis2 = r.direction(e, "axis2", Vector3d::UnitY());
  if (j.type == "universal" && !j.has_axis2) r.fail(e, "a universal joint needs <axis2>");
  return j;
}

// <gazebo><joint name type><pose>..</pose><parent>..</parent><child>..</child><axis><xyz>..
ExtJoint readSdfJoint(const XMLElement* e, const XmlReader& r, std::vector<std::string>* notes) {
  ExtJoint j;
  j.element = e;
  j.sdf = true;
  j.loop = true;
  if (!e->Attribute("name")) r.fail(e, "missing attribute 'name'");
  if (!e->Attribute("type")) r.fail(e, "missing attribute 'type'");
  j.name = e->Attribute("name");
  const std::string type = e->Attribute("type");
  static const std::map<std::string, std::string> types = {
      {"revolute", "revolute"}, {"continuous", "revolute"}, {"prismatic", "prismatic"}, {"ball", "spherical"},
      {"universal", "universal"}, {"screw", "screw"}, {"fixed", "fixed"}};
  if (type == "revolute2" || type == "gearbox")
    r.fail(e, "unsupported SDF joint type '" + type + "': write it as " +
                  (type == "revolute2" ? "a universal joint (perpendicular axes)" : "a <mimic> of the two joints it gears"));
  if (!types.count(type))
    r.fail(e, "unsupported SDF joint type '" + oneLine(type) + "' (revolute, continuous, prismatic, ball, universal, screw, fixed)");
  j.type = types.at(type);
  j.parent = r.text(e, "parent");
  j.child = r.text(e, "child");
  if (const XMLElement* pose = e->FirstChildElement("pose")) {
    // SDF 1.7+: the pose in the frame relative_to names (default: the child link)
    if (const char* to = pose->Attribute("relative_to"); to && *to && std::string(to) != j.child)
      j.pose_relative_to = to;
    if (pose->Attribute("degrees") || pose->Attribute("rotation_format"))
      r.fail(pose, "degrees and rotation_format are not read on a joint pose: write x y z roll pitch yaw in radians");
    std::istringstream is(pose->GetText() ? pose->GetText() : "");
    double v[6];
    for (double& x : v)
      if (!(is >> x) || !std::isfinite(x) || std::fabs(x) > 1e6) r.fail(pose, "pose needs six finite numbers");
    j.child_origin = poseFromXyzRpy(Vector3d(v[0], v[1], v[2]), Vector3d(v[3], v[4], v[5]));
  }
  auto sdfAxis = [&](const char* tag, Vector3d* out) {
    const XMLElement* a = e->FirstChildElement(tag);
    if (!a) return false;
    const XMLElement* xyz = a->FirstChildElement("xyz");
    if (!xyz || !xyz->GetText()) r.fail(a, "missing <xyz>");
    std::istringstream is(xyz->GetText());
    Vector3d v;
    if (!(is >> v.x() >> v.y() >> v.z()) || !v.allFinite()) r.fail(xyz, "axis needs three finite numbers");
    if (v.norm() < 1e-12) r.fail(xyz, "axis is zero");
    *out = v.normalized();
    if (const XMLElement* dyn = a->FirstChildElement("dynamics")) {  // SDF joint dynamics
      for (const char* tag : {"damping", "friction"}) {
        const XMLElement* d = dyn->FirstChildElement(tag);
        if (!d || !d->GetText()) continue;
        char* end = nullptr;
        const double value = std::strtod(d->GetText(), &end);
        if (!std::isfinite(value) || value < 0 || value > 1e9) r.fail(d, std::string(tag) + " must be finite and >= 0");
        (tag[0] == 'd' ? j.damping : j.friction) = value;
      }
    }
    const char* in = xyz->Attribute("expressed_in");
    const XMLElement* upm = a->FirstChildElement("use_parent_model_frame");
    if ((in && std::string(in) == "__model__") ||
        (upm && upm->GetText() && std::string(upm->GetText()).find("true") != std::string::npos))
      j.axis_in_model = true;
    else if (in && *in && std::string(in) != j.name) {  // (the joint's own frame is the default)
      if (!j.axis_expressed_in.empty() && j.axis_expressed_in != in)
        r.fail(xyz, "axis and axis2 expressed in different frames: express both in one");
      j.axis_expressed_in = in;
    }
    return true;
  };
  if (!sdfAxis("axis", &j.axis) && j.type != "spherical" && j.type != "fixed") r.fail(e, "missing <axis>");
  j.has_axis2 = sdfAxis("axis2", &j.axis2);
  if (j.type == "universal" && !j.has_axis2) r.fail(e, "a universal joint needs <axis2>");
  if (j.type == "screw") {
    // SDF 1.10 screw_thread_pitch: metres per revolution, right-handed positive.
    // Gazebo classic thread_pitch: radians per metre, positive = left-handed.
    if (const XMLElement* p = e->FirstChildElement("screw_thread_pitch")) {
      const double lead = std::atof(p->GetText() ? p->GetText() : "0");
      if (lead == 0.0 || !std::isfinite(lead)) r.fail(p, "screw_thread_pitch must be finite and non-zero");
      j.alpha = lead / (2.0 * M_PI);
    } else if (const XMLElement* p2 = e->FirstChildElement("thread_pitch")) {
      const double tp = std::atof(p2->GetText() ? p2->GetText() : "0");
      if (tp == 0.0 || !std::isfinite(tp)) r.fail(p2, "thread_pitch must be finite and non-zero");
      j.alpha = -1.0 / tp;
    } else {  // SDF's default thread_pitch, 1, which Gazebo classic's ScrewJoint::Load takes with a warning
      j.alpha = -1.0;
      notes->push_back(r.file + ":" + std::to_string(e->GetLineNum()) + ": SDF screw joint '" + j.name +
                       "' has no <screw_thread_pitch> or <thread_pitch>: SDF's default thread_pitch 1 (radians per metre, "
                       "left-handed: 6.28 m per turn) is used, as Gazebo does; give the pitch");
    }
  }
  return j;
}

}  // namespace

Extension readExtension(const XMLElement* robot, const XmlReader& r) {
  Extension ext;
  for (const XMLElement* e = robot->FirstChildElement(); e; e = e->NextSiblingElement()) {
    const std::string tag = e->Name();
    if (tag == "gazebo") {
      for (const XMLElement* j = e->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
        ext.joints.push_back(readSdfJoint(j, r, &ext.notes));
        // Gazebo classic converts the URDF's joints into its model and then adds the <gazebo>
        // block's SDF joints, as joints of their own: an SDF joint named as a URDF joint (PR2's
        // gripper_v0 closes the fingers with an SDF 'r_gripper_joint' beside the URDF gap
        // joint 'r_gripper_joint') is a second joint. The URDF joint keeps its name (joint
        // states, drives and initial values name it); the loop closure is '<name> (gazebo)'.
        ExtJoint& sdf = ext.joints.back();
        bool urdf_name = false;
        for (const XMLElement* u = robot->FirstChildElement("joint"); u && !urdf_name; u = u->NextSiblingElement("joint"))
          urdf_name = u->Attribute("name") && sdf.name == u->Attribute("name");
        if (urdf_name) {
          const std::string urdf_joint = sdf.name;
          sdf.name += " (gazebo)";
          ext.notes.push_back(r.file + ":" + std::to_string(j->GetLineNum()) + ": the <gazebo> block's SDF joint '" +
                              urdf_joint + "' is a joint of its own beside the URDF joint '" + urdf_joint +
                              "', as in Gazebo: the loop closure '" + sdf.name + "'");
        }
      }
      continue;
    }
    if (readLoopDialect(robot, e, r, &ext)) continue;
    if (tag.rfind(kPrefix, 0) != 0) continue;
    const std::string what = tag.substr(std::strlen(kPrefix));
    if (what == "joint") {
      ext.joints.push_back(readExtJoint(e, r));
    } else if (what == "spring") {
      r.onlyAttributes(e, {"name", "stiffness", "damping", "rest_length", "force"});
      ExtSpring s;
      s.element = e;
      s.name = e->Attribute("name") ? e->Attribute("name") : "";
      if (s.name.empty()) r.fail(e, "missing attribute 'name'");
      s.k = r.number(e, "stiffness", 0.0, 1e12);
      s.c = r.number(e, "damping", 0.0, 1e12);
      s.force = r.number(e, "force", 0.0, 1e12);
      if (e->Attribute("rest_length")) s.rest_length = r.number(e, "rest_length", std::nullopt);
      if (s.k < 0 || s.c < 0 || (s.rest_length && *s.rest_length < 0)) r.fail(e, "stiffness, damping and rest_length must be >= 0");
      for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
        const std::string ct = c->Name();
        if (ct != "from" && ct != "to") r.fail(c, "unknown element in <mechanism_sim:spring> (from, to)");
        r.onlyAttributes(c, {"link", "xyz"});
        if (!c->Attribute("link")) r.fail(c, "missing attribute 'link'");
        (ct == "from" ? s.link1 : s.link2) = c->Attribute("link");
        (ct == "from" ? s.p1 : s.p2) = r.vec3(c, "xyz", Vector3d::Zero());
      }
      if (s.link1.empty() || s.link2.empty()) r.fail(e, "a spring needs <from link=...> and <to link=...>");
      ext.springs.push_back(s);
    } else if (what == "initial") {
      r.onlyAttributes(e, {"joint", "position", "velocity"});
      ExtInitial in;
      in.element = e;
      if (!e->Attribute("joint")) r.fail(e, "missing attribute 'joint'");
      in.dof = e->Attribute("joint");
      if (e->Attribute("position")) in.position = r.number(e, "position", std::nullopt);
      if (e->Attribute("velocity")) in.velocity = r.number(e, "velocity", std::nullopt);
      ext.initial.push_back(in);
    } else if (what == "drive") {
      r.onlyAttributes(e, {"joint", "dof", "velocity", "profile", "offset", "amplitude", "frequency", "phase"});
      ExtDrive d;
      d.element = e;
      if (!e->Attribute("joint")) r.fail(e, "missing attribute 'joint'");
      d.dof = e->Attribute("joint");
      if (const char* dof = e->Attribute("dof")) d.dof += std::string(".") + dof;
      const char* profile = e->Attribute("profile");
      if (!profile && !e->Attribute("velocity")) r.fail(e, "a drive needs velocity=\"V\" or profile=\"harmonic|spline\"");
      if (profile && e->Attribute("velocity")) r.fail(e, "a drive takes velocity or a profile, not both");
      d.profile = profile ? profile : "velocity";
      auto none = [&](std::initializer_list<const char*> attrs) {
        for (const char* a : attrs)
          if (e->Attribute(a)) r.fail(e, std::string("attribute '") + a + "' does not belong to a " + d.profile + " drive");
      };
      if (d.profile == "velocity") {
        none({"offset", "amplitude", "frequency", "phase"});
        d.velocity = r.number(e, "velocity", std::nullopt);
      } else if (d.profile == "harmonic") {
        d.offset = r.number(e, "offset", 0.0);
        d.amplitude = r.number(e, "amplitude", std::nullopt);
        d.frequency = r.number(e, "frequency", std::nullopt);
        d.phase = r.number(e, "phase", 0.0);
        if (d.frequency < 0) r.fail(e, "frequency must be >= 0");
      } else if (d.profile == "spline") {
        none({"offset", "amplitude", "frequency", "phase"});
        for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
          if (std::string(c->Name()) != "point") r.fail(c, "unknown element in <mechanism_sim:drive> (point)");
          r.onlyAttributes(c, {"t", "position"});
          const double t = r.number(c, "t", std::nullopt);
          if (!d.t.empty() && !(t > d.t.back()))
          {
            std::ostringstream os;
            os << "spline points must be in increasing time (t = " << t << " after " << d.t.back() << ")";
            r.fail(c, os.str());
          }
          d.t.push_back(t);
          d.position.push_back(r.number(c, "position", std::nullopt));
        }
        if (d.t.size() < 2) r.fail(e, "a spline drive needs at least 2 <point t=... position=.../>");
      } else {
        r.fail(e, "unknown drive profile '" + oneLine(profile) + "' (harmonic, spline; or velocity=\"V\")");
      }
      if (d.profile != "spline" && e->FirstChildElement()) r.fail(e->FirstChildElement(), "only a spline drive has <point> elements");
      ext.drives.push_back(d);
    } else if (what == "gravity") {
      r.onlyAttributes(e, {"xyz"});
      ext.gravity = r.vec3(e, "xyz", Vector3d(0, 0, -9.81), 1e4);
    } else if (what == "actuator") {
      // read with the transmissions (transmissions.cpp)
    } else if (what == "coupling") {
      ext.linear_couplings.push_back(readLinearCoupling(e, r));  // (couplings.h)
    } else {
      r.fail(e, "unknown extension element (joint, spring, initial, drive, gravity, actuator, coupling)");
    }
  }
  readOnshapeClosures(robot, r, &ext);
  return ext;
}

}  // namespace urdf_input
}  // namespace mechanism_sim
