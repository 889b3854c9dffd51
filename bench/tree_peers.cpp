// One RK4 step of 1 ms of a free robot arm, and one forward-dynamics call, here and in
// Pinocchio and RBDL, in one process and interleaved, from the same state (these machines are
// noisy: compare the ratios of one run; callgrind's instruction counts are exact:
// bench/tree_peers.sh). Figures in bench/RESULTS.md, how to build it in doc/testing.md.
//
//   bench_tree_peers [--steps N] [--repeats R] [--only ENGINE:WHAT] FILE...
//
// The same mechanism in all three: the file's tree, fixed joints merged into their parents,
// the root welded to the world, gravity as the file gives it (the loader's), and each joint's
// <dynamics damping> as an effort -c q_dot. The peers have no joint limits: a run that reaches
// one here stops the program (take fewer steps; the default 200 stay clear of them). Here: the joint formulation, MechanismModel's
// step (the facade: joint state, integration, limits, damping, everything a run does). The
// peers: their forward dynamics (Pinocchio's aba, RBDL's ForwardDynamics, the articulated-body
// algorithm both) inside the classic RK4 tableau, the damping effort added at each stage,
// positions summed as vectors (revolute and prismatic joints only). The bare call is each
// engine's articulated-body forward dynamics at the start state (here: forwardDynamics of the
// joint formulation's tree, what a stage calls). Pinocchio's model is built here from the
// URDF as its own parser builds it (revolute joints about a coordinate axis as RX/RY/RZ, other
// axes unaligned); RBDL's by its URDF reader addon (rbdlText).
//
// --only ENGINE:WHAT (ENGINE here|pinocchio|rbdl, WHAT step|fd) runs that alone N times after
// loading, for callgrind (the difference of two N, tree_peers.sh).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/multibody.hpp>

#include <rbdl/rbdl.h>
#include <rbdl/addons/urdfreader/urdfreader.h>

#include <urdf_parser/urdf_parser.h>

#include "core/joint_space/tree.h"
#include "cpu_time.h"
#include "mechanism_sim/core/mechanism.h"
#include "mechanism_sim/urdf/model.h"

