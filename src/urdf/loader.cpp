// URDF (+ extension) -> Mechanism. Links joined by fixed joints form one body whose
// reference point is their common centre of mass and whose axes are those of the group's
// first link; every joint frame is expressed in those body frames.
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include "mechanism_sim/urdf/model.h"
#include "xml_input.h"

namespace mechanism_sim {

using Eigen::Isometry3d;
using urdf_input::ExtJoint;
using urdf_input::XmlReader;

namespace {

Isometry3d toEigen(const urdf::Pose& p) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().toRotationMatrix();
  T.translation() = Vector3d(p.position.x, p.position.y, p.position.z);
  return T;
}

// A rotation taking z onto a (unit).
Matrix3d alignZ(const Vector3d& a) { return Quaterniond::FromTwoVectors(Vector3d::UnitZ(), a).toRotationMatrix(); }

Isometry3d rotation(const Matrix3d& R) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = R;
  return T;
}

// Everything the builder knows of one joint, tree or loop, before the core sees it.
struct JointSpec {
  std::string name, type;  // core type, or "floating"
  const tinyxml2::XMLElement* element = nullptr;
  std::string parent, child;
  Isometry3d P_J = Isometry3d::Identity();  // joint frame in the parent link (axis -> z)
  Isometry3d C_J = Isometry3d::Identity();  // joint frame in the child link
  double alpha = 0.0, damping = 0.0, friction = 0.0;
  double lower = 0.0, upper = 0.0, effort = 0.0, velocity = 0.0;
  bool tree = true, sdf = false, axis_in_model = false;
  Vector3d sdf_axis = Vector3d::UnitZ(), sdf_axis2 = Vector3d::UnitY();
  bool has_axis2 = false;
  Vector3d axis = Vector3d::UnitZ(), axis2 = Vector3d::UnitY();
  std::string mimic;
  double mimic_multiplier = 1.0, mimic_offset = 0.0;
  int core = -1;
};

int dofCount(const std::string& type) {
  static const std::map<std::string, int> n = {{"revolute", 1}, {"prismatic", 1}, {"screw", 1},
                                               {"cylindrical", 2}, {"universal", 2}, {"spherical", 3},
                                               {"planar", 3}, {"fixed", 0}, {"floating", 0}};
  return n.at(type);
}

// Frame j relative to frame i for joint coordinates q (the joints' own conventions).
Isometry3d motion(const std::string& type, double alpha, const std::vector<double>& q) {
  Isometry3d T = Isometry3d::Identity();
  auto Rz = [](double a) { return Eigen::AngleAxisd(a, Vector3d::UnitZ()).toRotationMatrix(); };
  if (type == "revolute") T.linear() = Rz(q[0]);
  if (type == "prismatic") T.translation().z() = q[0];
  if (type == "screw") T.linear() = Rz(q[0]), T.translation().z() = alpha * q[0];
  if (type == "cylindrical") T.linear() = Rz(q[0]), T.translation().z() = q[1];
  if (type == "universal")
    T.linear() = (Eigen::AngleAxisd(q[0], Vector3d::UnitX()) * Eigen::AngleAxisd(q[1], Vector3d::UnitY())).toRotationMatrix();
  if (type == "spherical") T.linear() = expRotation(Vector3d(q[0], q[1], q[2])).toRotationMatrix();
  if (type == "planar") T.linear() = Rz(q[2]), T.translation() << q[0], q[1], 0;
  return T;
}

// urdfdom reports its parse errors through console_bridge, and the loader reports its own,
// so console_bridge is silenced while urdfdom parses and its level restored after (also
// when parsing throws): the embedding program's own logging is left as it was.
class ConsoleBridgeSilenced {
 public:
  ConsoleBridgeSilenced() : saved_(console_bridge::getLogLevel()) {
    console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  }
  ~ConsoleBridgeSilenced() { console_bridge::setLogLevel(saved_); }
  ConsoleBridgeSilenced(const ConsoleBridgeSilenced&) = delete;
  ConsoleBridgeSilenced& operator=(const ConsoleBridgeSilenced&) = delete;

