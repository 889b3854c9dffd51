#include "couplings.h"

#include <set>

#include "joint_specs.h"
#include "mechanism_sim/core/mechanism.h"
#include "xml_input.h"

namespace mechanism_sim {
namespace urdf_input {

using tinyxml2::XMLElement;

ExtLinearCoupling readLinearCoupling(const XMLElement* e, const XmlReader& r) {
  r.onlyAttributes(e, {"name", "constant", "backlash"});
  ExtLinearCoupling c;
  c.element = e;
  c.name = e->Attribute("name") ? e->Attribute("name") : "";
  if (c.name.empty()) r.fail(e, "missing attribute 'name'");
  c.c0 = r.number(e, "constant", 0.0);
  c.backlash = r.number(e, "backlash", 0.0);
  if (!(c.backlash >= 0.0)) r.fail(e, "backlash is negative (the clearance on the coupled sum, 0 for none)");
  for (const XMLElement* j = e->FirstChildElement(); j; j = j->NextSiblingElement()) {
    if (std::string(j->Name()) != "joint") r.fail(j, "unknown element in <mechanism_sim:coupling> (joint)");
    r.onlyAttributes(j, {"name", "dof", "coefficient"});
    ExtLinearCoupling::Term t;
    t.element = j;
    if (!j->Attribute("name")) r.fail(j, "missing attribute 'name'");
    t.joint = j->Attribute("name");
    if (j->Attribute("dof")) t.dof = j->Attribute("dof");
    t.c = r.number(j, "coefficient", std::nullopt);
    if (t.c == 0.0) r.fail(j, "coefficient is zero (leave the joint out of the coupling instead)");
    c.terms.push_back(t);
  }
  if (c.terms.size() < 2)
    r.fail(e, "a coupling needs at least two <joint name=... coefficient=...> children (it has " +
                  std::to_string(c.terms.size()) + ")");
  return c;
}

namespace {

// The core joint and coordinate of a term, or a one-line error on its element.
std::pair<int, int> resolve(const ExtLinearCoupling::Term& t, const JointSpecs& specs,
                            const std::map<std::string, int>& joint_index, const XmlReader& r) {
  const JointSpec* spec = nullptr;
  for (const auto* list : {&specs.tree, &specs.loops})
    for (const JointSpec& s : *list)
      if (s.name == t.joint) spec = &s;
  if (!spec) r.fail(t.element, "unknown joint (no joint of the model has this name)");
  if (spec->type == "fixed") r.fail(t.element, "a fixed joint has no coordinate to couple");
  const auto index = joint_index.find(t.joint);
  if (index == joint_index.end()) r.fail(t.element, "this joint has no coordinate to couple");
  const std::vector<std::string>& names = dofNames(*spec);
  if (names.size() <= 1) {
    if (!t.dof.empty()) r.fail(t.element, "a one-dof joint: drop dof='" + t.dof + "'");
    return {index->second, 0};
  }
  std::string list;
  for (size_t k = 0; k < names.size(); ++k) {
    if (names[k] == t.dof) return {index->second, static_cast<int>(k)};
    list += (k ? ", " : "") + names[k];
  }
  r.fail(t.element, std::to_string(names.size()) + " degrees of freedom (" + list + "): name one with dof=\"...\"" +
                        (t.dof.empty() ? "" : " ('" + t.dof + "' is none of them)"));
  return {};  // (not reached)
}

}  // namespace

std::vector<CouplingInfo> addLinearCouplings(const std::vector<ExtLinearCoupling>& couplings, const JointSpecs& specs,
                                             const std::map<std::string, int>& joint_index, Mechanism& mech,
                                             const XmlReader& r) {
  std::vector<CouplingInfo> added;
  std::set<std::string> names;
  for (const ExtLinearCoupling& c : couplings) {
    if (!names.insert(c.name).second) r.fail(c.element, "a coupling named '" + c.name + "' comes earlier in the file");
    if (c.terms.size() > static_cast<size_t>(kMaxCouplingTerms))
      r.fail(c.element, "couples " + std::to_string(c.terms.size()) + " joints; at most " +
                            std::to_string(kMaxCouplingTerms) + " are taken");
    std::vector<Mechanism::CouplingCoordinate> terms;
    for (const ExtLinearCoupling::Term& t : c.terms) {
      const std::pair<int, int> at = resolve(t, specs, joint_index, r);
      for (const Mechanism::CouplingCoordinate& before : terms)
        if (before.joint == at.first && before.k == at.second)
          r.fail(t.element, "named twice in coupling '" + c.name + "'");
      terms.push_back({at.first, at.second, t.c});
    }
    try {
      if (c.backlash > 0.0) added.push_back({c.name, -1, mech.addBacklashCoupling(c.name, terms, c.c0, c.backlash)});
      else added.push_back({c.name, mech.addCoupling(c.name, terms, c.c0)});
    } catch (const ModelError& e) {
      r.fail(c.element, e.what());
    }
  }
  return added;
}

}  // namespace urdf_input
}  // namespace mechanism_sim
