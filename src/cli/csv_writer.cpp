#include "csv_writer.h"

#include <iomanip>

namespace mechanism_sim {

CsvWriter::CsvWriter(std::ostream& out, const MechanismModel& model, bool poses, bool reactions)
    : out_(out), model_(model), poses_(poses), reactions_(reactions) {
  out_ << std::setprecision(12);
}

void CsvWriter::header() {
  out_ << "time";
  for (const Dof& d : model_.dofs()) out_ << ',' << d.name << ".position," << d.name << ".velocity," << d.name << ".effort";
  out_ << ",constraint.position,constraint.velocity";
  if (reactions_)
    for (const JointReaction& r : model_.jointReactions())
      for (const char* c : {"fx", "fy", "fz", "tx", "ty", "tz"}) out_ << ',' << r.joint << '.' << c;
  if (poses_)
    for (const Link& l : model_.links())
      for (const char* c : {"x", "y", "z", "qw", "qx", "qy", "qz"}) out_ << ',' << l.name << '.' << c;
  out_ << '\n';
}

void CsvWriter::row(const Sample& s) {
  out_ << s.time;
  for (size_t d = 0; d < s.position.size(); ++d) out_ << ',' << s.position[d] << ',' << s.velocity[d] << ',' << s.effort[d];
  out_ << ',' << s.position_violation << ',' << s.velocity_violation;
  if (reactions_)
    for (const JointReaction& r : s.reactions)
      out_ << ',' << r.force.x() << ',' << r.force.y() << ',' << r.force.z() << ',' << r.torque.x() << ','
           << r.torque.y() << ',' << r.torque.z();
  if (poses_)
    for (const Eigen::Isometry3d& T : s.link_poses) {
      const Eigen::Quaterniond q(T.linear());
      const Eigen::Vector3d& p = T.translation();
      out_ << ',' << p.x() << ',' << p.y() << ',' << p.z() << ',' << q.w() << ',' << q.x() << ',' << q.y() << ',' << q.z();
    }
  out_ << '\n';
}

}  // namespace mechanism_sim
