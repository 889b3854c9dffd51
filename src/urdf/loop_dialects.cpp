#include "loop_dialects.h"

#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "yaml_file.h"

#include "mechanism_sim/urdf/model.h"

namespace mechanism_sim {
namespace urdf_input {

using tinyxml2::XMLElement;

namespace {

std::string attr(const XMLElement* e, const char* name) {
  const char* v = e->Attribute(name);
  return v ? v : "";
}

const XMLElement* linkElement(const XMLElement* robot, const std::string& name) {
  for (const XMLElement* l = robot->FirstChildElement("link"); l; l = l->NextSiblingElement("link"))
    if (attr(l, "name") == name) return l;
  return nullptr;
}

// The link named by attribute `attribute` of e, which must exist.
std::string linkOf(const XMLElement* robot, const XMLElement* e, const char* attribute, const XmlReader& r) {
  if (!e->Attribute(attribute)) r.fail(e, std::string("missing attribute '") + attribute + "' (the link this side is on)");
  const std::string name = attr(e, attribute);
  if (!linkElement(robot, name)) r.fail(e, "link '" + name + "' does not exist");
  return name;
}

// The required child `tag` of e.
const XMLElement* child(const XMLElement* e, const char* tag, const XmlReader& r, const std::string& hint) {
  const XMLElement* c = e->FirstChildElement(tag);
  if (!c) r.fail(e, std::string("missing <") + tag + ">" + (hint.empty() ? "" : " (" + hint + ")"));
  return c;
}

std::string nameOf(const XMLElement* e, const XmlReader& r) {
  if (!e->Attribute("name") || !*e->Attribute("name")) r.fail(e, "missing attribute 'name'");
  return attr(e, "name");
}

// A rotation taking `from` onto the unit vector `to`.
Isometry3d turn(const Vector3d& from, const Vector3d& to) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond::FromTwoVectors(from, to).toRotationMatrix();
  return T;
}

// What every loop-closure element starts with: only `name` and `type` attributes, its name,
// and its type mapped to the core's by `types` (`unknown` names a type not in it, `known`
// lists the accepted ones for the message).
ExtJoint loopClosure(const XMLElement* e, const XmlReader& r, const std::map<std::string, std::string>& types,
                     const char* unknown, const char* known) {
  r.onlyAttributes(e, {"name", "type"});
  ExtJoint j;
  j.element = e;
  j.loop = true;
  j.name = nameOf(e, r);
  const std::string type = attr(e, "type");
  if (!types.count(type))
    r.fail(e, (e->Attribute("type") ? std::string(unknown) + " '" + oneLine(type) + "'" : std::string("missing attribute 'type'")) +
                  " (" + known + ")");
  j.type = types.at(type);
  return j;
}

// ---- Dojo.jl: <loop_joint name type><link1 link xyz rpy/><link2 link xyz rpy/><axis xyz/>
// (DojoEnvironments' fourbar.urdf; Dojo's parser parse_loop_joint reads link1's pose, the
// position only of link2 and <dynamics damping>). Semantics kept: the axis (default 1 0 0)
// is in link1's loop frame; link2's rpy is ignored, its rotation being the one that makes
// the two frames coincide at the file's zero pose (Dojo's "determined by the mechanism's
// structure").
ExtJoint readDojoLoopJoint(const XMLElement* robot, const XMLElement* e, const XmlReader& r) {
  static const std::map<std::string, std::string> types = {
      {"revolute", "revolute"}, {"continuous", "revolute"}, {"prismatic", "prismatic"}, {"fixed", "fixed"},
      {"spherical", "spherical"}, {"cylindrical", "cylindrical"}, {"planar", "planar"}};
  ExtJoint j = loopClosure(e, r, types, "unsupported loop joint type",
                           "revolute, continuous, prismatic, fixed, spherical, cylindrical, planar");
  j.child_rotation_from_zero_pose = true;
  const XMLElement* l1 = e->FirstChildElement("link1");
  const XMLElement* l2 = e->FirstChildElement("link2");
  if (!l1 || !l2) r.fail(e, "a Dojo loop joint needs both <link1 link=... xyz rpy> and <link2 link=... xyz>");
  for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
    const std::string tag = c->Name();
    if (tag == "link1" || tag == "link2") r.onlyAttributes(c, {"link", "xyz", "rpy"});
    else if (tag == "axis") r.onlyAttributes(c, {"xyz"});
    else if (tag == "dynamics") r.onlyAttributes(c, {"damping", "friction"});
    else r.fail(c, "unknown element in a Dojo loop joint (link1, link2, axis, dynamics)");
  }
  j.parent = linkOf(robot, l1, "link", r);
  j.child = linkOf(robot, l2, "link", r);
  j.origin = poseFromXyzRpy(r.vec3(l1, "xyz", Vector3d::Zero()), r.vec3(l1, "rpy", Vector3d::Zero(), 1e3));
  r.vec3(l2, "rpy", Vector3d::Zero(), 1e3);  // read (and checked), not used: see above
  j.child_origin = poseFromXyzRpy(r.vec3(l2, "xyz", Vector3d::Zero()), Vector3d::Zero());
  j.axis = r.direction(e, "axis", Vector3d::UnitX());
  if (const XMLElement* d = e->FirstChildElement("dynamics")) {
    j.damping = r.number(d, "damping", 0.0, 1e9);
    j.friction = r.number(d, "friction", 0.0, 1e9);
    if (j.damping < 0 || j.friction < 0) r.fail(d, "damping and friction must be >= 0");
  }
  return j;
}

// ---- URDF+ (Chignoli et al., "URDF+: An Enhanced URDF for Robots with Kinematic Loops",
// 2024; parser: the urdfdom fork of ROAM-Lab-ND/generalized_rbda, parseLoopConstraint):
// <loop name type><predecessor link><origin/></predecessor><successor link><origin/>
// </successor><axis xyz/></loop>. Each origin is its constraint frame in its own link; the
// two frames coincide up to the joint's motion; the axis (default 1 0 0, as that parser) is
// in the predecessor's frame. Types: revolute, continuous, prismatic, fixed, planar.
ExtJoint readUrdfPlusLoop(const XMLElement* robot, const XMLElement* e, const XmlReader& r) {
  static const std::map<std::string, std::string> types = {
      {"revolute", "revolute"}, {"continuous", "revolute"}, {"prismatic", "prismatic"}, {"fixed", "fixed"},
      {"planar", "planar"}};
  ExtJoint j = loopClosure(e, r, types, "unknown URDF+ loop type", "revolute, continuous, prismatic, fixed, planar");
  const XMLElement* p = child(e, "predecessor", r, "<predecessor link=...><origin xyz rpy/></predecessor>");
  const XMLElement* s = child(e, "successor", r, "<successor link=...><origin xyz rpy/></successor>");
  for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
    const std::string tag = c->Name();
    if (tag == "predecessor" || tag == "successor") {
      r.onlyAttributes(c, {"link"});
      for (const XMLElement* o = c->FirstChildElement(); o; o = o->NextSiblingElement())
        if (std::string(o->Name()) != "origin") r.fail(o, "unknown element in <" + tag + "> (origin)");
    } else if (tag == "axis") {
      r.onlyAttributes(c, {"xyz"});
    } else {
      r.fail(c, "unknown element in a URDF+ loop (predecessor, successor, axis)");
    }
  }
  j.parent = linkOf(robot, p, "link", r);
  j.child = linkOf(robot, s, "link", r);
  j.origin = r.origin(p);
  j.child_origin = r.origin(s);
  j.axis = r.direction(e, "axis", Vector3d::UnitX());
  return j;
}

