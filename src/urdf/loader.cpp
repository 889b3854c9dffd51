// URDF (+ extension) -> MechanismModel, in the order a reader checks a file:
//   1. the XML, the standard elements and the extension (xml_input.h);
//   2. urdfdom's model;
//   3. the joints, tree and loop closures, with their frames resolved (joint_specs.h);
//   4. the links grouped into rigid bodies (rigid_bodies.h);
//   5. the initial values, the bodies placed by forward kinematics, the joints, the
//      degrees of freedom, springs and gravity in the core; then assembly.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include "couplings.h"
#include "joint_specs.h"
#include "loop_dialects.h"
#include "massless_gimbals.h"
#include "mechanism_sim/core/model/inertia.h"
#include "mechanism_sim/core/kinematic.h"
#include "mechanism_sim/urdf/model.h"
#include "rigid_bodies.h"
#include "xacro.h"
#include "transmissions.h"
#include "xml_input.h"
#include "model_builder.h"

namespace mechanism_sim {


namespace {

// urdfdom reports its parse errors through console_bridge, and the loader reports its own:
// while urdfdom parses, its errors are captured (the first one explains a refusal) instead
// of printed, and console_bridge's level and handler are restored after (also when parsing
// throws): the embedding program's own logging is left as it was.
class ConsoleBridgeCaptured : public console_bridge::OutputHandler {
 public:
  ConsoleBridgeCaptured() : saved_(console_bridge::getLogLevel()) {
    console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_ERROR);
    console_bridge::useOutputHandler(this);
  }
  ~ConsoleBridgeCaptured() override {
    console_bridge::restorePreviousOutputHandler();
    console_bridge::setLogLevel(saved_);
  }
  ConsoleBridgeCaptured(const ConsoleBridgeCaptured&) = delete;
  ConsoleBridgeCaptured& operator=(const ConsoleBridgeCaptured&) = delete;
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR && first_.empty()) first_ = text;
  }
  const std::string& first() const { return first_; }

 private:
  console_bridge::LogLevel saved_;
  std::string first_;
};

urdf::ModelInterfaceSharedPtr parseWithUrdfdom(const std::string& xml, std::string* why) {
  ConsoleBridgeCaptured captured;
  urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(xml);
  *why = captured.first();
  return model;
}

// What tinyxml2's parse error means in the XML a user writes, and how it is fixed.
std::string xmlErrorWords(tinyxml2::XMLError id) {
  switch (id) {
    case tinyxml2::XML_ERROR_EMPTY_DOCUMENT: return "the file has no element";
    case tinyxml2::XML_ERROR_PARSING_DECLARATION:
      return "the XML declaration <?xml ...?> must be the first thing in the file, closed by ?> (a comment or "
             "element comes before it?)";
    case tinyxml2::XML_ERROR_MISMATCHED_ELEMENT:
      return "an end tag does not match the open element (an element left unclosed?)";
    case tinyxml2::XML_ERROR_PARSING_ELEMENT: return "an element is not closed or its tag is malformed";
    case tinyxml2::XML_ERROR_PARSING_ATTRIBUTE:
      return "an attribute is malformed (a value without quotes, a name given twice, or a raw '<' in a value?)";
    case tinyxml2::XML_ERROR_PARSING_TEXT: return "text is malformed (a raw '&' or '<'? write &amp; or &lt;)";
    case tinyxml2::XML_ERROR_PARSING_CDATA: return "a <![CDATA[ section is not closed by ]]>";
    case tinyxml2::XML_ERROR_PARSING_COMMENT: return "a comment <!-- is not closed by -->";
    case tinyxml2::XML_ERROR_PARSING_UNKNOWN: return "a <!...> declaration is not closed by >";
    case tinyxml2::XML_ELEMENT_DEPTH_EXCEEDED: return "the elements nest too deep";
    default: return "the XML cannot be read";
  }
}

// A joint coordinate: (joint name, coordinate index).
}  // namespace

