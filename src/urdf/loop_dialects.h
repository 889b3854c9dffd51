// Loop closures written in the dialects other tools read (doc/loop_dialects.md): each
// reader turns its dialect into the loader's ExtJoint (a loop-closure joint between two
// links) or ExtCoupling (a URDF+ transmission), with the dialect's own frame conventions,
// and fails with "FILE:LINE: element: what is wrong and what to change" on anything that
// looks like a closure but cannot be read. Internal to the loader.
//
//   <loop_joint>/<loop> with <link1>,<link2>     Dojo.jl (Isaac Sim: spherical only)
//   <loop>/<loop_joint> with <predecessor>,...   URDF+ (Chignoli et al. 2024)
//   <coupling>                                   URDF+ transmission (a ratio of rates)
//   <constraint>                                 urdfdom PR 264 / urdfdom_headers PR 108
//   <drake:ball_constraint>                      Drake
//   <gazebo><link> (SDF links; their joints: xml_input.h)  Gazebo
//   closing_<name>_1 / closing_<name>_2 links    onshape-to-robot
//   robot.yaml beside robot.urdf                 "Extended URDF" (Gepetto)
#pragma once
#include <string>
#include <vector>

#include <tinyxml2.h>

#include "joint_specs.h"
#include "xml_input.h"

namespace mechanism_sim {
namespace urdf_input {

// Reads e if it is one of the XML loop dialects (by tag: loop_joint, loop, coupling,
// constraint, drake:ball_constraint) into ext; false if it is none of them.
bool readLoopDialect(const tinyxml2::XMLElement* robot, const tinyxml2::XMLElement* e, const XmlReader& reader,
                     Extension* ext);

// Gazebo: each SDF <link> of a <gazebo> block (its <pose> in the model frame, the root
// link's, or in the link its relative_to names; its <inertial>) becomes a URDF <link> of
// `doc` with a floating joint from that frame, so that it is a body of the model, free but
// for the SDF joints that name it. Returns the links added (empty: none, doc unchanged).
std::vector<std::string> addSdfLinks(tinyxml2::XMLDocument& doc, tinyxml2::XMLElement* robot, const XmlReader& reader);

// onshape-to-robot: every pair of links closing_<name>_1 / closing_<name>_2 is a ball
// joint between their origins.
void readOnshapeClosures(const tinyxml2::XMLElement* robot, const XmlReader& reader, Extension* ext);

// "Extended URDF" closures in a YAML file (closed_loop, type, name_mot, joint_name,
// joint_type). Errors name the YAML file and line. An empty path reads nothing.
void readClosuresFile(const std::string& path, const tinyxml2::XMLElement* robot, Extension* ext);

// The YAML file of closures beside a URDF file (same stem, .yaml; for FILE.urdf.xacro,
// FILE.yaml) when it exists and mentions closed_loop; else "".
std::string siblingClosuresFile(const std::string& urdf_path);

// A URDF+ coupling resolved to joints: q_follower = ratio * q_leader (both one-dof).
struct Coupling {
  std::string name, follower, leader;
  double ratio = 1.0;
  const tinyxml2::XMLElement* element = nullptr;
};
std::vector<Coupling> resolveCouplings(const Extension& ext, const JointSpecs& specs, const XmlReader& reader);

}  // namespace urdf_input
}  // namespace mechanism_sim
