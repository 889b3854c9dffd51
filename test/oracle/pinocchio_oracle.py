"""Pinocchio's answers for the oracle test (test/python/test_pinocchio_oracle.py, doc/testing.md).

Runs in the test-only virtual environment .venv-oracle (PyPI `pin` and `example-robot-data`,
made by scripts/install-deps), whose NumPy 2 must not meet the project's Python module: the
two sides exchange JSON files only.

  pinocchio_oracle.py trees OUT_DIR [N_STATES]
      For every URDF that example-robot-data installs: N_STATES states drawn inside the joint
      limits (seeded by the file's path), Pinocchio's forward dynamics at each, written to
      OUT_DIR/trees.json with the copy of the file both sides load for dynamics (OUT_DIR/models/).
  pinocchio_oracle.py floating REQUEST.json OUT.json
      The same robots on a free base (a `floating` joint to their root link), at the states the
      request gives (mechanism_sim's base pose and velocity).
  pinocchio_oracle.py loop REQUEST.json OUT.json
      Pinocchio's constrained dynamics (constraintDynamics, one point-contact constraint between
      two links) at the state the request gives, and the request's own closure reaction mapped
      into joint space.

Conventions aligned with mechanism_sim (doc/robots.md, doc/model_format.md):
  * the root link is ground (no free-flyer): Pinocchio's default for a URDF, as mechanism_sim's;
    on a free base, Pinocchio's q = (x, y, z, qx, qy, qz, qw) and v in the root's own axes;
  * a continuous joint's angle t is Pinocchio's (cos t, sin t);
  * a <mimic> joint is an exact coupling q_f = multiplier q_l + offset: the tree's dynamics
    reduced onto the leaders, M_r = G^T M G, with G the constant coupling matrix (Pinocchio's own
    mimic joints refuse ABA and some files' mimics);
  * a link of mass 0 has no rotational inertia (mechanism_sim drops it with a note): the copy
    has its <inertia> zeroed;
  * Coulomb friction depends on the step being taken, not on the state alone: the copy has no
    friction; viscous damping stays and enters as tau = -c v;
  * states are drawn inside every joint's limits (no limit acts); a mimic follower whose limits
    admit no position of its leader takes the image of its leader's limits in the copy.
"""
import glob
import hashlib
import json
import math
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

GRAVITY = [0.0, 0.0, -9.81]


def robots_dir():
    """example-robot-data's robots/, as the wheel installs it in this environment."""
    d = os.path.join(sys.prefix, "lib", "python%d.%d" % sys.version_info[:2], "site-packages",
                     "cmeel.prefix", "share", "example-robot-data", "robots")
    if not os.path.isdir(d):
        sys.exit(f"pinocchio_oracle: no example-robot-data under {d} (scripts/install-deps)")
    return d


