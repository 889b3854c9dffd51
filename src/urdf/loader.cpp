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

namespace mechanism_sim {

using Eigen::Isometry3d;
using namespace urdf_input;

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
using Coordinate = std::pair<std::string, int>;

// Initial values by coordinate: the file's <mechanism_sim:initial>, then the options.
struct InitialValues {
  std::map<Coordinate, double> positions;   // placed by forward kinematics, held in assembly
  std::map<Coordinate, double> velocities;  // held in assembly
  std::map<Coordinate, bool> velocity_from_file;  // whether the file gave it (else the options)
  // Where a joint starts that nobody placed, because the file's zero pose lies outside its
  // limits (the nearest limit): placed like `positions`, but not held: assembly keeps every
  // coordinate within its limits as a bound, and a loop may need the joint off its limit.
  std::map<Coordinate, double> limit_starts;
  // A mimic follower's place, from its leader's start: placed, not held (the coupler holds it).
  std::map<Coordinate, double> followers;
  JointValues coordinates() const {
    JointValues q;
    for (const auto* m : {&followers, &limit_starts, &positions})
      for (const auto& p : *m) {
        q[p.first.first].resize(3, 0.0);
        q[p.first.first][p.first.second] = p.second;
      }
    return q;
  }
};

}  // namespace

class ModelBuilder {
 public:
  ModelBuilder(const std::string& xml, const std::string& source, const LoadOptions& options)
      : xml_(xml), options_(options) {
    reader_.file = source;
  }

  std::unique_ptr<MechanismModel> build() {
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
    const std::string balls = mergeMasslessGimbals(&specs, *urdf, ext, transmissions, options_);  // (massless_gimbals.h)
    if (!balls.empty()) root_notes_.push_back(balls);
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
    for (const JointSpec& s : specs.tree) addMimic(s, specs);
    for (const JointSpec& s : specs.tree) tree_joints_.push_back(s.name);
    for (const Coupling& c : resolveCouplings(ext, specs, reader_)) addCoupling(c);
    for (int c : addLinearCouplings(ext.linear_couplings, specs, joint_index_, mech(), reader_))
      model_->couplings_.push_back({mech().constraint(c).name(), c});
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
    return std::move(model_);
  }

 private:
  Mechanism& mech() { return *model_->mechanism_; }
  [[noreturn]] void fail(const tinyxml2::XMLElement* e, const std::string& what) const { reader_.fail(e, what); }
  [[noreturn]] void fail(const std::string& what) const { throw LoadError(reader_.file + ": " + what); }