std::unique_ptr<MechanismModel> ModelBuilder::build() {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml_.c_str(), xml_.size()) != tinyxml2::XML_SUCCESS) {
    std::ostringstream os;
    os << reader_.file << ":" << doc.ErrorLineNum() << ": malformed XML: " << xmlErrorWords(doc.ErrorID()) << " ("
       << doc.ErrorName() << ")";
    throw LoadError(os.str());
  }
  tinyxml2::XMLElement* robot = doc.RootElement();
  if (!robot || std::string(robot->Name()) != "robot") reader_.fail(robot, "the root element is not <robot>");
  const bool implicit_world = addImplicitWorld(doc, robot);
  const std::vector<std::string> sdf_links = addSdfLinks(doc, robot, reader_);  // Gazebo (loop_dialects.h)
  if (!sdf_links.empty()) {
    std::string list;
    for (const std::string& l : sdf_links) list += (list.empty() ? "'" : ", '") + l + "'";
    root_notes_.push_back("SDF links of <gazebo> blocks are bodies, free but for their SDF joints: " + list);
  }
  const std::vector<std::string> roots = validateStandard(robot, reader_);
  if (roots.size() > 1) floatExtraRoots(doc, robot, roots, implicit_world);
  Transmissions transmissions = readTransmissions(robot, reader_);  // (transmissions.h)
  readActuatorsFile(options_.actuators_file, transmissions);
  noteIgnored(robot, transmissions.ignored);
  Extension ext = readExtension(robot, reader_);
  readClosuresFile(options_.closures_file, robot, &ext);  // "Extended URDF" (loop_dialects.h)
  std::string why;
  const urdf::ModelInterfaceSharedPtr urdf = parseWithUrdfdom(roots.size() > 1 || !sdf_links.empty() || implicit_world ? printed(doc) : xml_, &why);
  if (!urdf) {
    // urdfdom reads the XML with TinyXML 1, which takes a raw '&' or '<' in a name
    // differently from tinyxml2: name the element instead of a bare refusal
    for (const char* tag : {"link", "joint", "material"})
      for (auto* e = robot->FirstChildElement(tag); e; e = e->NextSiblingElement(tag)) {
        const char* name = e->Attribute("name");
        if (name && std::strpbrk(name, "&<"))
          reader_.fail(e, std::string("urdfdom could not parse the robot description: it reads this ") + tag +
                              "'s name differently (an unescaped '&' or '<'? write &amp; or &lt;)");
      }
    throw LoadError(reader_.file + ": urdfdom could not parse the robot description" +
                    (why.empty() ? std::string() : ": " + oneLine(why)));
  }

  model_ = std::make_unique<MechanismModel>();
  model_->source_ = reader_.file;
  model_->mechanism_ = std::make_unique<Mechanism>();
  model_->name_ = urdf->getName();
  model_->root_link_ = urdf->getRoot()->name;
  JointSpecs specs = collectJointSpecs(robot, *urdf, ext, reader_);
  const MergedGimbals balls = mergeMasslessGimbals(&specs, *urdf, ext, transmissions, options_);
  if (!balls.note.empty()) root_notes_.push_back(balls.note);
  const LinkTree tree(specs.tree, model_->root_link_);
  const RigidBodies bodies(tree, *urdf);
  checkInertias(robot, bodies, *urdf);
  kinematic_ = bodies.groups().size() > 1;
  for (size_t g = 1; g < bodies.groups().size(); ++g) kinematic_ = kinematic_ && bodies.groups()[g].mass == 0.0;
  InitialValues initial = initialValues(specs, ext);
  startInsideLimits(specs, ext, initial);
  const std::map<std::string, Isometry3d> placed = tree.poses(initial.coordinates());
  addBodies(bodies, placed, *urdf);
  for (const JointSpec& s : specs.tree) model_->tree_.push_back(TreeJoint{s.name, s.parent, s.child, s.type == "fixed"});
  for (const JointSpec& s : specs.tree) addJoint(s, bodies, true);
  for (const JointSpec& s : specs.loops) addJoint(s, bodies, false);
  markPassive(ext);
  addGimbals(balls.chains);
  for (const JointSpec& s : specs.tree) addMimic(s, specs);
  for (const JointSpec& s : specs.tree) tree_joints_.push_back(s.name);
  for (const Coupling& c : resolveCouplings(ext, specs, reader_)) addCoupling(c);
  for (const CouplingInfo& c : addLinearCouplings(ext.linear_couplings, specs, joint_index_, mech(), reader_))
    model_->couplings_.push_back(c);
  addTransmissions(transmissions);
  model_->notes_ = ext.notes;
  model_->notes_.insert(model_->notes_.end(), root_notes_.begin(), root_notes_.end());
  if (!ignored_note_.empty()) model_->notes_.push_back(ignored_note_);
  model_->notes_.insert(model_->notes_.end(), limit_notes_.begin(), limit_notes_.end());
  model_->notes_.insert(model_->notes_.end(), inertia_notes_.begin(), inertia_notes_.end());
  addDrives(specs, ext, initial);
  addSprings(ext, bodies, placed, *urdf);
  setGravityAndIntegrator(ext);
  assemble(initial);
  if (options_.actuator_limits) {  // (the saturating mode: doc/actuators.md)
    const std::string note = model_->setActuatorLimits(true);
    if (!note.empty()) model_->notes_.push_back(note);
    model_->initial_ = model_->mechanism_->snapshot();  // (reset() returns to it within the bounds)
  }
  return std::move(model_);
}