def dynamics_copy(src, dst):
    """The file as both sides load it for dynamics: no friction, no inertia on mass-0 links,
    mimic followers' limits consistent with their leaders'. Returns what was changed, as counts."""
    tree = ET.parse(src)
    root = tree.getroot()
    changed = {"friction": 0, "massless_inertia": 0}
    for dyn in root.iter("dynamics"):
        if "friction" in dyn.attrib and float(dyn.get("friction")) != 0.0:
            dyn.set("friction", "0")
            changed["friction"] += 1
    for link in root.findall("link"):
        inertial = link.find("inertial")
        if inertial is None or inertial.find("mass") is None or inertial.find("inertia") is None:
            continue
        if float(inertial.find("mass").get("value")) == 0.0:
            inertia = inertial.find("inertia")
            if any(float(inertia.get(k, "0")) != 0.0 for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")):
                for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                    inertia.set(k, "0")
                changed["massless_inertia"] += 1
    # A <mimic> follower whose limits exclude every position of its leader's range (PR2's
    # parallel_root joints: multiplier -1, both in [0, 0.548]) gets its leader's image.
    joints = {j.get("name"): j for j in root.findall("joint")}
    changed["follower_limits"] = 0
    for j in joints.values():
        mimic, lim = j.find("mimic"), j.find("limit")
        leader = joints.get(mimic.get("joint")) if mimic is not None else None
        if lim is None or leader is None or leader.find("limit") is None or j.get("type") == "continuous":
            continue
        a, b = float(mimic.get("multiplier", "1")), float(mimic.get("offset", "0"))
        llim = leader.find("limit")
        lo, hi = sorted((a * float(llim.get("lower", "0")) + b, a * float(llim.get("upper", "0")) + b))
        flo, fhi = float(lim.get("lower", "0")), float(lim.get("upper", "0"))
        if flo < fhi and lo < hi and max(lo, flo) >= min(hi, fhi):
            lim.set("lower", repr(lo))
            lim.set("upper", repr(hi))
            changed["follower_limits"] += 1
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    tree.write(dst)
    return changed


def floating_copy(src, dst):
    """The file with its root link on a `floating` joint from a new link `oracle_world` (a
    free-flyer in Pinocchio; a free base in mechanism_sim). Returns the root link's name."""
    tree = ET.parse(src)
    root = tree.getroot()
    children = {j.find("child").get("link") for j in root.findall("joint")}
    base = next(link.get("name") for link in root.findall("link") if link.get("name") not in children)
    ET.SubElement(root, "link", name="oracle_world")
    joint = ET.SubElement(root, "joint", name="oracle_base", type="floating")
    ET.SubElement(joint, "parent", link="oracle_world")
    ET.SubElement(joint, "child", link=base)
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    tree.write(dst)
    return base


def urdf_joints(path):
    """name -> (type, lower, upper, mimic (leader, multiplier, offset) or None)."""
    joints = {}
    for j in ET.parse(path).getroot().findall("joint"):
        lim = j.find("limit")
        lo = float(lim.get("lower", "0")) if lim is not None else 0.0
        hi = float(lim.get("upper", "0")) if lim is not None else 0.0
        mimic = j.find("mimic")
        m = None
        if mimic is not None:
            m = (mimic.get("joint"), float(mimic.get("multiplier", "1")), float(mimic.get("offset", "0")))
        joints[j.get("name")] = (j.get("type"), lo, hi, m)
    return joints


class Tree:
    """A Pinocchio model of a URDF with its mimic couplings as a reduction; fixed-base, or with
    the free-flyer a `floating` joint makes (floating_copy)."""

    def __init__(self, path):
        self.model = pin.buildModelFromUrdf(path)
        self.model.gravity.linear = np.array(GRAVITY)
        self.data = self.model.createData()
        self.urdf = urdf_joints(path)
        # the free-flyer, if any, apart; every other joint one dof (revolute, prismatic, continuous)
        self.base = [n for n in self.model.names[1:] if self.model.joints[self.model.getJointId(n)].shortname() == "JointModelFreeFlyer"]
        self.names = [n for n in self.model.names[1:] if n not in self.base]
        for n in self.names:
            jm = self.model.joints[self.model.getJointId(n)]
            if jm.nv != 1:
                raise ValueError(f"joint '{n}': {jm.shortname()} has {jm.nv} dofs (only one-dof joints are mapped)")
        # mimic chains resolved to a leader that is itself free: q_f = a q_l + b
        self.coupling = {}
        for n in self.names:
            a, b, leader, seen = 1.0, 0.0, n, set()
            while self.urdf[leader][3] is not None:
                if leader in seen:
                    raise ValueError(f"joint '{n}': mimic cycle")
                seen.add(leader)
                lead, mult, off = self.urdf[leader][3]
                if lead not in self.urdf:
                    raise ValueError(f"joint '{leader}': mimics '{lead}', which is not a joint of the file")
                a, b, leader = a * mult, a * off + b, lead
            if leader not in self.names:
                raise ValueError(f"joint '{n}': mimics '{leader}', which has no dof")
            self.coupling[n] = (leader, a, b)
        self.leaders = [n for n in self.names if self.coupling[n][0] == n]
        self.G = np.zeros((self.model.nv, len(self.leaders) + 6 * len(self.base)))
        for n in self.names:
            leader, a, _ = self.coupling[n]
            self.G[self.model.joints[self.model.getJointId(n)].idx_v, self.leaders.index(leader)] = a
        for k, n in enumerate(self.base):
            i = self.model.joints[self.model.getJointId(n)].idx_v
            self.G[i:i + 6, len(self.leaders) + 6 * k:len(self.leaders) + 6 * k + 6] = np.eye(6)

    def q_of(self, angles):
        """Pinocchio's q from one value per dof name."""
        q = pin.neutral(self.model)
        for n, t in angles.items():
            jm = self.model.joints[self.model.getJointId(n)]
            if jm.nq == 2:
                q[jm.idx_q:jm.idx_q + 2] = (math.cos(t), math.sin(t))
            else:
                q[jm.idx_q] = t
        return q

    def v_of(self, rates):
        v = np.zeros(self.model.nv)
        for n, r in rates.items():
            v[self.model.joints[self.model.getJointId(n)].idx_v] = r
        return v

    def per_dof(self, x):
        return {n: float(x[self.model.joints[self.model.getJointId(n)].idx_v]) for n in self.names}

    def expand(self, leader_values, rates=False):
        """Every dof's value from the leaders' (rates: no offsets)."""
        return {n: self.coupling[n][1] * leader_values[self.coupling[n][0]] + (0.0 if rates else self.coupling[n][2])
                for n in self.names}

    def forward_dynamics(self, q, v):
        """Accelerations of every dof: M_r a_r = G^T (tau - b) with tau = -damping v, a = G a_r."""
        tau = -self.model.damping * v
        if self.G.shape[1] == self.model.nv:
            return pin.aba(self.model, self.data, q, v, tau)
        M = pin.crba(self.model, self.data, q)
        M = np.triu(M) + np.triu(M, 1).T
        b = pin.nonLinearEffects(self.model, self.data, q, v)
        a_r = np.linalg.solve(self.G.T @ M @ self.G, self.G.T @ (tau - b))
        return self.G @ a_r

    def limits(self, n):
        kind, lo, hi, _ = self.urdf[n]
        return (-math.pi, math.pi) if kind == "continuous" or not lo < hi else (lo, hi)

    def draw_state(self, rng):
        """Leaders' positions in the middle 80 % of the range that keeps them and their
        followers inside their limits (continuous and unlimited: (-pi, pi)); rates in (-1, 1)."""
        leaders = {}
        for n in self.leaders:
            lo, hi = self.limits(n)
            for f in self.names:
                leader, a, b = self.coupling[f]
                if leader != n or f == n or self.limits(f) == (-math.pi, math.pi):
                    continue
                flo, fhi = sorted(((self.limits(f)[0] - b) / a, (self.limits(f)[1] - b) / a))
                lo, hi = max(lo, flo), min(hi, fhi)
            if not lo < hi:
                raise ValueError(f"joint '{n}': no position keeps it and its mimic joints inside their limits")
            leaders[n] = lo + (0.1 + 0.8 * rng.random()) * (hi - lo)
        rates = {n: rng.uniform(-1.0, 1.0) for n in self.leaders}
        return leaders, rates


def trees(out_dir, n_states):
    base = robots_dir()
    robots = []
    for path in sorted(glob.glob(os.path.join(base, "**", "*.urdf"), recursive=True)):
        rel = os.path.relpath(path, base)
        copy = os.path.join(out_dir, "models", rel)
        entry = {"file": rel, "path": path, "dynamics_file": copy}
        try:
            entry["changed"] = dynamics_copy(path, copy)
            tree = Tree(copy)
            rng = np.random.default_rng(int(hashlib.sha256(rel.encode()).hexdigest()[:8], 16))
            drawn = [tree.draw_state(rng) for _ in range(n_states)]
        except Exception as e:  # noqa: BLE001 (Pinocchio's or the XML's message, reported)
            entry["pin_error"] = str(e).strip().split("\n")[0]
            robots.append(entry)
            continue
        states = []
        try:
            for leaders, rates in drawn:
                q = tree.q_of(tree.expand(leaders))
                v = tree.v_of(tree.expand(rates, rates=True))
                a = tree.forward_dynamics(q, v)
                if not np.all(np.isfinite(a)):
                    raise np.linalg.LinAlgError("Singular matrix")
                states.append({"positions": leaders, "velocities": rates, "accelerations": tree.per_dof(a)})
        except np.linalg.LinAlgError:
            entry["pin_error"] = "the joint-space inertia is singular (a moving body without mass)"
            robots.append(entry)
            continue
        entry.update(dofs=tree.names, leaders=tree.leaders, states=states)
        entry["floating_file"] = os.path.join(out_dir, "models_floating", rel)
        entry["root_link"] = floating_copy(copy, entry["floating_file"])
        robots.append(entry)
    with open(os.path.join(out_dir, "trees.json"), "w") as f:
        json.dump({"robots_dir": base, "gravity": GRAVITY, "pinocchio": pin.__version__, "robots": robots}, f)


def loop(request_path, out_path):
    """Constrained dynamics of a tree closed by a point constraint (a spherical closure)
    between `child_link` at `child_point` and `parent_link` at `parent_point` (link frames)."""
    req = json.load(open(request_path))
    tree = Tree(req["urdf"])
    model = tree.model
    # the closure's point on each side, as an operational frame of that link's joint
    sides = []
    for side, sign in (("child", 1.0), ("parent", -1.0)):
        fid = model.getFrameId(req[side + "_link"])
        link = model.frames[fid]
        placement = link.placement * pin.SE3(np.eye(3), np.array(req[side + "_point"]))
        point = model.addFrame(pin.Frame(f"closure_{side}", link.parentJoint, fid, placement, pin.FrameType.OP_FRAME))
        sides.append((link.parentJoint, placement, point, sign))
    data = model.createData()
    q = tree.q_of(req["positions"])
    v = tree.v_of(req["velocities"])
    tau = -model.damping * v

    (j1, p1, _, _), (j2, p2, _, _) = sides
    cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, j1, p1, j2, p2, pin.ReferenceFrame.LOCAL)
    cms = pin.StdVec_RigidConstraintModel()
    cms.append(cm)
    cds = pin.StdVec_RigidConstraintData()
    cds.append(cm.createData())
    pin.initConstraintDynamics(model, data, cms, cds)
    # mu = 0: the exact KKT solution; a loop whose equations are dependent (a planar loop's
    # out-of-plane row) needs the proximal iterations (mu > 0), which converge to its
    # accelerations (unique, as J^T lambda is, though lambda is not)
    mu = req.get("mu", 0.0)
    prox = pin.ProximalSettings(1e-15, mu, 1 if mu == 0.0 else 1000)
    ddq = pin.constraintDynamics(model, data, q, v, tau, cms, cds, prox)
    jt_lambda = pin.getConstraintJacobian(model, data, cm, cds[0]).T @ data.lambda_c
    # The constraint forces in joint space: M ddq + b - tau (which is J^T lambda).
    tau_c = pin.rnea(model, data, q, v, ddq) - tau
    # The request's reaction: force and torque (world axes, torque about the closure point)
    # that the closure exerts on its child link, and their opposite on its parent link,
    # mapped into joint space by the point's Jacobian.
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    wrench = np.concatenate([req["reaction_force"], req["reaction_torque"]])
    ours = np.zeros(model.nv)
    for _, _, point, sign in sides:
        ours += sign * pin.getFrameJacobian(model, data, point, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).T @ wrench
    out = {"pinocchio": pin.__version__, "iterations": prox.iter, "accelerations": tree.per_dof(ddq), "constraint_forces": tree.per_dof(tau_c),
           "jt_lambda": tree.per_dof(jt_lambda), "ours_constraint_forces": tree.per_dof(ours)}
    json.dump(out, open(out_path, "w"))