// URDF+ <coupling name><predecessor link|joint/><successor link|joint/><ratio value/>:
// the successor's rate is `ratio` times the predecessor's (parseCouplingConstraint in the
// same parser; a link stands for the joint above it, as in the published
// mit_humanoid_leg.urdf).
ExtCoupling readUrdfPlusCoupling(const XMLElement* robot, const XMLElement* e, const XmlReader& r) {
  r.onlyAttributes(e, {"name"});
  ExtCoupling c;
  c.element = e;
  c.name = nameOf(e, r);
  auto side = [&](const char* tag, std::string* name, bool* is_link) {
    const XMLElement* s = child(e, tag, r, "a link or a joint: <" + std::string(tag) + " link=...>");
    r.onlyAttributes(s, {"link", "joint"});
    if (s->Attribute("link") && s->Attribute("joint")) r.fail(s, "give a link or a joint, not both");
    if (s->Attribute("joint")) {
      *name = attr(s, "joint");
      bool found = false;
      for (const XMLElement* j = robot->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint"))
        found = found || attr(j, "name") == *name;
      if (!found) r.fail(s, "joint '" + *name + "' does not exist");
    } else {
      *name = linkOf(robot, s, "link", r);
      *is_link = true;
    }
  };
  side("predecessor", &c.predecessor, &c.predecessor_is_link);
  side("successor", &c.successor, &c.successor_is_link);
  const XMLElement* ratio = child(e, "ratio", r, "<ratio value=\"successor rate / predecessor rate\"/>");
  r.onlyAttributes(ratio, {"value"});
  c.ratio = r.number(ratio, "value", std::nullopt);
  if (c.ratio == 0.0) r.fail(ratio, "a ratio of zero holds the successor still: remove the coupling or give a non-zero ratio");
  return c;
}

// ---- urdfdom <constraint name type> (ros/urdfdom PR 264, ros/urdfdom_headers PR 108):
// <parent link/><parent_origin xyz rpy/><parent_axis xyz/><child link/><child_origin/>
// <child_axis/>, each origin in its own link, each axis in its own origin's frame. Types:
// revolute and prismatic (the axis on each side; child_axis defaults to parent_axis),
// universal (parent_axis the first axis, on the parent; child_axis the second, on the
// child), spherical (origins only), link (rigid: the frames coincide).
ExtJoint readUrdfdomConstraint(const XMLElement* robot, const XMLElement* e, const XmlReader& r) {
  static const std::map<std::string, std::string> types = {
      {"revolute", "revolute"}, {"continuous", "revolute"}, {"prismatic", "prismatic"},
      {"universal", "universal"}, {"spherical", "spherical"}, {"link", "fixed"}};
  ExtJoint j = loopClosure(e, r, types, "unknown constraint type", "revolute, prismatic, universal, spherical, link");
  const std::string type = attr(e, "type");  // as written, for the messages below
  for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
    const std::string tag = c->Name();
    if (tag == "parent" || tag == "child") r.onlyAttributes(c, {"link"});
    else if (tag == "parent_origin" || tag == "child_origin") r.onlyAttributes(c, {"xyz", "rpy"});
    else if (tag == "parent_axis" || tag == "child_axis") r.onlyAttributes(c, {"xyz"});
    else r.fail(c, "unknown element in <constraint> (parent, parent_origin, parent_axis, child, child_origin, child_axis)");
  }
  j.parent = linkOf(robot, child(e, "parent", r, "<parent link=...>"), "link", r);
  j.child = linkOf(robot, child(e, "child", r, "<child link=...>"), "link", r);
  const Isometry3d P = r.origin(e, "parent_origin"), C = r.origin(e, "child_origin");
  const bool axial = j.type == "revolute" || j.type == "prismatic" || j.type == "universal";
  if (axial && !e->FirstChildElement("parent_axis")) r.fail(e, "a " + type + " constraint needs <parent_axis xyz=...>");
  if (j.type == "universal" && !e->FirstChildElement("child_axis"))
    r.fail(e, "a universal constraint needs <child_axis xyz=...> (its second axis, on the child)");
  if (!axial && (e->FirstChildElement("parent_axis") || e->FirstChildElement("child_axis")))
    r.fail(e, "a " + type + " constraint has no axis: remove <parent_axis> and <child_axis>");
  j.origin = P;
  j.child_origin = C;
  if (!axial) return j;
  const Vector3d a_p = r.direction(e, "parent_axis", Vector3d::UnitX());
  const Vector3d a_c = r.direction(e, "child_axis", a_p);
  // The axes turned into each side's frame: the joint's axis is then z (x and y for a
  // universal joint) on both sides.
  if (j.type == "universal") {
    j.origin = P * turn(Vector3d::UnitX(), a_p);
    j.child_origin = C * turn(Vector3d::UnitY(), a_c);
    j.axis = Vector3d::UnitX();
    j.axis2 = Vector3d::UnitY();
    j.has_axis2 = true;
  } else {
    j.origin = P * turn(Vector3d::UnitZ(), a_p);
    j.child_origin = C * turn(Vector3d::UnitZ(), a_c);
    j.axis = Vector3d::UnitZ();
  }
  return j;
}