Coordinate ModelBuilder::locate(const JointSpecs& specs, const std::string& dof, const tinyxml2::XMLElement* e) const {
  auto find = [&](const std::string& name) -> const JointSpec* {
    for (const auto* list : {&specs.tree, &specs.loops})
      for (const JointSpec& s : *list)
        if (s.name == name) return &s;
    return nullptr;
  };
  if (const JointSpec* s = find(dof)) {
    if (dofNames(*s).size() == 1) return {s->name, 0};
  } else if (const size_t dot = dof.rfind('.'); dot != std::string::npos) {
    if (const JointSpec* j = find(dof.substr(0, dot))) {
      const std::vector<std::string>& names = dofNames(*j);
      for (size_t k = 0; names.size() > 1 && k < names.size(); ++k)
        if (names[k] == dof.substr(dot + 1)) return {j->name, static_cast<int>(k)};
    }
  }
  const std::string what = "no joint degree of freedom named '" + dof + "'";
  if (e) fail(e, what);
  fail(what);
}

InitialValues ModelBuilder::initialValues(const JointSpecs& specs, const Extension& ext) const {
  InitialValues in;
  for (const ExtInitial& i : ext.initial) {
    const Coordinate at = locate(specs, i.dof, i.element);
    if (i.position) in.positions[at] = *i.position;
    if (i.velocity) in.velocities[at] = *i.velocity, in.velocity_from_file[at] = true;
  }
  for (const auto& p : options_.positions) {
    const Coordinate at = locate(specs, p.first, nullptr);
    if (!std::isfinite(p.second)) fail("initial position of '" + p.first + "' is not finite");
    in.positions[at] = p.second;
  }
  for (const auto& v : options_.velocities) {
    const Coordinate at = locate(specs, v.first, nullptr);
    if (!std::isfinite(v.second)) fail("initial velocity of '" + v.first + "' is not finite");
    in.velocities[at] = v.second;
    in.velocity_from_file[at] = false;
  }
  return in;
}