def floating(request_path, out_path):
    """Forward dynamics of free-based robots (floating_copy) at the states requested: the root
    link's pose (4x4) and the velocity of its origin and its angular velocity (world axes), the
    leaders' positions and rates. Pinocchio's free-flyer takes q = (x, y, z, qx, qy, qz, qw) and
    v = (R^T v_O, R^T w), in the root's own axes."""
    answers = {}
    for req in json.load(open(request_path)):
        tree = Tree(req["urdf"])
        (base,) = tree.base
        jm = tree.model.joints[tree.model.getJointId(base)]
        q = tree.q_of(tree.expand(req["positions"]))
        v = tree.v_of(tree.expand(req["velocities"], rates=True))
        pose = np.array(req["root_pose"])
        R = pose[:3, :3]
        q[jm.idx_q:jm.idx_q + 7] = pin.SE3ToXYZQUAT(pin.SE3(R, pose[:3, 3]))
        v[jm.idx_v:jm.idx_v + 6] = np.concatenate([R.T @ np.array(req["root_velocity"][:3]),
                                                   R.T @ np.array(req["root_velocity"][3:])])
        answers[req["urdf"]] = tree.per_dof(tree.forward_dynamics(q, v))
    json.dump(answers, open(out_path, "w"))


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "trees":
        trees(sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 3)
    elif len(sys.argv) == 4 and sys.argv[1] == "loop":
        loop(sys.argv[2], sys.argv[3])
    elif len(sys.argv) == 4 and sys.argv[1] == "floating":
        floating(sys.argv[2], sys.argv[3])
    else:
        sys.exit(__doc__)