// ---- Drake <drake:ball_constraint> (Drake's URDF parser, detail_urdf_parser.cc; its
// documentation "drake:ball_constraint"): point P of body A (p_AP, in A's frame) stays on
// point Q of body B (p_BQ, in B's frame). A spherical joint between the two points.
ExtJoint readDrakeBallConstraint(const XMLElement* robot, const XMLElement* e, const XmlReader& r, int index) {
  r.onlyAttributes(e, {});
  ExtJoint j;
  j.element = e;
  j.loop = true;
  j.type = "spherical";
  j.name = "ball_constraint_" + std::to_string(index);
  for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
    const std::string tag = c->Name();
    if (tag == "drake:ball_constraint_body_A" || tag == "drake:ball_constraint_body_B") r.onlyAttributes(c, {"name"});
    else if (tag == "drake:ball_constraint_p_AP" || tag == "drake:ball_constraint_p_BQ") r.onlyAttributes(c, {"value"});
    else r.fail(c, "unknown element in <drake:ball_constraint> (drake:ball_constraint_body_A, _p_AP, _body_B, _p_BQ)");
  }
  const std::string hint = "a ball constraint needs body_A, p_AP, body_B and p_BQ";
  j.parent = linkOf(robot, child(e, "drake:ball_constraint_body_A", r, hint), "name", r);
  j.child = linkOf(robot, child(e, "drake:ball_constraint_body_B", r, hint), "name", r);
  const XMLElement* p = child(e, "drake:ball_constraint_p_AP", r, hint);
  const XMLElement* q = child(e, "drake:ball_constraint_p_BQ", r, hint);
  const std::vector<double> p_AP = r.numbers(p, "value", 3), p_BQ = r.numbers(q, "value", 3);
  j.origin.translation() = Vector3d(p_AP[0], p_AP[1], p_AP[2]);
  j.child_origin.translation() = Vector3d(p_BQ[0], p_BQ[1], p_BQ[2]);
  return j;
}