void ModelBuilder::noteIgnored(const tinyxml2::XMLElement* robot, const std::map<std::string, int>& transmission_types) {
  std::map<std::string, int> count;
  static const std::set<std::string> read = {"link", "joint", "material", "loop_joint", "loop", "coupling",
                                             "constraint", "drake:ball_constraint", "transmission"};
  for (const auto& [type, n] : transmission_types) count["<transmission> of type " + type] += n;
  for (const tinyxml2::XMLElement* e = robot->FirstChildElement(); e; e = e->NextSiblingElement()) {
    const std::string tag = e->Name();
    if (tag == "gazebo") {
      for (const tinyxml2::XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement())
        if (std::string(c->Name()) != "joint" && std::string(c->Name()) != "link") {
          ++count["<gazebo> " + std::string(c->Name())];
        }
    } else if (tag == "link") {
      for (const tinyxml2::XMLElement* c = e->FirstChildElement("collision"); c; c = c->NextSiblingElement("collision"))
        ++count["<collision> (no contact is simulated)"];
    } else if (tag == "joint") {
      for (const char* t : {"safety_controller", "calibration"})
        if (e->FirstChildElement(t)) ++count["<" + std::string(t) + ">"];
    } else if (!read.count(tag) && tag.rfind("mechanism_sim:", 0) != 0) {
      ++count["<" + tag + ">"];
    }
  }
  if (count.empty()) return;
  std::string list;
  for (const auto& [what, n] : count) list += (list.empty() ? "" : ", ") + std::to_string(n) + " " + what;
  ignored_note_ = "ignored (read, not simulated): " + list;
}

bool ModelBuilder::addImplicitWorld(tinyxml2::XMLDocument& doc, tinyxml2::XMLElement* robot) {
  for (auto* l = robot->FirstChildElement("link"); l; l = l->NextSiblingElement("link"))
    if (l->Attribute("name") && std::string(l->Attribute("name")) == "world") return false;
  std::string naming;
  for (auto* j = robot->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
    tinyxml2::XMLElement* p = j->FirstChildElement("parent");
    tinyxml2::XMLElement* c = j->FirstChildElement("child");
    if (!p || !c || !p->Attribute("link") || !c->Attribute("link")) continue;  // validateStandard says so
    const std::string name = j->Attribute("name") ? j->Attribute("name") : "";
    if (std::string(c->Attribute("link")) == "world") {
      if (!j->Attribute("type") || std::string(j->Attribute("type")) != "fixed")
        fail(j, "link 'world' (the world, as in Drake) is the child of this movable joint: make 'world' its parent");
      // the weld read from the world: the parent's frame in the world is the inverse of
      // the origin, the child's (the world's) frame in the parent
      const Isometry3d T = reader_.origin(j).inverse();
      const Eigen::Vector3d ypr = T.linear().eulerAngles(2, 1, 0);
      tinyxml2::XMLElement* o = j->FirstChildElement("origin");
      if (!o) o = j->InsertNewChildElement("origin");
      std::ostringstream xyz, rpy;
      xyz.precision(17);
      rpy.precision(17);
      xyz << T.translation().x() << " " << T.translation().y() << " " << T.translation().z();
      rpy << ypr(2) << " " << ypr(1) << " " << ypr(0);
      o->SetAttribute("xyz", xyz.str().c_str());
      o->SetAttribute("rpy", rpy.str().c_str());
      const std::string parent = p->Attribute("link");
      p->SetAttribute("link", "world");
      c->SetAttribute("link", parent.c_str());
    }
    if (naming.empty() && std::string(p->Attribute("link")) == "world") naming = name;
  }
  if (naming.empty()) return false;
  robot->InsertFirstChild(doc.NewElement("link"))->ToElement()->SetAttribute("name", "world");
  root_notes_.push_back("joint '" + naming + "' names link 'world', which the file does not declare: it is the world "
                        "(ground), as in Drake's URDF parser");
  return true;
}