  // A dof name ("joint" or "joint.dof") as a coordinate; e: the element naming it, if any.
  Coordinate locate(const JointSpecs& specs, const std::string& dof, const tinyxml2::XMLElement* e) const {
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

  InitialValues initialValues(const JointSpecs& specs, const Extension& ext) const {
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

  // Elements that are read (valid URDF) but not simulated, listed once so nothing is
  // dropped without a word: transmissions, safety controllers, calibrations, collision
  // shapes (no contact is simulated), Gazebo extensions other than SDF joints and links (plugins,
  // materials, sensors) and other tools' top-level elements (<mujoco>, ...). Visuals and
  // materials are for viewers (rviz reads them) and not listed.
  void noteIgnored(const tinyxml2::XMLElement* robot, const std::map<std::string, int>& transmission_types) {
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

  // Several root links (links no joint has as child: a stray object beside a robot, a
  // second robot): the root with the most links below it (the first in the file among
  // equals) is the model's root; each other root gets a floating joint from it, so it and
  // its subtree move freely, as Drake does with a model's extra roots (MuJoCo welds them to
  // the world). urdfdom takes only one root, so it reads the document with these joints.
  // Drake's URDF parser takes the link name 'world' for the world body, declared or not: a
  // joint whose parent is 'world' welds (or hinges) its child to the world. A file that names
  // 'world' in a joint and declares no such link gets one (before urdfdom reads the file, which
  // would refuse the joint), and it is the model's root: ground. A fixed joint with 'world' as
  // its child is the same weld read the other way; other joints need the world as parent.
  bool addImplicitWorld(tinyxml2::XMLDocument& doc, tinyxml2::XMLElement* robot) {
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

  void floatExtraRoots(tinyxml2::XMLDocument& doc, tinyxml2::XMLElement* robot, const std::vector<std::string>& roots,
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

  static std::string printed(const tinyxml2::XMLDocument& doc) {
    tinyxml2::XMLPrinter printer;
    doc.Print(&printer);
    return printer.CStr();
  }

  // Inertia is judged where it acts: on the rigid body that links joined by fixed joints
  // make. A link whose own inertia is not physical (a finger pad's six entries of 1e-10)
  // but merges into a body whose inertia is runs, with a note; a body whose merged inertia
  // is not physical runs with the nearest physical one (nearestPhysicalInertia), with one
  // note giving its principal moments before and after, or with strict_inertia is refused
  // at the <inertia> of the link at fault. Mass-0 links' inertia is dropped (RigidBodies),
  // with a note.
  void checkInertias(const tinyxml2::XMLElement* robot, const RigidBodies& bodies, const urdf::ModelInterface& urdf) {
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

  // Real files often have a zero pose outside some joints' limits (a humanoid's elbows
  // whose range excludes 0). Such a joint, when no position is given for it, starts at its
  // nearest limit, with a note per joint (MuJoCo and pybullet start it outside and let the
  // soft limit push it in; a hard limit here cannot start violated). A position the user
  // gives outside the limits is still refused (assembly). A mimic follower is placed from
  // its leader's start; if that lies outside the follower's limits, the leader (when free
  // to) starts where the follower sits on its nearest limit. Driven joints are left to
  // their drives.
  void startInsideLimits(const JointSpecs& specs, const Extension& ext, InitialValues& in) {
    std::set<std::string> driven;
    for (const ExtDrive& d : ext.drives) driven.insert(d.dof.substr(0, d.dof.find('.')));
    for (const auto& d : options_.drives) driven.insert(d.first.substr(0, d.first.find('.')));
    std::map<std::string, const JointSpec*> by_name;
    for (const JointSpec& s : specs.tree) by_name[s.name] = &s;
    auto limited = [](const JointSpec& s) { return s.upper > s.lower && dofNames(s).size() == 1; };
    auto given = [&](const std::string& joint) -> std::optional<double> {
      for (const auto* m : {&in.positions, &in.limit_starts}) {
        const auto it = m->find({joint, 0});
        if (it != m->end()) return it->second;
      }
      return std::nullopt;
    };
    auto note = [&](const JointSpec& s, double zero, double start) {
      std::ostringstream os;
      os << "joint '" << s.name << "': its zero pose (" << zero << ") lies outside its limits [" << s.lower << ", "
         << s.upper << "]; it starts at " << start;
      limit_notes_.push_back(os.str());
    };
    // leaders and unrelated joints first, then mimic followers
    for (const JointSpec& s : specs.tree) {
      if (!s.mimic.empty() || !limited(s) || driven.count(s.name) || given(s.name)) continue;
      if (0.0 >= s.lower && 0.0 <= s.upper) continue;
      const double start = 0.0 < s.lower ? s.lower : s.upper;
      in.limit_starts[{s.name, 0}] = start;
      note(s, 0.0, start);
    }
    for (const JointSpec& s : specs.tree) {
      if (s.mimic.empty() || given(s.name)) continue;
      const auto leader = by_name.find(s.mimic);
      if (leader == by_name.end() || dofNames(*leader->second).size() != 1) continue;
      const double q_leader = given(s.mimic).value_or(0.0);
      double q = s.mimic_multiplier * q_leader + s.mimic_offset;
      if (limited(s) && (q < s.lower || q > s.upper) && s.mimic_multiplier != 0.0 && !driven.count(s.mimic) &&
          !in.positions.count({s.mimic, 0})) {
        const double target = q < s.lower ? s.lower : s.upper;
        const double q_new = (target - s.mimic_offset) / s.mimic_multiplier;
        const JointSpec& l = *leader->second;
        if (!limited(l) || (q_new >= l.lower && q_new <= l.upper)) {
          in.limit_starts[{s.mimic, 0}] = q_new;
          note(s, q, target);
          q = target;
        }
      }
      in.followers[{s.name, 0}] = q;
    }
  }

  // One core body per moving group, placed where the initial values put its first link;
  // then every link with its body.
  void addBodies(const RigidBodies& bodies, const std::map<std::string, Isometry3d>& placed,
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

  int bodyOf(const RigidBodies& bodies, const std::string& link) const { return body_of_group_[bodies.groupOf(link)]; }

  JointFrame frameOn(const RigidBodies& bodies, const std::string& link, const Isometry3d& L_J) const {
    const Isometry3d B_J = bodies.bodyTLink(link) * L_J;
    JointFrame f;
    f.sp_B = B_J.translation();
    f.Rp = B_J.linear();
    return f;
  }

  // A joint of the core, its degrees of freedom, damping, friction and limits. Fixed tree
  // joints are inside a body and floating ones leave the body free: neither is a joint.
  void addJoint(const JointSpec& s, const RigidBodies& bodies, bool tree) {
    if (s.type == "floating" || (tree && s.type == "fixed")) return;
    const int bi = bodyOf(bodies, s.parent), bj = bodyOf(bodies, s.child);
    if (bi == bj) fail(s.element, "joins links '" + s.parent + "' and '" + s.child + "' that are rigidly connected");
    std::unique_ptr<Joint> joint;
    try {
      joint = makeJoint(s.type, s.name, bi, frameOn(bodies, s.parent, s.P_J), bj, frameOn(bodies, s.child, s.C_J),
                        s.params);
    } catch (const ModelError& e) {  // an unknown type, a bad parameter
      fail(s.element, e.what());
    }
    const int index = mech().addJoint(std::move(joint));
    joint_index_[s.name] = index;
    model_->reaction_frames_.push_back(bodies.bodyTLink(s.child) * s.C_U);
    if (!tree)
      model_->loops_.push_back(LoopJoint{s.name, s.type, model_->linkIndex(s.parent), model_->linkIndex(s.child),
                                         s.P_J.translation(), s.C_J.translation()});
    const int dofs = static_cast<int>(dofNames(s).size());
    for (int k = 0; k < dofs; ++k) {
      Dof d;
      d.joint = s.name;
      d.name = dofName(s, k);
      d.joint_index = index;
      d.k = k;
      d.effort_limit = s.effort;
      d.velocity_limit = s.velocity;
      model_->dofs_.push_back(d);
      // a kinematic model has no forces: its joints' damping and friction do nothing
      if (s.damping > 0 && !kinematic_) mech().setJointDamping(index, k, s.damping);
      if (s.friction > 0 && !kinematic_) mech().setJointFriction(index, k, s.friction);
    }
    if (dofs == 1 && s.upper > s.lower) mech().setJointLimits(index, 0, s.lower, s.upper);
    if (s.sdf_no_limit) limit_notes_.push_back("joint '" + s.name + "': limits [-1e16, 1e16] (SDF's 'no limit') read as none");
  }

  // A file that names its actuated joints (Extended-URDF name_mot) makes every other dof
  // passive, loop closures included, as the reference tool's ActuationModel does.
  void markPassive(const Extension& ext) {
    if (ext.actuated.empty()) return;
    const std::set<std::string> actuated(ext.actuated.begin(), ext.actuated.end());
    for (Dof& d : model_->dofs_) d.actuated = actuated.count(d.joint) > 0;
  }

  // URDF <mimic>: an exact coupling of two one-dof joints.
  void addMimic(const JointSpec& s, const JointSpecs& specs) {
    if (s.mimic.empty()) return;
    if (s.type == "fixed") {  // no coordinate to couple; joint_state_publisher ignores it too
      limit_notes_.push_back("joint '" + s.name + "' is fixed: its <mimic> of '" + s.mimic + "' is ignored");
      return;
    }
    const auto a = joint_index_.find(s.name), b = joint_index_.find(s.mimic);
    for (const JointSpec& leader : specs.tree)
      if (leader.name == s.mimic && leader.type == "fixed")
        fail(s.element, "mimics '" + s.mimic + "', a fixed joint, which has no coordinate to follow: make '" +
                            s.name + "' fixed too (turned by its offset), or '" + s.mimic + "' movable");
    if (a == joint_index_.end() || b == joint_index_.end() || mech().joint(a->second).dof() != 1 ||
        mech().joint(b->second).dof() != 1)
      fail(s.element, "mimic needs two one-dof joints ('" + s.name + "', '" + s.mimic + "')");
    mech().addCoupler(s.name + " mimic", a->second, 0, b->second, 0, s.mimic_multiplier, s.mimic_offset);
    followers_.insert(s.name);
  }

  // URDF+ <coupling>: q_follower = ratio * q_leader, an exact coupler like <mimic>; the
  // offset 0 keeps the file's zero pose (both joints at zero there).
  void addCoupling(const Coupling& c) {
    const auto a = joint_index_.find(c.follower), b = joint_index_.find(c.leader);
    if (a == joint_index_.end() || b == joint_index_.end() || mech().joint(a->second).dof() != 1 ||
        mech().joint(b->second).dof() != 1)
      fail(c.element, "a coupling needs two one-dof joints ('" + c.leader + "', '" + c.follower + "')");
    mech().addCoupler(c.name, a->second, 0, b->second, 0, c.ratio, 0.0);
    followers_.insert(c.follower);
  }

  // The simulated <transmission>s (transmissions.h, doc/actuators.md): each joint a movable
  // one-dof joint; the actuators' rotors reflected onto the joints (System::rotors).
  void addTransmissions(const Transmissions& read) {
    std::string no_reduction;  // transmissions without a reduction, listed in one note
    if (read.repeated)
      limit_notes_.push_back(std::to_string(read.repeated) + " <transmission>s repeat another exactly (one per "
                             "hardware interface): each is read once");
    // A reduced model locks joints by making them fixed, or leaves them out, and keeps their
    // <transmission>s: those drive nothing and are not simulated, listed in one note each way
    // (ros_control's loader skips a transmission whose joint the URDF lacks, with an error).
    std::string on_fixed, on_missing;
    for (const TransmissionSpec& s : read.simulated) {
      bool fixed = false, missing = false;
      for (const std::string& joint : s.joints) {
        bool found = false;
        for (const TreeJoint& t : model_->tree_)
          if (t.name == joint) found = true, fixed = fixed || t.fixed;
        if (!found && joint_index_.find(joint) == joint_index_.end()) missing = true;
      }
      if (fixed || missing) {
        std::string& list = missing ? on_missing : on_fixed;
        list += (list.empty() ? "'" : ", '") + s.map.name + "'";
        continue;
      }
      TransmissionInfo info;
      info.map = s.map;
      const Eigen::MatrixXd E = s.map.velocityMap();
      info.E.topLeftCorner(E.rows(), E.cols()) = E;
      info.E_inv_T.topLeftCorner(E.rows(), E.cols()) = E.inverse().transpose();
      if (!s.note.empty()) no_reduction += (no_reduction.empty() ? "'" : ", '") + s.map.name + "'";
      RotorInertia rotor;
      rotor.name = s.map.name;
      for (const std::string& joint : s.joints) {
        const int d = model_->dofIndex(joint);
        const auto index = joint_index_.find(joint);
        if (index == joint_index_.end() || d < 0 || mech().joint(index->second).dof() != 1)
          fail(s.element, "joint '" + joint + "' is not a movable one-dof joint of the model" +
                              (index == joint_index_.end() && d < 0 ? " (no such joint)" : ""));
        info.dofs.push_back(d);
        rotor.coords.push_back({index->second, 0});
      }
      Eigen::VectorXd J(s.actuators.size());
      for (size_t k = 0; k < s.actuators.size(); ++k) {
        Actuator a;
        a.name = s.actuators[k];
        a.transmission = static_cast<int>(model_->transmissions_.size());
        a.k = static_cast<int>(k);
        a.ratings = read.actuators.at(a.name).ratings;
        J[k] = a.ratings.rotor_inertia;
        if (a.ratings.friction > 0 || a.ratings.damping > 0)
          limit_notes_.push_back("actuator '" + a.name + "': its friction and damping are counted in its torque "
                                 "(sizing), not applied to the motion");
        info.actuators.push_back(static_cast<int>(model_->actuators_.size()));
        model_->actuators_.push_back(a);
      }
      const Eigen::MatrixXd B = s.map.reflectedInertia(J);
      rotor.B.topLeftCorner(B.rows(), B.cols()) = B;
      // a kinematic model has no forces: its rotors do nothing (as joint damping)
      if (J.maxCoeff() > 0.0 && !kinematic_) mech().addRotorInertia(rotor);
      model_->transmissions_.push_back(info);
    }
    if (!on_missing.empty())
      limit_notes_.push_back("transmissions of joints the file does not have drive nothing and are not simulated: " +
                             on_missing);
    if (!on_fixed.empty())
      limit_notes_.push_back("transmissions of fixed joints drive nothing and are not simulated: " + on_fixed);
    if (!no_reduction.empty())
      limit_notes_.push_back("transmissions without a <mechanicalReduction> take 1, as gazebo_ros_control reads them: " +
                             no_reduction);
  }

  // <mechanism_sim:drive> and the options' velocity drives (which replace the file's
  // drive of the same dof). A velocity drive starts from the dof's initial position (its
  // initial value, else where the file's pose puts it); a profile fixes the position.
  void addDrives(const JointSpecs& specs, const Extension& ext, const InitialValues& initial) {
    std::vector<std::pair<Coordinate, ExtDrive>> drives;
    auto put = [&](const Coordinate& at, const ExtDrive& d) {
      for (auto& existing : drives)
        if (existing.first == at) {
          if (d.element) fail(d.element, "dof '" + d.dof + "' is already driven");
          existing.second = d;  // the command line's drive replaces the file's
          return;
        }
      drives.push_back({at, d});
    };
    for (const ExtDrive& d : ext.drives) put(locate(specs, d.dof, d.element), d);
    for (const auto& o : options_.drives) {
      if (!std::isfinite(o.second)) fail("drive velocity of '" + o.first + "' is not finite");
      ExtDrive d;
      d.dof = o.first;
      d.velocity = o.second;
      d.profile = "velocity";
      put(locate(specs, o.first, nullptr), d);
    }
    for (const auto& entry : drives) {  // (no structured binding: lambdas below capture these)
      const Coordinate& at = entry.first;
      const ExtDrive& d = entry.second;
      auto refuse = [&](const std::string& what) {
        if (d.element) fail(d.element, what);  // both throw
        fail("drive of '" + d.dof + "': " + what);
      };
      const auto index = joint_index_.find(at.first);
      if (index == joint_index_.end()) {
        refuse("joint '" + at.first + "' has no coordinate to drive");
        continue;  // not reached
      }
      if (!ext.actuated.empty() && std::find(ext.actuated.begin(), ext.actuated.end(), at.first) == ext.actuated.end())
        refuse("dof '" + d.dof + "' is passive: only the actuated joints (" + ext.actuated_source +
               ") take a drive; drive one of those or add this joint to them");
      for (const JointSpec& s : specs.tree)
        if (!s.mimic.empty() && (s.name == at.first || s.mimic == at.first))
          refuse("dof '" + d.dof + "' is coupled by mimic ('" + s.name + "' mimics '" + s.mimic +
                 "'); drive the joint it follows, or drop the mimic");
      // a command-line drive overrides the file's initial velocity of its dof; any other
      // pair contradicts itself
      if (initial.velocities.count(at) && (d.element || !initial.velocity_from_file.at(at)))
        refuse("dof '" + d.dof + "' is driven: its initial velocity is the drive's; remove the initial velocity");
      if (d.profile != "velocity" && initial.positions.count(at))
        refuse("dof '" + d.dof + "' follows a " + d.profile + " profile, which sets its position; remove the initial position");
      std::string error;
      try {
        DriveProfile profile;
        double q0 = 0.0;
        if (d.profile == "velocity") {
          profile = DriveProfile::velocity(d.velocity);
          const auto p = initial.positions.find(at);
          q0 = p != initial.positions.end() ? p->second : placedCoordinate(index->second, at.second);
        } else {
          profile = d.profile == "harmonic" ? DriveProfile::harmonic(d.offset, d.amplitude, d.frequency, d.phase)
                                            : DriveProfile::spline(d.t, d.position);
        }
        const int drive = mech().addDrive(index->second, at.second, profile, q0);
        for (Dof& dof : model_->dofs_)
          if (dof.joint_index == index->second && dof.k == at.second) dof.drive = drive;
      } catch (const UsageError& e) {  // a profile's points
        error = e.what();
      } catch (const ModelError& e) {
        error = e.what();
      }
      if (!error.empty()) refuse(error);
    }
  }

  // Coordinate k of a core joint in the pose the bodies were placed in.
  double placedCoordinate(int joint, int k) {
    const Joint& j = mech().joint(joint);
    auto kin = [&](int b) {
      BodyKin kb;
      if (b != Mechanism::kGround) {
        kb.r = mech().body(b).r;
        kb.A_Oi = mech().body(b).p.normalized().toRotationMatrix();
      }
      return kb;
    };
    Row rows[kMaxJointDofs];
    j.coordinates(kin(j.bodyI()), kin(j.bodyJ()), j.initialTracked(), rows);
    return rows[k].Phi;
  }

  void addSprings(const Extension& ext, const RigidBodies& bodies, const std::map<std::string, Isometry3d>& placed,
                  const urdf::ModelInterface& urdf) {
    for (const ExtSpring& sp : ext.springs) {
      for (const std::string* l : {&sp.link1, &sp.link2})
        if (!urdf.getLink(*l)) fail(sp.element, "link '" + *l + "' does not exist");
      SpringDamper s;
      s.name = sp.name;
      s.body_i = bodyOf(bodies, sp.link1);
      s.body_j = bodyOf(bodies, sp.link2);
      s.sp_i = bodies.bodyTLink(sp.link1) * sp.p1;
      s.sp_j = bodies.bodyTLink(sp.link2) * sp.p2;
      s.k = sp.k, s.c = sp.c, s.f_act = sp.force;
      s.L0 = sp.rest_length ? *sp.rest_length : ((placed.at(sp.link2) * sp.p2) - (placed.at(sp.link1) * sp.p1)).norm();
      mech().addSpring(s);
    }
  }

  void setGravityAndIntegrator(const Extension& ext) {
    if (ext.gravity) mech().setGravity(*ext.gravity);
    IntegratorOptions io = mech().integrator();
    if (!options_.integrator.empty()) io.method = options_.integrator;
    // a URDF's mechanism runs in the formulation auto picks unless asked (doc/method.md,
    // "Formulations"); the core's own default stays the seed's absolute coordinates
    io.formulation = options_.formulation.empty() ? "auto" : options_.formulation;
    // a kinematic model runs in absolute coordinates: the joint formulation's tree has no
    // inertia to factor (holdFreeDofs)
    if (kinematic_ && io.formulation == "joint")
      fail("no moving body has mass, so the model runs kinematically, in the absolute formulation; drop "
           "formulation 'joint'");
    if (kinematic_) io.formulation = "absolute";
    try {
      mech().setIntegrator(io);
    } catch (const ModelError& e) {
      throw LoadError(e.what());
    }
  }

  void assemble(const InitialValues& initial) {
    if (kinematic_) holdFreeDofs(initial);
    std::vector<CoordinateTarget> positions, velocities;
    for (const auto& p : initial.positions) positions.push_back({joint_index_.at(p.first.first), p.first.second, p.second});
    for (const auto& v : initial.velocities) {
      const int joint = joint_index_.at(v.first.first);
      if (mech().driveOf(joint, v.first.second) < 0) velocities.push_back({joint, v.first.second, v.second});
    }
    std::vector<double> placed(model_->dofs_.size());
    for (size_t d = 0; d < placed.size(); ++d) placed[d] = placedCoordinate(model_->dofs_[d].joint_index, model_->dofs_[d].k);
    try {
      mech().build();
      model_->assembly_ = mech().assemble(positions, velocities);
    } catch (const ModelError& e) {
      fail(e.what());
    }
    noteAssemblyMoves(placed);
    if (model_->assembly_.position_residual > 1e-9) {
      // (past assembly's own failure residual: dependent equations that disagree at the
      // file's precision, which assembly accepts)
      std::ostringstream os;
      os.precision(3);
      os << "the loops' dependent equations disagree by " << model_->assembly_.position_residual
         << " (relative) at the closest pose: the file's precision (axes or points that should meet miss by a "
            "rounding); the independent ones are held";
      model_->notes_.push_back(os.str());
    }
    model_->command_.assign(model_->dofs_.size(), 0.0);
    model_->initial_ = mech().snapshot();
  }

  // A kinematic model (no moving body has mass: a file without <inertial>s, as industrial
  // arms' support packages and grippers' visualisation packages are) has no dynamics: each
  // degree of freedom of its tree that the loops and couplers leave free is driven (a
  // drive of the file or the options), else held where it starts by a velocity drive of
  // velocity 0 (which drive commands and trajectories move like any velocity drive); the
  // rest are solved from the loops and couplers at every step (doc/method.md, "Kinematic
  // models"). A dof is held when its drive's equation is independent of the others and of
  // the dofs held before it, tried in this order: the dofs given a
  // position, the tree's other dofs, then mimic and coupling followers
  // (independentCoordinates, before build: the held dofs' drives enter the System with
  // the others, so assembly finds every motion prescribed).
  void holdFreeDofs(const InitialValues& initial) {
    std::vector<int> order;
    std::set<std::string> tree(tree_joints_.begin(), tree_joints_.end());
    for (int pass = 0; pass < 3; ++pass)
      for (size_t d = 0; d < model_->dofs_.size(); ++d) {
        const Dof& dof = model_->dofs_[d];
        if (!tree.count(dof.joint)) continue;
        const bool given = initial.positions.count({dof.joint, dof.k}) > 0, follower = followers_.count(dof.joint) > 0;
        if ((pass == 0 && given) || (pass == 1 && !given && !follower) || (pass == 2 && !given && follower))
          order.push_back(static_cast<int>(d));
      }
    int held = 0, driven = 0, solved = 0;
    std::vector<std::pair<int, int>> candidates;
    std::vector<int> candidate_dof;
    for (const int d : order) {
      const Dof& dof = model_->dofs_[d];
      if (dof.drive >= 0) {
        ++driven;
        continue;
      }
      candidates.push_back({dof.joint_index, dof.k});
      candidate_dof.push_back(d);
    }
    std::vector<char> free;
    try {
      free = independentCoordinates(mech().system(), candidates);
    } catch (const ModelError&) {
      return;  // the model is invalid: build() names why
    }
    for (size_t i = 0; i < free.size(); ++i) {
      Dof& dof = model_->dofs_[candidate_dof[i]];
      if (!free[i]) {  // its motion follows from the loops, couplers and drives
        ++solved;
        continue;
      }
      dof.drive = mech().addDrive(dof.joint_index, dof.k, DriveProfile::velocity(0.0),
                                  placedCoordinate(dof.joint_index, dof.k));
      ++held;
      if (initial.velocities.count({dof.joint, dof.k}))
        fail("dof '" + dof.name + "' is held (no moving body has mass, so the model runs kinematically): its initial "
             "velocity would be lost; drive it instead (--drive " + dof.name + "=VELOCITY)");
    }
    model_->kinematic_ = true;
    model_->notes_.push_back("kinematic: no moving body has mass; " + std::to_string(held) + " dofs held, " +
                             std::to_string(driven) + " driven, " + std::to_string(solved) +
                             " solved from the loops and couplers");
  }

  // "assembly moved N of M dofs ...: dof old -> new, ...": the dofs whose positions the
  // assembly changed by more than 1e-6 relative (1 m or 1 rad the smallest scale), as when
  // a file's zero pose leaves its loops open.
  void noteAssemblyMoves(const std::vector<double>& placed) {
    std::ostringstream os;
    os.precision(4);
    int moved = 0;
    for (size_t d = 0; d < placed.size(); ++d) {
      const double now = model_->position(static_cast<int>(d));
      if (!(std::fabs(now - placed[d]) > 1e-6 * std::max(1.0, std::fabs(placed[d])))) continue;
      os << (moved++ ? ", " : "") << model_->dofs_[d].name << " " << placed[d] << " -> " << now;
    }
    if (moved)
      model_->notes_.push_back("assembly moved " + std::to_string(moved) + " of " + std::to_string(placed.size()) +
                               " dofs (the file's pose does not close its loops): " + os.str());
  }

  std::string xml_;
  LoadOptions options_;
  XmlReader reader_;
  std::unique_ptr<MechanismModel> model_;
  std::vector<int> body_of_group_;          // core body of each rigid group
  std::vector<Matrix3d> inertia_of_group_;  // each rigid group's inertia, made physical (checkInertias)
  bool kinematic_ = false;                  // no moving body has mass (holdFreeDofs)
  std::vector<std::string> tree_joints_;    // the tree's joints, in file order
  std::set<std::string> followers_;         // mimic and coupling followers  // each rigid group's inertia, made physical (checkInertias)
  std::map<std::string, int> joint_index_;  // core joint of each joint with one
  std::vector<std::string> limit_notes_;     // joints started at a limit (startInsideLimits)
  std::vector<std::string> inertia_notes_;   // inertias dropped or judged on their body (checkInertias)
  std::vector<std::string> root_notes_;      // extra roots floated (floatExtraRoots)
  std::string ignored_note_;                 // elements read but not simulated (noteIgnored)
};

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