// A YAML node's place: "FILE:LINE: " (yaml-cpp's lines count from 0).
std::string where(const std::string& path, const YAML::Node& n) {
  std::ostringstream os;
  os << path;
  if (n.Mark().line >= 0) os << ":" << n.Mark().line + 1;
  return os.str() + ": ";
}

}  // namespace

bool readLoopDialect(const XMLElement* robot, const XMLElement* e, const XmlReader& r, Extension* ext) {
  const std::string tag = e->Name();
  if (tag == "loop_joint" || tag == "loop") {
    // Dojo and URDF+ are told apart by their children, not by the tag.
    const bool dojo = e->FirstChildElement("link1") || e->FirstChildElement("link2");
    const bool urdf_plus = e->FirstChildElement("predecessor") || e->FirstChildElement("successor");
    if (dojo && urdf_plus) r.fail(e, "mixes Dojo's <link1>/<link2> with URDF+'s <predecessor>/<successor>: use one pair");
    if (!dojo && !urdf_plus)
      r.fail(e, "a loop closure needs <link1 link=...>/<link2 link=...> (Dojo) or <predecessor link=...>/<successor link=...> (URDF+)");
    ext->joints.push_back(dojo ? readDojoLoopJoint(robot, e, r) : readUrdfPlusLoop(robot, e, r));
    return true;
  }
  if (tag == "coupling") {
    ext->couplings.push_back(readUrdfPlusCoupling(robot, e, r));
    return true;
  }
  if (tag == "constraint") {
    ext->joints.push_back(readUrdfdomConstraint(robot, e, r));
    return true;
  }
  if (tag == "drake:ball_constraint") {
    int index = 1;
    for (const ExtJoint& j : ext->joints) index += j.name.rfind("ball_constraint_", 0) == 0 ? 1 : 0;
    ext->joints.push_back(readDrakeBallConstraint(robot, e, r, index));
    return true;
  }
  return false;
}

// ---- Gazebo <gazebo><link name> (SDF link.sdf, inertial.sdf, pose.sdf; Gazebo classic
// inserts a <gazebo> block without reference into the model it makes of the URDF, whose
// model frame is the root link's): <pose [relative_to]>x y z roll pitch yaw</pose> in the
// model frame or in the frame relative_to names (a link, or __model__); <inertial> with
// <pose> (the centre of mass and inertia axes in the link frame), <mass>, <inertia><ixx>
// ... <izz>, SDF's defaults where absent (mass 1, ixx = iyy = izz = 1, products 0, the
// pose zero). Visuals, collisions, sensors and the like are not read (no contact is
// simulated).
namespace {

// Text of child `tag` of e as `count` finite numbers (absent: def, when given).
std::vector<double> sdfNumbers(const XMLElement* e, const char* tag, size_t count, const XmlReader& r,
                               const std::vector<double>* def = nullptr) {
  const XMLElement* c = e->FirstChildElement(tag);
  if (!c) {
    if (def) return *def;
    r.fail(e, std::string("missing <") + tag + ">");
  }
  std::istringstream is(c->GetText() ? c->GetText() : "");
  std::vector<double> v(count);
  const std::string needs = count == 1 ? "needs a finite number" : "needs " + std::to_string(count) + " finite numbers";
  for (double& x : v)
    if (!(is >> x) || !std::isfinite(x) || std::fabs(x) > 1e6)
      r.fail(c, needs + ": '" + oneLine(c->GetText() ? c->GetText() : "") + "'");
  std::string extra;
  if (is >> extra) r.fail(c, needs + ", got more: '" + oneLine(c->GetText()) + "'");
  return v;
}

// An SDF <pose> child of e: "x y z roll pitch yaw" (degrees="true": the angles in degrees).
Isometry3d sdfPose(const XMLElement* e, const XmlReader& r) {
  const XMLElement* p = e->FirstChildElement("pose");
  if (!p) return Isometry3d::Identity();
  if (p->Attribute("rotation_format") && attr(p, "rotation_format") != "euler_rpy")
    r.fail(p, "rotation_format '" + oneLine(attr(p, "rotation_format")) + "' is not read: write the pose as x y z roll pitch yaw");
  const std::vector<double> v = sdfNumbers(e, "pose", 6, r);
  const double k = attr(p, "degrees") == "true" ? M_PI / 180.0 : 1.0;
  return poseFromXyzRpy(Vector3d(v[0], v[1], v[2]), k * Vector3d(v[3], v[4], v[5]));
}

std::string numberText(double x) {
  std::ostringstream os;
  os.precision(17);
  os << x;
  return os.str();
}

std::string xyzText(const Vector3d& v) { return numberText(v.x()) + " " + numberText(v.y()) + " " + numberText(v.z()); }

}  // namespace