 private:
  console_bridge::LogLevel saved_;
};

urdf::ModelInterfaceSharedPtr parseWithUrdfdom(const std::string& xml) {
  ConsoleBridgeSilenced quiet;
  return urdf::parseURDF(xml);
}

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
      os << reader_.file << ":" << doc.ErrorLineNum() << ": malformed XML: " << doc.ErrorStr();
      throw LoadError(os.str());
    }
    const tinyxml2::XMLElement* robot = doc.RootElement();
    if (!robot || std::string(robot->Name()) != "robot") reader_.fail(robot, "the root element is not <robot>");
    urdf_input::validateStandard(robot, reader_);
    ext_ = urdf_input::readExtension(robot, reader_);

    urdf_ = parseWithUrdfdom(xml_);
    if (!urdf_) throw LoadError(reader_.file + ": urdfdom could not parse the robot description");

    model_ = std::make_unique<MechanismModel>();
    model_->mechanism_ = std::make_unique<Mechanism>();
    model_->name_ = urdf_->getName();
    model_->root_link_ = urdf_->getRoot()->name;
    collectJoints(robot);
    for (const JointSpec& s : specs_)
      if (s.tree) children_[s.parent].push_back(&s);
    groupLinks();
    addBodies();
    addJoints();
    addExtras();
    assemble();
    return std::move(model_);
  }

 private:
  Mechanism& mech() { return *model_->mechanism_; }
  [[noreturn]] void fail(const tinyxml2::XMLElement* e, const std::string& what) const { reader_.fail(e, what); }

  const tinyxml2::XMLElement* urdfJointElement(const tinyxml2::XMLElement* robot, const std::string& name) {
    for (auto* e = robot->FirstChildElement("joint"); e; e = e->NextSiblingElement("joint"))
      if (name == e->Attribute("name")) return e;
    return nullptr;
  }

  void collectJoints(const tinyxml2::XMLElement* robot) {
    std::map<std::string, const ExtJoint*> overrides;
    std::set<std::string> names;
    for (const auto& j : urdf_->joints_) names.insert(j.first);
    for (const ExtJoint& e : ext_.joints) {
      if (e.loop) {
        if (names.count(e.name)) fail(e.element, "a joint named '" + e.name + "' already exists");
        names.insert(e.name);
        continue;
      }
      const auto it = urdf_->joints_.find(e.name);
      if (it == urdf_->joints_.end()) fail(e.element, "no URDF joint '" + e.name + "' to give this type to (a loop closure needs <parent> and <child>)");
      if (it->second->type == urdf::Joint::FIXED || it->second->type == urdf::Joint::FLOATING)
        fail(e.element, "cannot change the type of a fixed or floating URDF joint");
      if (overrides.count(e.name)) fail(e.element, "joint type given twice");
      overrides[e.name] = &e;
    }
    // Tree joints in file order, then loop closures in file order.
    for (auto* element = robot->FirstChildElement("joint"); element; element = element->NextSiblingElement("joint")) {
      const urdf::Joint& j = *urdf_->joints_.at(element->Attribute("name"));
      JointSpec s;
      s.name = j.name;
      s.element = urdfJointElement(robot, j.name);
      s.parent = j.parent_link_name;
      s.child = j.child_link_name;
      Vector3d axis(j.axis.x, j.axis.y, j.axis.z);
      if (axis.norm() > 0) axis.normalize(); else axis = Vector3d::UnitX();
      switch (j.type) {
        case urdf::Joint::REVOLUTE: case urdf::Joint::CONTINUOUS: s.type = "revolute"; break;
        case urdf::Joint::PRISMATIC: s.type = "prismatic"; break;
        case urdf::Joint::PLANAR: s.type = "planar"; break;
        case urdf::Joint::FLOATING: s.type = "floating"; break;
        default: s.type = "fixed";
      }
      if (j.limits && j.type != urdf::Joint::CONTINUOUS) s.lower = j.limits->lower, s.upper = j.limits->upper;
      if (j.limits) s.effort = j.limits->effort, s.velocity = j.limits->velocity;
      if (j.dynamics) s.damping = j.dynamics->damping, s.friction = j.dynamics->friction;
      if (j.mimic) s.mimic = j.mimic->joint_name, s.mimic_multiplier = j.mimic->multiplier, s.mimic_offset = j.mimic->offset;
      Vector3d axis2 = Vector3d::UnitY();
      bool has_axis2 = false;
      if (overrides.count(j.name)) {
        const ExtJoint& o = *overrides[j.name];
        s.type = o.type == "continuous" ? "revolute" : o.type;
        s.alpha = o.alpha;
        if (o.element->FirstChildElement("axis")) axis = o.axis;
        axis2 = o.axis2;
        has_axis2 = o.has_axis2;
        if (o.damping > 0) s.damping = o.damping;
        if (o.friction > 0) s.friction = o.friction;
        if (s.type != "revolute" && s.type != "prismatic") s.lower = s.upper = 0;
      }
      s.axis = axis, s.axis2 = axis2, s.has_axis2 = has_axis2;
      const Matrix3d R = frameAxes(s, s.element);
      s.P_J = toEigen(j.parent_to_joint_origin_transform) * rotation(R);
      s.C_J = rotation(R);
      specs_.push_back(s);
    }
    for (const ExtJoint& e : ext_.joints) {
      if (!e.loop) continue;
      JointSpec s;
      s.name = e.name;
      s.type = e.type == "continuous" ? "revolute" : e.type;
      s.element = e.element;
      s.parent = e.parent;
      s.child = e.child;
      s.tree = false;
      s.alpha = e.alpha;
      s.damping = e.damping;
      s.friction = e.friction;
      s.sdf = e.sdf;
      s.axis_in_model = e.axis_in_model;
      s.axis = e.axis, s.axis2 = e.axis2, s.has_axis2 = e.has_axis2;
      if (!urdf_->getLink(e.parent)) fail(e.element, "parent link '" + e.parent + "' does not exist");
      if (!urdf_->getLink(e.child)) fail(e.element, "child link '" + e.child + "' does not exist");
      if (e.parent == e.child) fail(e.element, "joint's parent is its child ('" + e.parent + "')");
      if (!e.sdf) {
        const Matrix3d R = frameAxes(s, e.element);
        s.P_J = e.origin * rotation(R);
        s.C_J = e.child_origin * rotation(R);
      } else {
        s.C_J = e.child_origin;  // SDF: the joint frame is given in the child link
      }
      specs_.push_back(s);
    }
  }

  // Joint-frame axes: z along the axis; a universal joint's x along axis, y along axis2.
  Matrix3d frameAxes(const JointSpec& s, const tinyxml2::XMLElement* e) const {
    if (s.type != "universal") return alignZ(s.axis);
    if (std::fabs(s.axis.dot(s.axis2)) > 1e-6) fail(e, "universal joint axes must be perpendicular");
    Matrix3d R;
    R.col(0) = s.axis;
    R.col(1) = (s.axis2 - s.axis.dot(s.axis2) * s.axis).normalized();
    R.col(2) = R.col(0).cross(R.col(1));
    return R;
  }

  // Groups of links joined by fixed tree joints; the group of the root is ground.
  void groupLinks() {
    std::function<void(const std::string&, int, const Isometry3d&)> visit =
        [&](const std::string& link, int group, const Isometry3d& G_L) {
          link_group_[link] = group;
          group_T_link_[link] = G_L;
          for (const JointSpec* j : children_[link]) {
            if (j->type == "fixed") {
              visit(j->child, group, G_L * j->P_J * j->C_J.inverse());
            } else {
              group_root_.push_back(j->child);
              visit(j->child, static_cast<int>(group_root_.size()) - 1, Isometry3d::Identity());
            }
          }
        };
    group_root_.push_back(model_->root_link_);
    visit(model_->root_link_, 0, Isometry3d::Identity());
  }

  void addBodies() {
    const int groups = static_cast<int>(group_root_.size());
    std::vector<double> mass(groups, 0.0);
    std::vector<Vector3d> first(groups, Vector3d::Zero());
    std::vector<Matrix3d> second(groups, Matrix3d::Zero());
    std::vector<std::vector<std::pair<double, std::pair<Vector3d, Matrix3d>>>> parts(groups);
    for (const auto& entry : urdf_->links_) {
      const urdf::Link& l = *entry.second;
      if (!l.inertial) continue;
      const int g = link_group_.at(l.name);
      const Isometry3d G_I = group_T_link_.at(l.name) * toEigen(l.inertial->origin);
      Matrix3d I;
      I << l.inertial->ixx, l.inertial->ixy, l.inertial->ixz, l.inertial->ixy, l.inertial->iyy,
          l.inertial->iyz, l.inertial->ixz, l.inertial->iyz, l.inertial->izz;
      parts[g].push_back({l.inertial->mass, {G_I.translation(), G_I.linear() * I * G_I.linear().transpose()}});
      mass[g] += l.inertial->mass;
      first[g] += l.inertial->mass * G_I.translation();
    }
    // Initial link poses by forward kinematics: nominal (all zero) and initial.
    initialValues();
    fk(nominal_, {});
    fk(initial_, initial_q_);
    body_of_group_.assign(groups, Mechanism::kGround);
    group_T_body_.assign(groups, Isometry3d::Identity());
    for (int g = 1; g < groups; ++g) {
      Body b;
      b.name = group_root_[g];
      b.m = mass[g];
      const Vector3d c = mass[g] > 0 ? Vector3d(first[g] / mass[g]) : Vector3d::Zero();
      for (const auto& p : parts[g]) {  // parallel axis theorem about the common centre
        const Vector3d d = p.second.first - c;
        b.Jp += p.second.second + p.first * (d.squaredNorm() * Matrix3d::Identity() - d * d.transpose());
      }
      b.Jp = 0.5 * (b.Jp + b.Jp.transpose());
      group_T_body_[g].translation() = c;
      const Isometry3d W_B = initial_.at(group_root_[g]) * group_T_body_[g];
      b.r = W_B.translation();
      b.p = Quaterniond(W_B.linear());
      body_of_group_[g] = mech().addBody(b);
    }
    for (const auto& entry : urdf_->links_) {
      Link l;
      l.name = entry.first;
      const int g = link_group_.at(l.name);
      l.body = body_of_group_[g];
      l.body_T_link = group_T_body_[g].inverse() * group_T_link_.at(l.name);
      model_->links_.push_back(l);
    }
    for (const JointSpec& s : specs_)
      if (s.tree) model_->tree_.push_back(TreeJoint{s.name, s.parent, s.child, s.type == "fixed"});
  }

  // Initial joint values: the file's <mechanism_sim:initial>, then the options.
  void initialValues() {
    std::map<std::string, const JointSpec*> by_name;
    for (const JointSpec& s : specs_) by_name[s.name] = &s;
    auto locate = [&](const std::string& dof, const tinyxml2::XMLElement* e) -> std::pair<std::string, int> {
      const JointSpec* s = nullptr;
      int k = 0;
      if (by_name.count(dof)) s = by_name[dof];
      const size_t dot = dof.rfind('.');
      if (!s && dot != std::string::npos && by_name.count(dof.substr(0, dot))) {
        s = by_name[dof.substr(0, dot)];
        k = -1;
        auto joint = makeJoint(s->type == "floating" ? "fixed" : s->type, "", 1, JointFrame(), 2, JointFrame(),
                               JointParams{s->alpha, 0.0});
        for (int i = 0; i < joint->dof(); ++i)
          if (joint->dofName(i) == dof.substr(dot + 1)) k = i;
        if (k < 0) s = nullptr;
      } else if (s && dofCount(s->type) != 1) {
        s = nullptr;
      }
      if (!s || dofCount(s->type) == 0) {
        const std::string what = "no joint degree of freedom named '" + dof + "'";
        if (e) fail(e, what);
        throw LoadError(reader_.file + ": " + what);
      }
      return {s->name, k};
    };
    // An initial position is placed by forward kinematics and held during assembly.
    auto hold = [&](const std::pair<std::string, int>& at, double value) {
      initial_q_[at.first].resize(3, 0.0);
      initial_q_[at.first][at.second] = value;
      held_.insert(at);
    };
    for (const auto& in : ext_.initial) {
      const auto at = locate(in.dof, in.element);
      if (in.position) hold(at, *in.position);
      if (in.velocity) initial_v_[at] = *in.velocity;
    }
    for (const auto& p : options_.positions) {
      const auto at = locate(p.first, nullptr);
      if (!std::isfinite(p.second)) throw LoadError(reader_.file + ": initial position of '" + p.first + "' is not finite");
      hold(at, p.second);
    }
    for (const auto& v : options_.velocities) {
      const auto at = locate(v.first, nullptr);
      if (!std::isfinite(v.second)) throw LoadError(reader_.file + ": initial velocity of '" + v.first + "' is not finite");
      initial_v_[at] = v.second;
    }
  }

  void fk(std::map<std::string, Isometry3d>& out, const std::map<std::string, std::vector<double>>& q) {
    std::function<void(const std::string&, const Isometry3d&)> visit = [&](const std::string& link, const Isometry3d& W) {
      out[link] = W;
      for (const JointSpec* j : children_[link]) {
        std::vector<double> values(3, 0.0);
        if (q.count(j->name)) values = q.at(j->name);
        visit(j->child, W * j->P_J * motion(j->type, j->alpha, values) * j->C_J.inverse());
      }
    };
    visit(model_->root_link_, Isometry3d::Identity());
  }

  JointFrame frameOn(const std::string& link, const Isometry3d& L_J) const {
    const int g = link_group_.at(link);
    const Isometry3d B_J = group_T_body_[g].inverse() * group_T_link_.at(link) * L_J;
    JointFrame f;
    f.sp_B = B_J.translation();
    f.Rp = B_J.linear();
    return f;
  }

  void addJoints() {
    std::map<std::string, int> core_of;
    for (JointSpec& s : specs_) {
      if (s.type == "floating" || (s.tree && s.type == "fixed")) continue;
      const int bi = body_of_group_[link_group_.at(s.parent)], bj = body_of_group_[link_group_.at(s.child)];
      if (bi == bj) fail(s.element, "joins links '" + s.parent + "' and '" + s.child + "' that are rigidly connected");
      if (s.sdf) {
        // SDF: joint frame given in the child link; the axis in the joint frame (or the model
        // frame); the parent side is where that frame sits in the nominal configuration.
        const Isometry3d W_J = nominal_.at(s.child) * s.C_J;
        auto inJoint = [&](const Vector3d& a) { return s.axis_in_model ? Vector3d(W_J.linear().transpose() * a) : a; };
        s.axis = inJoint(s.axis);
        s.axis2 = inJoint(s.axis2);
        const Matrix3d R = frameAxes(s, s.element);
        s.C_J = s.C_J * rotation(R);
        s.P_J = nominal_.at(s.parent).inverse() * nominal_.at(s.child) * s.C_J;
      }
      std::unique_ptr<Joint> joint;
      try {
        joint = makeJoint(s.type, s.name, bi, frameOn(s.parent, s.P_J), bj, frameOn(s.child, s.C_J), JointParams{s.alpha, 0.0});
      } catch (const std::invalid_argument& e) {
        fail(s.element, e.what());
      }
      const int index = mech().addJoint(std::move(joint));
      s.core = index;
      if (!s.tree)
        model_->loops_.push_back(LoopJoint{s.name, s.type, model_->linkIndex(s.parent), model_->linkIndex(s.child),
                                           s.P_J.translation(), s.C_J.translation()});
      core_of[s.name] = index;
      const Joint& j = mech().joint(index);
      for (int k = 0; k < j.dof(); ++k) {
        Dof d;
        d.joint = s.name;
        d.name = j.dof() == 1 ? s.name : s.name + "." + j.dofName(k);
        d.joint_index = index;
        d.k = k;
        d.effort_limit = s.effort;
        d.velocity_limit = s.velocity;
        model_->dofs_.push_back(d);
        if (s.damping > 0) mech().setJointDamping(index, k, s.damping);
        if (s.friction > 0) mech().setJointFriction(index, k, s.friction);
      }
      if (j.dof() == 1 && s.upper > s.lower) mech().setJointLimits(index, 0, s.lower, s.upper);
    }
    for (const JointSpec& s : specs_) {
      if (s.mimic.empty()) continue;
      if (s.core < 0 || !core_of.count(s.mimic) || mech().joint(core_of[s.mimic]).dof() != 1 || mech().joint(s.core).dof() != 1)
        fail(s.element, "mimic needs two one-dof joints ('" + s.name + "', '" + s.mimic + "')");
      mech().addCoupler(s.name + " mimic", s.core, 0, core_of[s.mimic], 0, s.mimic_multiplier, s.mimic_offset);
    }
  }

  void addExtras() {
    for (const auto& sp : ext_.springs) {
      for (const auto* l : {&sp.link1, &sp.link2})
        if (!urdf_->getLink(*l)) fail(sp.element, "link '" + *l + "' does not exist");
      SpringDamper s;
      s.name = sp.name;
      s.body_i = body_of_group_[link_group_.at(sp.link1)];
      s.body_j = body_of_group_[link_group_.at(sp.link2)];
      s.sp_i = frameOn(sp.link1, Isometry3d(Eigen::Translation3d(sp.p1))).sp_B;
      s.sp_j = frameOn(sp.link2, Isometry3d(Eigen::Translation3d(sp.p2))).sp_B;
      s.k = sp.k, s.c = sp.c, s.f_act = sp.force;
      s.L0 = sp.rest_length ? *sp.rest_length
                            : ((initial_.at(sp.link2) * sp.p2) - (initial_.at(sp.link1) * sp.p1)).norm();
      mech().addSpring(s);
    }
    if (ext_.gravity) mech().setGravity(*ext_.gravity);
    if (!options_.integrator.empty()) {
      IntegratorOptions io = mech().integrator();
      io.method = options_.integrator;
      try {
        mech().setIntegrator(io);
      } catch (const ModelError& e) {
        throw LoadError(e.what());
      }
    }
  }

  void assemble() {
    std::vector<CoordinateTarget> positions, velocities;
    std::map<std::string, int> core_of;
    for (const JointSpec& s : specs_) core_of[s.name] = s.core;
    for (const auto& h : held_) positions.push_back({core_of.at(h.first), h.second, initial_q_.at(h.first)[h.second]});
    for (const auto& v : initial_v_) velocities.push_back({core_of.at(v.first.first), v.first.second, v.second});
    try {
      mech().build();
      model_->assembly_ = mech().assemble(positions, velocities);
    } catch (const ModelError& e) {
      throw LoadError(reader_.file + ": " + e.what());
    }
    model_->command_.assign(model_->dofs_.size(), 0.0);
    model_->initial_ = mech().snapshot();
  }

  std::string xml_;
  LoadOptions options_;
  XmlReader reader_;
  urdf_input::Extension ext_;
  urdf::ModelInterfaceSharedPtr urdf_;
  std::unique_ptr<MechanismModel> model_;
  std::vector<JointSpec> specs_;
  std::map<std::string, std::vector<const JointSpec*>> children_;  // tree joints by parent link
  std::vector<std::string> group_root_;
  std::map<std::string, int> link_group_;
  std::map<std::string, Isometry3d> group_T_link_, nominal_, initial_;
  std::vector<int> body_of_group_;
  std::vector<Isometry3d> group_T_body_;
  std::map<std::string, std::vector<double>> initial_q_;
  std::set<std::pair<std::string, int>> held_;
  std::map<std::pair<std::string, int>, double> initial_v_;
};

std::unique_ptr<MechanismModel> loadModelString(const std::string& xml, const std::string& source,
                                                const LoadOptions& options) {
  return ModelBuilder(xml, source, options).build();
}

std::unique_ptr<MechanismModel> loadModelFile(const std::string& path, const LoadOptions& options) {
  std::ifstream in(path);
  if (!in) throw LoadError(path + ": cannot open the file");
  std::stringstream ss;
  ss << in.rdbuf();
  return loadModelString(ss.str(), path, options);
}

}  // namespace mechanism_sim