void ModelBuilder::floatExtraRoots(tinyxml2::XMLDocument& doc, tinyxml2::XMLElement* robot, const std::vector<std::string>& roots,
                     bool implicit_world) {
  std::map<std::string, std::vector<std::string>> children;
  std::set<std::string> joint_names;
  for (auto* j = robot->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
    joint_names.insert(j->Attribute("name"));
    children[j->FirstChildElement("parent")->Attribute("link")].push_back(j->FirstChildElement("child")->Attribute("link"));
  }
  std::function<size_t(const std::string&)> size = [&](const std::string& l) {
    size_t n = 1;
    for (const std::string& c : children[l]) n += size(c);
    return n;
  };
  std::string main = roots.front();
  for (const std::string& r : roots)
    if (size(r) > size(main)) main = r;
  if (implicit_world) main = "world";  // the world is ground; the other trees float (Drake's free bodies)
  std::string floating;
  for (const std::string& r : roots) {
    if (r == main) continue;
    std::string name = r + "_floating";
    while (joint_names.count(name)) name += "_";
    joint_names.insert(name);
    tinyxml2::XMLElement* j = doc.NewElement("joint");
    j->SetAttribute("name", name.c_str());
    j->SetAttribute("type", "floating");
    j->InsertNewChildElement("parent")->SetAttribute("link", main.c_str());
    j->InsertNewChildElement("child")->SetAttribute("link", r.c_str());
    robot->InsertEndChild(j);
    floating += (floating.empty() ? "'" : ", '") + r + "' (joint '" + name + "')";
  }
  root_notes_.push_back("several root links: '" + main + "' is the model's root; " + floating +
                        " float free of it (a floating joint each)");
}

std::string ModelBuilder::printed(const tinyxml2::XMLDocument& doc) {
  tinyxml2::XMLPrinter printer;
  doc.Print(&printer);
  return printer.CStr();
}

void ModelBuilder::checkInertias(const tinyxml2::XMLElement* robot, const RigidBodies& bodies, const urdf::ModelInterface& urdf) {
  auto element = [&](const std::string& link) -> const tinyxml2::XMLElement* {
    for (auto* e = robot->FirstChildElement("link"); e; e = e->NextSiblingElement("link"))
      if (e->Attribute("name") && link == e->Attribute("name")) {
        const tinyxml2::XMLElement* in = e->FirstChildElement("inertial");
        const tinyxml2::XMLElement* I = in ? in->FirstChildElement("inertia") : nullptr;
        return I ? I : e;
      }
    return robot;
  };
  // group -> (link, fault) of the links whose own inertia is not physical
  std::map<int, std::vector<std::pair<std::string, std::string>>> own_faults;
  for (const auto& entry : urdf.links_) {
    const urdf::Link& l = *entry.second;
    const int g = bodies.groupOf(l.name);
    if (!l.inertial || g == 0 || l.inertial->mass == 0.0) continue;
    const RigidGroup& G = bodies.groups()[g];
    const std::string fault = inertiaFault(inertiaOf(*l.inertial), l.inertial->mass * G.extent * G.extent);
    if (!fault.empty()) own_faults[g].push_back({l.name, fault});
  }
  const std::vector<RigidGroup>& groups = bodies.groups();
  inertia_of_group_.resize(groups.size());
  for (size_t g = 1; g < groups.size(); ++g) {
    inertia_of_group_[g] = groups[g].Jp;
    const std::string fault = inertiaFault(groups[g].Jp, groups[g].inertiaScale());
    const auto own = own_faults.find(static_cast<int>(g));
    if (!fault.empty()) {
      const std::string link = own != own_faults.end() ? own->second.front().first : groups[g].first_link;
      if (options_.strict_inertia)
        fail(element(link), "the rigid body of link '" + groups[g].first_link + "' (with the links fixed to it): " +
                                fault + "; fix the <inertia> of link '" + link + "'");
      Eigen::Vector3d before, after;
      inertia_of_group_[g] = nearestPhysicalInertia(groups[g].Jp, &before, &after);
      std::ostringstream os;
      os.precision(6);
      os << "body '" << groups[g].first_link << "': its " << fault << "; principal moments (" << before(0) << ", "
         << before(1) << ", " << before(2) << ") -> (" << after(0) << ", " << after(1) << ", " << after(2)
         << ") kg m^2, the nearest physical inertia (fix the <inertia> of link '" << link
         << "'; strict_inertia refuses)";
      inertia_notes_.push_back(os.str());
      continue;
    }
    if (own == own_faults.end()) continue;
    for (const auto& [link, why] : own->second)
      inertia_notes_.push_back("link '" + link + "': its own " + why + "; it is fixed to body '" +
                               groups[g].first_link + "', whose inertia is physical, and runs");
  }
  if (!bodies.massless().empty()) {
    std::string names;
    for (const std::string& l : bodies.massless()) names += (names.empty() ? "'" : ", '") + l + "'";
    inertia_notes_.push_back("links of mass 0 with a non-zero inertia: " + names +
                             ": their inertia is dropped (a body without mass has none; MuJoCo does the same)");
  }
}