std::vector<std::string> addSdfLinks(tinyxml2::XMLDocument& doc, XMLElement* robot, const XmlReader& r) {
  std::vector<const XMLElement*> sdf_links;
  for (const XMLElement* g = robot->FirstChildElement("gazebo"); g; g = g->NextSiblingElement("gazebo"))
    for (const XMLElement* l = g->FirstChildElement("link"); l; l = l->NextSiblingElement("link")) sdf_links.push_back(l);
  std::vector<std::string> added;
  if (sdf_links.empty()) return added;
  // the model frame: the root link's (the first link that is no joint's child)
  std::set<std::string> children, joints;
  for (const XMLElement* j = robot->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
    joints.insert(attr(j, "name"));
    if (const XMLElement* c = j->FirstChildElement("child")) children.insert(attr(c, "link"));
  }
  std::string root;
  for (const XMLElement* l = robot->FirstChildElement("link"); l && root.empty(); l = l->NextSiblingElement("link"))
    if (!children.count(attr(l, "name"))) root = attr(l, "name");
  if (root.empty()) r.fail(robot, "no root link: every link is a joint's child");
  for (const XMLElement* l : sdf_links) {
    const std::string name = nameOf(l, r);
    if (linkElement(robot, name)) r.fail(l, "an SDF link named '" + name + "', as a URDF link already is: rename one");
    std::string parent = root;
    if (const XMLElement* p = l->FirstChildElement("pose"); p && p->Attribute("relative_to")) {
      const std::string to = attr(p, "relative_to");
      if (to != "__model__" && to != "") {
        if (!linkElement(robot, to))
          r.fail(p, "relative_to '" + oneLine(to) + "' is not a link of the URDF (a link, or __model__)");
        parent = to;
      }
    }
    const Isometry3d T = sdfPose(l, r);
    // <inertial>, SDF's defaults where absent
    double mass = 1.0;
    std::vector<double> I = {1, 0, 0, 1, 0, 1};  // ixx ixy ixz iyy iyz izz
    Isometry3d C = Isometry3d::Identity();
    if (const XMLElement* in = l->FirstChildElement("inertial")) {
      C = sdfPose(in, r);
      const std::vector<double> one = {1.0};
      mass = sdfNumbers(in, "mass", 1, r, &one)[0];
      if (!(mass >= 0)) r.fail(in->FirstChildElement("mass"), "mass must be >= 0");
      if (const XMLElement* J = in->FirstChildElement("inertia")) {
        const char* tags[6] = {"ixx", "ixy", "ixz", "iyy", "iyz", "izz"};
        for (int k = 0; k < 6; ++k) {
          const std::vector<double> def = {I[k]};
          I[k] = sdfNumbers(J, tags[k], 1, r, &def)[0];
        }
      }
    }
    std::string joint_name = name + "_floating";
    while (joints.count(joint_name)) joint_name += "_";
    joints.insert(joint_name);
    // the URDF equivalent: the link with its inertial, on a floating joint from its frame
    XMLElement* link = doc.NewElement("link");
    link->SetAttribute("name", name.c_str());
    XMLElement* inertial = link->InsertNewChildElement("inertial");
    const Vector3d rpy = C.linear().eulerAngles(2, 1, 0).reverse();
    XMLElement* origin = inertial->InsertNewChildElement("origin");
    origin->SetAttribute("xyz", xyzText(C.translation()).c_str());
    origin->SetAttribute("rpy", xyzText(rpy).c_str());
    inertial->InsertNewChildElement("mass")->SetAttribute("value", numberText(mass).c_str());
    XMLElement* inertia = inertial->InsertNewChildElement("inertia");
    const char* names[6] = {"ixx", "ixy", "ixz", "iyy", "iyz", "izz"};
    for (int k = 0; k < 6; ++k) inertia->SetAttribute(names[k], numberText(I[k]).c_str());
    robot->InsertEndChild(link);
    XMLElement* joint = doc.NewElement("joint");
    joint->SetAttribute("name", joint_name.c_str());
    joint->SetAttribute("type", "floating");
    XMLElement* jo = joint->InsertNewChildElement("origin");
    jo->SetAttribute("xyz", xyzText(T.translation()).c_str());
    jo->SetAttribute("rpy", xyzText(T.linear().eulerAngles(2, 1, 0).reverse()).c_str());
    joint->InsertNewChildElement("parent")->SetAttribute("link", parent.c_str());
    joint->InsertNewChildElement("child")->SetAttribute("link", name.c_str());
    robot->InsertEndChild(joint);
    added.push_back(name);
  }
  return added;
}