namespace {

using bench::cpuSeconds;
using bench::median;

constexpr double kStep = 1e-3;

// The start state, by joint name: a pose away from the axes' alignments and a swing.
double startAngle(int i) { return (i % 2 ? -0.4 : 0.3) + 0.05 * i; }
double startRate(int i) { return 0.5 - 0.1 * i; }

pinocchio::SE3 pose(const urdf::Pose& p) {
  double x, y, z, w;
  p.rotation.getQuaternion(x, y, z, w);
  return pinocchio::SE3(Eigen::Quaterniond(w, x, y, z).toRotationMatrix(),
                        Eigen::Vector3d(p.position.x, p.position.y, p.position.z));
}

pinocchio::Inertia inertia(const urdf::Link& link) {
  if (!link.inertial) return pinocchio::Inertia::Zero();
  const urdf::Inertial& I = *link.inertial;
  Eigen::Matrix3d J;
  J << I.ixx, I.ixy, I.ixz, I.ixy, I.iyy, I.iyz, I.ixz, I.iyz, I.izz;
  return pose(I.origin).act(pinocchio::Inertia(I.mass, Eigen::Vector3d::Zero(), J));
}

// The joints of `link`'s children, each under `parent` at `placement` (the fixed joints on
// the way merged into the parent's body), as Pinocchio's URDF parser builds them.
void addChildren(const urdf::ModelInterface& doc, const urdf::Link& link, pinocchio::Model& model,
                 pinocchio::JointIndex parent, const pinocchio::SE3& placement, std::map<std::string, int>& q_index) {
  for (const urdf::JointSharedPtr& j : link.child_joints) {
    const urdf::Link& child = *doc.getLink(j->child_link_name);
    const pinocchio::SE3 X = placement * pose(j->parent_to_joint_origin_transform);
    if (j->type == urdf::Joint::FIXED) {
      model.appendBodyToJoint(parent, X.act(inertia(child)), pinocchio::SE3::Identity());
      addChildren(doc, child, model, parent, X, q_index);
      continue;
    }
    const Eigen::Vector3d axis(j->axis.x, j->axis.y, j->axis.z);
    const bool revolute = j->type == urdf::Joint::REVOLUTE || j->type == urdf::Joint::CONTINUOUS;
    if (!revolute && j->type != urdf::Joint::PRISMATIC) {
      std::fprintf(stderr, "joint '%s': only revolute, continuous, prismatic and fixed joints here\n",
                   j->name.c_str());
      std::exit(2);
    }
    pinocchio::JointIndex id;
    auto along = [&](int k) { return axis.isApprox(Eigen::Vector3d::Unit(k)); };
    if (revolute && along(0)) id = model.addJoint(parent, pinocchio::JointModelRX(), X, j->name);
    else if (revolute && along(1)) id = model.addJoint(parent, pinocchio::JointModelRY(), X, j->name);
    else if (revolute && along(2)) id = model.addJoint(parent, pinocchio::JointModelRZ(), X, j->name);
    else if (revolute) id = model.addJoint(parent, pinocchio::JointModelRevoluteUnaligned(axis), X, j->name);
    else if (along(0)) id = model.addJoint(parent, pinocchio::JointModelPX(), X, j->name);
    else if (along(1)) id = model.addJoint(parent, pinocchio::JointModelPY(), X, j->name);
    else if (along(2)) id = model.addJoint(parent, pinocchio::JointModelPZ(), X, j->name);
    else id = model.addJoint(parent, pinocchio::JointModelPrismaticUnaligned(axis), X, j->name);
    model.appendBodyToJoint(id, inertia(child), pinocchio::SE3::Identity());
    q_index[j->name] = model.joints[id].idx_q();
    addChildren(doc, child, model, id, pinocchio::SE3::Identity(), q_index);
  }
}

// One classic RK4 step of h of q_ddot = f(q, q_dot) (vector positions).
template <class F>
void rk4(F&& f, Eigen::VectorXd& q, Eigen::VectorXd& v, double h, Eigen::VectorXd* k) {
  // k: scratch of 8 vectors (the stages' rates of v, then the stage state q, v)
  Eigen::VectorXd &a1 = k[0], &a2 = k[1], &a3 = k[2], &a4 = k[3], &qs = k[4], &vs = k[5], &v2 = k[6], &v3 = k[7];
  f(q, v, a1);
  qs = q + 0.5 * h * v;
  vs = v + 0.5 * h * a1;
  v2 = vs;
  f(qs, vs, a2);
  qs = q + 0.5 * h * v2;
  vs = v + 0.5 * h * a2;
  v3 = vs;
  f(qs, vs, a3);
  qs = q + h * v3;
  vs = v + h * a3;
  f(qs, vs, a4);
  q += (h / 6.0) * (v + 2.0 * v2 + 2.0 * v3 + vs);
  v += (h / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
}

// The file's text for RBDL's reader: the root link's <inertial> left out (the root is welded
// to the world, so its inertia acts on nothing; the reader refuses a root with inertia and
// no mass, as the KUKA arm's base is written).
std::string rbdlText(const std::string& file, const std::string& root) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  const std::string x = text.str();
  std::smatch m;
  const std::regex link("<link\\s+name=\"" + root + "\"[^>]*>([^]*?)</link>");
  if (!std::regex_search(x, m, link)) return x;
  const std::string body = std::regex_replace(m[1].str(), std::regex("<inertial\\b[^]*?</inertial>"), "");
  return x.substr(0, m.position(1)) + body + x.substr(m.position(1) + m.length(1));
}

struct Runs {
  std::vector<double> step, fd;
};

}  // namespace