void ModelBuilder::addBodies(const RigidBodies& bodies, const std::map<std::string, Isometry3d>& placed,
               const urdf::ModelInterface& urdf) {
  const std::vector<RigidGroup>& groups = bodies.groups();
  body_of_group_.assign(groups.size(), Mechanism::kGround);
  for (size_t g = 1; g < groups.size(); ++g) {
    Body b;
    b.name = groups[g].first_link;
    b.m = groups[g].mass;
    b.Jp = inertia_of_group_[g];
    const Isometry3d W_B = placed.at(groups[g].first_link) * groups[g].link_T_body;
    b.r = W_B.translation();
    b.p = Quaterniond(W_B.linear());
    body_of_group_[g] = mech().addBody(b);
  }
  for (const auto& entry : urdf.links_) {
    Link l;
    l.name = entry.first;
    l.body = body_of_group_[bodies.groupOf(l.name)];
    l.body_T_link = bodies.bodyTLink(l.name);
    model_->links_.push_back(l);
  }
}

JointFrame ModelBuilder::frameOn(const RigidBodies& bodies, const std::string& link, const Isometry3d& L_J) const {
  const Isometry3d B_J = bodies.bodyTLink(link) * L_J;
  JointFrame f;
  f.sp_B = B_J.translation();
  f.Rp = B_J.linear();
  return f;
}

std::unique_ptr<MechanismModel> loadModelString(const std::string& xml, const std::string& source,
                                                const LoadOptions& options) {
  // The error contract: one line naming the file and, from the core, the joint or body at
  // fault; nothing else escapes.
  std::unique_ptr<MechanismModel> model;
  try {
    model = ModelBuilder(xml, source, options).build();
  } catch (const LoadError&) {
    throw;
  } catch (const Error& e) {  // ModelError, SimulationError, InternalError (which says it is one)
    throw LoadError(source + ": " + e.what());
  } catch (const std::bad_alloc&) {
    throw LoadError(source + ": out of memory while building the model");
  } catch (const std::exception& e) {
    throw LoadError(source + ": " + InternalError(e.what()).what());
  }
  return model;
}

std::unique_ptr<MechanismModel> loadModelFile(const std::string& path, const LoadOptions& options) {
  if (options.closures_file.empty())  // an "Extended URDF" YAML beside the file (loop_dialects.h)
    if (const std::string yaml = siblingClosuresFile(path); !yaml.empty()) {
      LoadOptions with = options;
      with.closures_file = yaml;
      return loadModelFile(path, with);
    }
  if (isXacroFile(path)) return loadModelString(expandXacro(path, options.xacro_args), path + " (xacro expansion)", options);
  if (!options.xacro_args.empty())
    throw LoadError(path + ": xacro arguments (name:=value) given, but the file is not a .xacro file");
  std::ifstream in(path);
  if (!in) throw LoadError(path + ": cannot open the file");
  std::stringstream ss;
  ss << in.rdbuf();
  return loadModelString(ss.str(), path, options);
}

}  // namespace mechanism_sim