// ---- onshape-to-robot (Rhoban; assembly.py, "Processing loop closing frames", and its
// documentation "Handling kinematic loops"): a mate named closing_<name> between two parts
// becomes a frame closing_<name>_1 on the first and closing_<name>_2 on the second, both
// at the mate connector; a REVOLUTE mate adds closing_<name>_1_z / closing_<name>_2_z, 0.1
// m along the connector's z (the hinge axis). In a URDF each frame is a dummy link on a
// fixed joint (exporter_urdf.py add_frame: link <frame>, joint <frame>_frame), and the
// closures themselves are written only for MuJoCo (exporter_mujoco.py: a <connect> per pair
// for BALL and REVOLUTE, a <weld> for FASTENED). Read as that export: each pair is a ball
// joint between the frames' origins, named closing_<name> (and closing_<name>_z for the
// second pair of a hinge, whose two balls on the axis make the hinge; one of their six
// equations is then dependent). A FASTENED mate's frames cannot be told from a ball's in a
// URDF: they are read as a ball.
void readOnshapeClosures(const XMLElement* robot, const XmlReader& r, Extension* ext) {
  const std::string prefix = "closing_";
  auto endsWith = [](const std::string& s, const std::string& tail) {
    return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
  };
  for (const XMLElement* l = robot->FirstChildElement("link"); l; l = l->NextSiblingElement("link")) {
    const std::string name = attr(l, "name");
    if (name.rfind(prefix, 0) != 0) continue;
    // (first tail, second tail, closure name suffix): closing_<name>_1_z before closing_<name>_1
    std::string tail, other, suffix;
    for (const auto& t : std::vector<std::array<std::string, 3>>{
             {"_1_z", "_2_z", "_z"}, {"_2_z", "_1_z", "_z"}, {"_1", "_2", ""}, {"_2", "_1", ""}})
      if (endsWith(name, t[0]) && name.size() > prefix.size() + t[0].size()) {
        tail = t[0], other = t[1], suffix = t[2];
        break;
      }
    if (tail.empty()) continue;
    const std::string stem = name.substr(0, name.size() - tail.size());
    const std::string partner = stem + other;
    if (!linkElement(robot, partner))
      r.fail(l, "an onshape-to-robot closing frame without its partner '" + partner +
                    "' (add that link where the loop closes, or rename this one)");
    if (tail[1] == '2') continue;  // the pair is read once, from _1
    ExtJoint j;
    j.element = l;
    j.loop = true;
    j.type = "spherical";
    j.name = stem + suffix;
    j.parent = name;
    j.child = partner;
    ext->joints.push_back(j);
  }
}