int main(int argc, char** argv) {
  int steps = 200, repeats = 31;
  std::string only;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--steps" && i + 1 < argc) steps = std::atoi(argv[++i]);
    else if (a == "--repeats" && i + 1 < argc) repeats = std::atoi(argv[++i]);
    else if (a == "--only" && i + 1 < argc) only = argv[++i];
    else if (!a.empty() && a[0] == '-') files.clear(), i = argc;
    else files.push_back(a);
  }
  if (files.empty() || steps < 1 || repeats < 1) {
    std::fprintf(stderr, "usage: %s [--steps N] [--repeats R] [--only here|pinocchio|rbdl:step|fd] FILE...\n", argv[0]);
    return 2;
  }
  if (only.empty()) {
    std::printf("| robot | dofs | µs a step: here | Pinocchio | RBDL | µs a forward dynamics: here | Pinocchio | RBDL "
                "| q after 1 step, largest difference to here: Pinocchio | RBDL |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  }
  for (const std::string& file : files) {
    urdf::ModelInterfaceSharedPtr doc = urdf::parseURDFFile(file);
    if (!doc) {
      std::fprintf(stderr, "%s: urdfdom cannot read it\n", file.c_str());
      return 1;
    }
    // the start state, by joint name
    std::vector<std::string> names;
    std::map<std::string, double> q_start, v_start, damping;
    mechanism_sim::LoadOptions options;
    options.formulation = "joint";
    {
      auto probe = mechanism_sim::loadModelFile(file, options);
      for (const mechanism_sim::Dof& d : probe->dofs()) names.push_back(d.joint);
    }
    for (size_t i = 0; i < names.size(); ++i) {
      q_start[names[i]] = startAngle(static_cast<int>(i));
      v_start[names[i]] = startRate(static_cast<int>(i));
      options.positions.emplace_back(names[i], q_start[names[i]]);
      options.velocities.emplace_back(names[i], v_start[names[i]]);
      const urdf::JointConstSharedPtr j = doc->getJoint(names[i]);
      damping[names[i]] = j && j->dynamics ? j->dynamics->damping : 0.0;
    }
    const int n = static_cast<int>(names.size());

    // here
    auto model = mechanism_sim::loadModelFile(file, options);
    mechanism_sim::Mechanism& mech = model->mechanism();
    const mechanism_sim::Mechanism::Snapshot start = mech.snapshot();
    const Eigen::Vector3d g = mech.gravity();
    const mechanism_sim::System& sys = mech.system();
    const mechanism_sim::TreeModel tree(sys);
    mechanism_sim::TreeWorkspace ws(tree);
    Eigen::VectorXd tree_tau(tree.nv), tree_qddot(tree.nv);
    std::vector<int> tree_index(n), tree_damped;  // per name: its coordinate in the State
    for (int i = 0; i < n; ++i) {
      const mechanism_sim::Dof& d = model->dofs()[i];
      tree_index[i] = mech.treeCoordinate(d.joint_index, true);
    }
    for (int i = 0; i < n; ++i) tree_tau(tree_index[i]) = -damping[names[i]] * v_start[names[i]];

    // Pinocchio
    pinocchio::Model pm;
    std::map<std::string, int> pin_q;
    addChildren(*doc, *doc->getRoot(), pm, 0, pinocchio::SE3::Identity(), pin_q);
    pm.gravity.linear(g);
    pinocchio::Data pd(pm);
    Eigen::VectorXd pin_c = Eigen::VectorXd::Zero(pm.nv), pin_q0(pm.nq), pin_v0(pm.nv);
    for (int i = 0; i < n; ++i) {
      const int k = pin_q.at(names[i]);
      pin_q0(k) = q_start[names[i]], pin_v0(k) = v_start[names[i]], pin_c(k) = damping[names[i]];
    }
    // RBDL
    RigidBodyDynamics::Model rm;
    if (!RigidBodyDynamics::Addons::URDFReadFromString(rbdlText(file, doc->getRoot()->name).c_str(), &rm, false)) {
      std::fprintf(stderr, "%s: RBDL's URDF reader cannot read it\n", file.c_str());
      return 1;
    }
    rm.gravity = g;
    Eigen::VectorXd rbdl_c = Eigen::VectorXd::Zero(rm.qdot_size), rbdl_q0(rm.q_size), rbdl_v0(rm.qdot_size);
    for (int i = 0; i < n; ++i) {
      const unsigned body = rm.GetBodyId(doc->getJoint(names[i])->child_link_name.c_str());
      const int k = static_cast<int>(rm.mJoints[body].q_index);
      rbdl_q0(k) = q_start[names[i]], rbdl_v0(k) = v_start[names[i]], rbdl_c(k) = damping[names[i]];
    }
    if (pm.nv != n || rm.qdot_size != static_cast<unsigned>(n) || tree.nv != n) {
      std::fprintf(stderr, "%s: the engines disagree on the dofs (%d here, %d Pinocchio, %u RBDL)\n", file.c_str(), n,
                   pm.nv, rm.qdot_size);
      return 1;
    }

    Eigen::VectorXd k[8], q, v, tau(n);
    for (Eigen::VectorXd& x : k) x.setZero(n);  // (RBDL writes q_ddot into a vector of its size)
    auto pinF = [&](const Eigen::VectorXd& qs, const Eigen::VectorXd& vs, Eigen::VectorXd& a) {
      tau = -pin_c.cwiseProduct(vs);
      a = pinocchio::aba(pm, pd, qs, vs, tau);
    };
    auto rbdlF = [&](const Eigen::VectorXd& qs, const Eigen::VectorXd& vs, Eigen::VectorXd& a) {
      tau = -rbdl_c.cwiseProduct(vs);
      RigidBodyDynamics::ForwardDynamics(rm, qs, vs, tau, a);
    };
    Eigen::VectorXd rbdl_a(n);
    auto run = [&](const std::string& engine, const std::string& what, int count) {
      if (engine == "here" && what == "step") {
        mech.restore(start);
        for (int s = 0; s < count; ++s) mech.step(kStep);
        // (a joint limit the arm reached is a stop here and nothing to the peers: the runs
        // would not do the same work)
        for (signed char side : mech.state().limit_side)
          if (side != 0) {
            std::fprintf(stderr, "%s: a joint limit is reached within %d steps; take fewer\n", file.c_str(), count);
            std::exit(1);
          }
      } else if (engine == "here" && what == "fd") {
        for (int s = 0; s < count; ++s)
          mechanism_sim::forwardDynamics(tree, sys, start.q, start.qdot, tree_tau, ws, tree_qddot);
      } else if (engine == "pinocchio" && what == "step") {
        q = pin_q0, v = pin_v0;
        for (int s = 0; s < count; ++s) rk4(pinF, q, v, kStep, k);
      } else if (engine == "pinocchio" && what == "fd") {
        tau = -pin_c.cwiseProduct(pin_v0);
        for (int s = 0; s < count; ++s) pinocchio::aba(pm, pd, pin_q0, pin_v0, tau);
      } else if (engine == "rbdl" && what == "step") {
        q = rbdl_q0, v = rbdl_v0;
        for (int s = 0; s < count; ++s) rk4(rbdlF, q, v, kStep, k);
      } else if (engine == "rbdl" && what == "fd") {
        tau = -rbdl_c.cwiseProduct(rbdl_v0);
        for (int s = 0; s < count; ++s) RigidBodyDynamics::ForwardDynamics(rm, rbdl_q0, rbdl_v0, tau, rbdl_a);
      } else {
        std::fprintf(stderr, "--only %s:%s: ENGINE here|pinocchio|rbdl, WHAT step|fd\n", engine.c_str(), what.c_str());
        std::exit(2);
      }
    };
    if (!only.empty()) {
      const size_t colon = only.find(':');
      run(only.substr(0, colon), colon == std::string::npos ? "" : only.substr(colon + 1), steps);
      continue;
    }
    // the three agree: q after one step, by joint name
    run("here", "step", 1);
    run("pinocchio", "step", 1);
    const Eigen::VectorXd pin_q1 = q;
    run("rbdl", "step", 1);
    double d_pin = 0, d_rbdl = 0;
    for (int i = 0; i < n; ++i) {
      const double here = mech.state().q(tree_index[i]);
      const unsigned body = rm.GetBodyId(doc->getJoint(names[i])->child_link_name.c_str());
      d_pin = std::max(d_pin, std::abs(pin_q1(pin_q.at(names[i])) - here));
      d_rbdl = std::max(d_rbdl, std::abs(q(rm.mJoints[body].q_index) - here));
    }
    std::map<std::string, Runs> times;
    const char* engines[] = {"here", "pinocchio", "rbdl"};
    for (int r = 0; r < repeats; ++r)
      for (const char* e : engines)
        for (const char* what : {"step", "fd"}) {
          const double t0 = cpuSeconds();
          run(e, what, steps);
          const double us = (cpuSeconds() - t0) / steps * 1e6;
          (std::string(what) == "step" ? times[e].step : times[e].fd).push_back(us);
        }
    std::printf("| %s | %d | %.2f | %.2f | %.2f | %.3f | %.3f | %.3f | %.1e | %.1e |\n", file.c_str(), n,
                median(times["here"].step), median(times["pinocchio"].step), median(times["rbdl"].step),
                median(times["here"].fd), median(times["pinocchio"].fd), median(times["rbdl"].fd), d_pin, d_rbdl);
    std::fflush(stdout);
  }
  return 0;
}
