// The loader's builder (loader.cpp, loader_joints.cpp, loader_start.cpp): one file read in
// the order loader.cpp's header gives, into a MechanismModel. Private to the loader.
#pragma once
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "couplings.h"
#include "joint_specs.h"
#include "loop_dialects.h"
#include "massless_gimbals.h"
#include "mechanism_sim/urdf/model.h"
#include "rigid_bodies.h"
#include "transmissions.h"
#include "xml_input.h"

namespace mechanism_sim {

using Eigen::Isometry3d;
using namespace urdf_input;

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

class ModelBuilder {
 public:
  ModelBuilder(const std::string& xml, const std::string& source, const LoadOptions& options)
      : xml_(xml), options_(options) {
    reader_.file = source;
  }

  std::unique_ptr<MechanismModel> build();

 private:
  Mechanism& mech() { return *model_->mechanism_; }
  [[noreturn]] void fail(const tinyxml2::XMLElement* e, const std::string& what) const { reader_.fail(e, what); }
  [[noreturn]] void fail(const std::string& what) const { throw LoadError(reader_.file + ": " + what); }

  // A dof name ("joint" or "joint.dof") as a coordinate; e: the element naming it, if any.
  Coordinate locate(const JointSpecs& specs, const std::string& dof, const tinyxml2::XMLElement* e) const;

  InitialValues initialValues(const JointSpecs& specs, const Extension& ext) const;

  // Elements that are read (valid URDF) but not simulated, listed once so nothing is
  // dropped without a word: transmissions, safety controllers, calibrations, collision
  // shapes (no contact is simulated), Gazebo extensions other than SDF joints and links (plugins,
  // materials, sensors) and other tools' top-level elements (<mujoco>, ...). Visuals and
  // materials are for viewers (rviz reads them) and not listed.
  void noteIgnored(const tinyxml2::XMLElement* robot, const std::map<std::string, int>& transmission_types);

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
  bool addImplicitWorld(tinyxml2::XMLDocument& doc, tinyxml2::XMLElement* robot);

  void floatExtraRoots(tinyxml2::XMLDocument& doc, tinyxml2::XMLElement* robot, const std::vector<std::string>& roots,
                       bool implicit_world);

  static std::string printed(const tinyxml2::XMLDocument& doc);

  // Inertia is judged where it acts: on the rigid body that links joined by fixed joints
  // make. A link whose own inertia is not physical (a finger pad's six entries of 1e-10)
  // but merges into a body whose inertia is runs, with a note; a body whose merged inertia
  // is not physical runs with the nearest physical one (nearestPhysicalInertia), with one
  // note giving its principal moments before and after, or with strict_inertia is refused
  // at the <inertia> of the link at fault. Mass-0 links' inertia is dropped (RigidBodies),
  // with a note.
  void checkInertias(const tinyxml2::XMLElement* robot, const RigidBodies& bodies, const urdf::ModelInterface& urdf);

  // Real files often have a zero pose outside some joints' limits (a humanoid's elbows
  // whose range excludes 0). Such a joint, when no position is given for it, starts at its
  // nearest limit, with a note per joint (MuJoCo and pybullet start it outside and let the
  // soft limit push it in; a hard limit here cannot start violated). A position the user
  // gives outside the limits is still refused (assembly). A mimic follower is placed from
  // its leader's start; if that lies outside the follower's limits, the leader (when free
  // to) starts where the follower sits on its nearest limit. Driven joints are left to
  // their drives.
  void startInsideLimits(const JointSpecs& specs, const Extension& ext, InitialValues& in);

  // One core body per moving group, placed where the initial values put its first link;
  // then every link with its body.
  void addBodies(const RigidBodies& bodies, const std::map<std::string, Isometry3d>& placed,
                 const urdf::ModelInterface& urdf);

  int bodyOf(const RigidBodies& bodies, const std::string& link) const { return body_of_group_[bodies.groupOf(link)]; }

  JointFrame frameOn(const RigidBodies& bodies, const std::string& link, const Isometry3d& L_J) const;

  // A joint of the core, its degrees of freedom, damping, friction and limits. Fixed tree
  // joints are inside a body and floating ones leave the body free: neither is a joint.
  void addJoint(const JointSpec& s, const RigidBodies& bodies, bool tree);

  // A file that names its actuated joints (Extended-URDF name_mot) makes every other dof
  // passive, loop closures included, as the reference tool's ActuationModel does.
  // A ball written as a gimbal (massless_gimbals.h) reported by the file's joints: J0's
  // three dofs become J0, J1, J2 (Dof::gimbal), J1 and J2 move in tf.
  void addGimbals(const std::vector<GimbalChain>& chains);
  void markPassive(const Extension& ext);

  // URDF <mimic>: an exact coupling of two one-dof joints.
  void addMimic(const JointSpec& s, const JointSpecs& specs);

  // URDF+ <coupling>: q_follower = ratio * q_leader, an exact coupler like <mimic>; the
  // offset 0 keeps the file's zero pose (both joints at zero there).
  void addCoupling(const Coupling& c);

  // The simulated <transmission>s (transmissions.h, doc/actuators.md): each joint a movable
  // one-dof joint; the actuators' rotors reflected onto the joints (System::rotors).
  void addTransmissions(const Transmissions& read);

  // <mechanism_sim:drive> and the options' velocity drives (which replace the file's
  // drive of the same dof). A velocity drive starts from the dof's initial position (its
  // initial value, else where the file's pose puts it); a profile fixes the position.
  void addDrives(const JointSpecs& specs, const Extension& ext, const InitialValues& initial);

  // Coordinate k of a core joint in the pose the bodies were placed in.
  double placedCoordinate(int joint, int k);

  void addSprings(const Extension& ext, const RigidBodies& bodies, const std::map<std::string, Isometry3d>& placed,
                  const urdf::ModelInterface& urdf);

  void setGravityAndIntegrator(const Extension& ext);

  void assemble(const InitialValues& initial);

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
  void holdFreeDofs(const InitialValues& initial);

  // "assembly moved N of M dofs ...: dof old -> new, ...": the dofs whose positions the
  // assembly changed by more than 1e-6 relative (1 m or 1 rad the smallest scale), as when
  // a file's zero pose leaves its loops open.
  void noteAssemblyMoves(const std::vector<double>& placed);

  std::string xml_;
  LoadOptions options_;
  XmlReader reader_;
  std::unique_ptr<MechanismModel> model_;
  std::vector<int> body_of_group_;          // core body of each rigid group
  std::vector<Matrix3d> inertia_of_group_;  // each rigid group's inertia, made physical (checkInertias)
  bool kinematic_ = false;                  // no moving body has mass (holdFreeDofs)
  std::vector<std::string> tree_joints_;    // the tree's joints, in file order
  std::set<std::string> followers_;         // mimic and coupling followers
  std::map<std::string, int> joint_index_;  // core joint of each joint with one
  std::vector<std::string> limit_notes_;     // joints started at a limit (startInsideLimits)
  std::vector<std::string> inertia_notes_;   // inertias dropped or judged on their body (checkInertias)
  std::vector<std::string> root_notes_;      // extra roots floated (floatExtraRoots)
  std::string ignored_note_;                 // elements read but not simulated (noteIgnored)
};

}  // namespace mechanism_sim