// ---- "Extended URDF" (Gepetto/example-parallel-robots, loader_tools.py
// completeRobotLoader, which builds a Pinocchio model from the URDF and then):
//  - joint_name/joint_type: rebuilds each named joint of the model at its placement as
//    SPHERICAL (JointModelSpherical), CARDAN (JointModelRX then JointModelRY, both at the
//    joint's origin frame: a universal joint with axes x then y of that frame), UJOINT_AB
//    (the later versions' JointModelRA then JointModelRB, A and B among X, Y, Z) or FIXED
//    (locked at the neutral configuration, q = 0, by buildReducedModel); a name that is no
//    joint of the model is passed over;
//  - closed_loop/type: for each pair, model.getFrameId(name) on the rebuilt model and a
//    RigidConstraintModel between the two frames, CONTACT_3D for 3d/3D (the origins
//    coincide: a ball), CONTACT_6D otherwise (the frames coincide: fixed);
//  - name_mot: ActuationModel(model, name_mot): these joints are the motors (the actuated
//    dofs); every other dof is passive.
// A Pinocchio frame named in closed_loop is any frame of the URDF parser: a link's (BODY),
// a joint's (JOINT, or FIXED_JOINT for a fixed joint: Pinocchio turns fixed joints into
// frames) or "universe" (the world, the root link of a fixed-base model). A joint's frame is
// attached to the joint with identity placement, which is the child link's frame (the
// joint origin, moving with the joint): a joint's name stands for its child link.
void readClosuresFile(const std::string& path, const XMLElement* robot, Extension* ext) {
  if (path.empty()) return;
  const YAML::Node doc = loadYamlFile(path, "closures");
  auto fail = [&](const YAML::Node& n, const std::string& what) { throw LoadError(where(path, n) + oneLine(what, 400)); };
  if (!doc.IsMap()) fail(doc, "a closures file is a map with closed_loop: [[frameA, frameB], ...] and type: [3d|6d, ...]");
  auto stringList = [&](const char* key) {
    std::vector<std::pair<std::string, YAML::Node>> out;
    const YAML::Node n = doc[key];
    if (!n || n.IsNull()) return out;
    if (!n.IsSequence()) fail(n, std::string(key) + ": a list is needed, as [a, b]");
    for (size_t i = 0; i < n.size(); ++i) {
      if (!n[i].IsScalar()) fail(n[i], std::string(key) + "[" + std::to_string(i) + "]: a name is needed");
      out.emplace_back(n[i].as<std::string>(), n[i]);
    }
    return out;
  };
  std::map<std::string, std::string> joint_type, joint_child;  // by joint name
  for (const XMLElement* j = robot->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
    const XMLElement* c = j->FirstChildElement("child");
    joint_type[attr(j, "name")] = attr(j, "type");
    joint_child[attr(j, "name")] = c ? attr(c, "link") : "";
  }
  std::set<std::string> children;
  for (const auto& jc : joint_child) children.insert(jc.second);
  for (auto it = doc.begin(); it != doc.end(); ++it) {
    const std::string key = it->first.as<std::string>();
    if (key != "closed_loop" && key != "type" && key != "name_mot" && key != "joint_name" && key != "joint_type")
      fail(it->first, "unknown key '" + key + "' (closed_loop, type, name_mot, joint_name, joint_type)");
  }
  // A Pinocchio frame's link (see above); "" if no frame has that name.
  auto frameLink = [&](const YAML::Node& node, const std::string& at, const std::string& frame) -> std::string {
    const bool link = linkElement(robot, frame) != nullptr;
    const auto joint = joint_child.find(frame);
    if (link && joint != joint_child.end() && joint->second != frame)
      fail(node, at + "frame '" + frame + "' names both a link and joint '" + frame + "' (whose child is link '" +
                     joint->second + "'): the frames differ; rename one of them");
    if (link) return frame;
    if (joint != joint_child.end()) return joint->second;
    if (frame == "universe") {
      for (const XMLElement* l = robot->FirstChildElement("link"); l; l = l->NextSiblingElement("link"))
        if (!children.count(attr(l, "name"))) return attr(l, "name");
    }
    return "";
  };
  const YAML::Node loops = doc["closed_loop"];
  if (!loops || !loops.IsSequence()) fail(loops ? loops : doc, "closed_loop: a list of frame pairs is needed, as [[frameA, frameB]]");
  const auto types = stringList("type");
  if (doc["type"] && types.size() != loops.size())
    fail(doc["type"], "type: " + std::to_string(types.size()) + " entries for " + std::to_string(loops.size()) +
                          " closed_loop pairs: give one (3d or 6d) per pair");
  for (size_t i = 0; i < loops.size(); ++i) {
    const YAML::Node pair = loops[i];
    const std::string at = "closed_loop[" + std::to_string(i) + "]: ";
    if (!pair.IsSequence() || pair.size() != 2 || !pair[0].IsScalar() || !pair[1].IsScalar())
      fail(pair, at + "a pair of frame names is needed, as [frameA, frameB]");
    ExtJoint j;
    j.loop = true;
    const std::string names[2] = {pair[0].as<std::string>(), pair[1].as<std::string>()};
    std::string* links[2] = {&j.parent, &j.child};
    for (int k = 0; k < 2; ++k) {
      *links[k] = frameLink(pair, at, names[k]);
      if (links[k]->empty())
        fail(pair, at + "frame '" + names[k] + "' is not a frame of the URDF (a link, a joint or 'universe', as "
                        "Pinocchio names them): name one of those");
    }
    if (j.parent == j.child)
      fail(pair, at + "frames '" + names[0] + "' and '" + names[1] + "' are on the same link ('" + j.parent +
                     "'): a loop closes between two bodies");
    const std::string type = types.empty() ? "6d" : types[i].first;
    if (type == "3d" || type == "3D") j.type = "spherical";
    else if (type == "6d" || type == "6D") j.type = "fixed";
    else fail(types[i].second, "type[" + std::to_string(i) + "]: unknown closure type '" + type + "' (3d: a ball; 6d: rigid)");
    j.name = names[0] + "-" + names[1];
    ext->joints.push_back(j);
  }
  const auto replaced = stringList("joint_name"), replacement = stringList("joint_type");
  if (replaced.size() != replacement.size())
    fail(doc["joint_type"] ? doc["joint_type"] : doc["joint_name"], "joint_name and joint_type need one entry each per joint");
  std::set<std::string> seen;
  for (size_t i = 0; i < replaced.size(); ++i) {
    const std::string& name = replaced[i].first;
    if (!joint_type.count(name)) {  // the reference rebuilds the model's joints only: ignored there
      ext->notes.push_back(where(path, replaced[i].second) + "joint_name '" + name +
                           "' names no joint of the URDF: ignored, as completeRobotLoader does");
      continue;
    }
    const std::string t = joint_type[name];
    if (t == "fixed" || t == "floating")
      fail(replaced[i].second, "joint_name: '" + name + "' is a " + t + " joint, whose type cannot change");
    if (!seen.insert(name).second) fail(replaced[i].second, "joint_name: '" + name + "' is listed twice");
    ExtJoint j;
    j.name = name;
    const std::string& to = replacement[i].first;
    if (to == "SPHERICAL") {
      j.type = "spherical";
    } else if (to == "FIXED") {
      j.type = "fixed";
    } else if (to == "CARDAN" || (to.size() == 9 && to.rfind("UJOINT_", 0) == 0)) {
      // CARDAN: RX then RY; UJOINT_AB: RA then RB (A, B among X, Y, Z), at the joint's origin
      const std::string axes = to == "CARDAN" ? "XY" : to.substr(7, 2);
      auto unit = [](char c) -> std::optional<Vector3d> {
        if (c == 'X') return Vector3d::UnitX();
        if (c == 'Y') return Vector3d::UnitY();
        if (c == 'Z') return Vector3d::UnitZ();
        return std::nullopt;
      };
      const auto a = unit(axes[0]), b = unit(axes[1]);
      if (!a || !b || axes[0] == axes[1])
        fail(replacement[i].second, "joint_type: '" + to + "': a UJOINT_AB needs two different axes A, B among X, Y, Z");
      j.type = "universal";
      j.axis = *a;
      j.axis2 = *b;
      j.has_axis2 = j.axes_given = true;
    } else {
      fail(replacement[i].second, "joint_type: unknown type '" + to + "' (SPHERICAL, CARDAN, UJOINT_XY and the like, FIXED)");
    }
    ext->joints.push_back(j);
  }
  std::string motors;
  for (const auto& m : stringList("name_mot")) {
    if (!joint_type.count(m.first)) fail(m.second, "name_mot: no joint '" + m.first + "' in the URDF");
    const std::string t = joint_type[m.first];
    if (t == "fixed" || t == "floating")
      fail(m.second, "name_mot: '" + m.first + "' is a " + t + " joint, which has no dof to actuate");
    if (seen.count(m.first)) {
      for (size_t i = 0; i < replaced.size(); ++i)
        if (replaced[i].first == m.first && replacement[i].first == "FIXED")
          fail(m.second, "name_mot: '" + m.first + "' is made FIXED by joint_type, which leaves no dof to actuate");
    }
    ext->actuated.push_back(m.first);
    motors += (motors.empty() ? "" : ", ") + m.first;
  }
  if (!motors.empty()) {
    ext->actuated_source = "name_mot in " + path;
    ext->notes.push_back("actuated joints (name_mot in " + path + "): " + motors +
                         "; every other dof is passive (no effort command, no drive)");
  }
}

