#include "csv_writer.h"

#include <charconv>

namespace mechanism_sim {

namespace {

// A row's numbers as printf's %.12g writes them (std::to_chars with chars_format::general
// and a precision is specified as that conversion, C++17 [utility.to.chars]), formatted into
// one buffer and written at once: the stream's num_put went through a locale and vsnprintf
// for every number, 3.6% of the humanoid's run through `simulate`.
class RowBuffer {
 public:
  explicit RowBuffer(std::string& s) : s_(s) { s_.clear(); }
  RowBuffer& number(double x) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, x, std::chars_format::general, 12);
    s_.append(buf, r.ptr);
    return *this;
  }
  RowBuffer& comma(double x) {
    s_.push_back(',');
    return number(x);
  }

 private:
  std::string& s_;
};

}  // namespace

CsvWriter::CsvWriter(std::ostream& out, const MechanismModel& model, bool poses, bool reactions)
    : out_(out), model_(model), poses_(poses), reactions_(reactions) {}

void CsvWriter::header() {
  out_ << "time";
  for (const Dof& d : model_.dofs()) out_ << ',' << d.name << ".position," << d.name << ".velocity," << d.name << ".effort";
  out_ << ",constraint.position,constraint.velocity";
  for (const Actuator& a : model_.actuators()) {
    for (const char* c : {"motor_position", "motor_velocity", "motor_torque", "motor_power"}) out_ << ',' << a.name << '.' << c;
    if (electricalGiven(a.ratings))
      for (const char* c : {"motor_current", "motor_voltage", "electrical_power"}) out_ << ',' << a.name << '.' << c;
    if (model_.actuatorLimits()) out_ << ',' << a.name << ".lag," << a.name << ".saturated";
  }
  if (reactions_)
    for (const JointReaction& r : model_.jointReactions())
      for (const char* c : {"fx", "fy", "fz", "tx", "ty", "tz"}) out_ << ',' << r.joint << '.' << c;
  if (reactions_)
    for (const CouplingInfo& c : model_.couplings()) out_ << ',' << c.name << ".reaction";
  if (poses_)
    for (const Link& l : model_.links())
      for (const char* c : {"x", "y", "z", "qw", "qx", "qy", "qz"}) out_ << ',' << l.name << '.' << c;
  out_ << '\n';
}

void CsvWriter::row(const Sample& s) {
  RowBuffer b(line_);
  b.number(s.time);
  for (size_t d = 0; d < s.position.size(); ++d) b.comma(s.position[d]).comma(s.velocity[d]).comma(s.effort[d]);
  b.comma(s.position_violation).comma(s.velocity_violation);
  for (size_t k = 0; k < s.actuators.size(); ++k) {
    const ActuatorState& a = s.actuators[k];
    b.comma(a.position).comma(a.velocity).comma(a.torque).comma(a.power);
    if (electricalGiven(model_.actuators()[k].ratings)) b.comma(a.current).comma(a.voltage).comma(a.electrical_power);
    if (model_.actuatorLimits()) b.comma(a.lag).comma(a.saturated ? 1.0 : 0.0);
  }
  if (reactions_)
    for (const JointReaction& r : s.reactions)
      b.comma(r.force.x()).comma(r.force.y()).comma(r.force.z()).comma(r.torque.x()).comma(r.torque.y()).comma(r.torque.z());
  if (reactions_)
    for (double lambda : s.coupling_reactions) b.comma(lambda);
  if (poses_)
    for (const Eigen::Isometry3d& T : s.link_poses) {
      const Eigen::Quaterniond q(T.linear());
      const Eigen::Vector3d& p = T.translation();
      b.comma(p.x()).comma(p.y()).comma(p.z()).comma(q.w()).comma(q.x()).comma(q.y()).comma(q.z());
    }
  line_.push_back('\n');
  out_.write(line_.data(), static_cast<std::streamsize>(line_.size()));
}

}  // namespace mechanism_sim