std::string siblingClosuresFile(const std::string& urdf_path) {
  std::string stem = urdf_path;
  const std::string xacro = ".xacro";
  if (stem.size() > xacro.size() && stem.compare(stem.size() - xacro.size(), xacro.size(), xacro) == 0)
    stem.resize(stem.size() - xacro.size());
  const size_t slash = stem.find_last_of('/'), dot = stem.find_last_of('.');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) stem.resize(dot);
  const std::string yaml = stem + ".yaml";
  std::ifstream in(yaml);
  if (!in) return "";
  std::stringstream text;
  text << in.rdbuf();
  return text.str().find("closed_loop") != std::string::npos ? yaml : "";
}

std::vector<Coupling> resolveCouplings(const Extension& ext, const JointSpecs& specs, const XmlReader& r) {
  std::vector<Coupling> out;
  for (const ExtCoupling& c : ext.couplings) {
    auto jointOf = [&](const std::string& name, bool is_link) -> std::string {
      if (!is_link) return name;
      for (const JointSpec& s : specs.tree)
        if (s.child == name) return s.name;
      r.fail(c.element, "link '" + name + "' is the root: it has no joint to couple");
    };
    Coupling k;
    k.name = c.name;
    k.element = c.element;
    k.leader = jointOf(c.predecessor, c.predecessor_is_link);
    k.follower = jointOf(c.successor, c.successor_is_link);
    k.ratio = c.ratio;
    if (k.leader == k.follower) r.fail(c.element, "couples joint '" + k.leader + "' with itself");
    out.push_back(k);
  }
  return out;
}

}  // namespace urdf_input
}  // namespace mechanism_sim
