#!/usr/bin/env python3
"""Writes the robot zoo (test/zoo/*.urdf): URDF files shaped like the robots users have
(a 7-dof arm, an arm with a gripper, a UR-style arm with a four-bar gripper written with
<mimic> and as a loop, a humanoid, a quadruped, a wheeled base, a five-bar, the five-bar as onshape exports it), with this
project's own numbers. Standard library only. Run: python3 test/zoo/generate_zoo.py
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
NS = 'xmlns:mechanism_sim="https://mechanism-sim.github.io/urdf-extension"'


def f(x):
    s = "%.9f" % x
    s = s.rstrip("0").rstrip(".") if "." in s else s
    return "0" if s in ("-0", "") else s


def v3(v):
    return " ".join(f(x) for x in v)


# ---------------------------------------------------------------- inertia helpers
def rot(rpy):
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]


def rotated(principal, rpy):
    """R diag(principal) R^T: a full inertia tensor (products of inertia non-zero)."""
    R = rot(rpy)
    return [[sum(R[i][k] * principal[k] * R[j][k] for k in range(3)) for j in range(3)] for i in range(3)]


def rod(m, length, radius, axis):
    """Principal moments of a solid cylinder along axis 0/1/2."""
    a = m * radius * radius / 2.0
    t = m * (3 * radius * radius + length * length) / 12.0
    return [a if i == axis else t for i in range(3)]


def box(m, x, y, z):
    return [m * (y * y + z * z) / 12.0, m * (x * x + z * z) / 12.0, m * (x * x + y * y) / 12.0]


def inertial(m, com, principal=(0, 0, 0), rpy=(0, 0, 0)):
    I = rotated(principal, rpy)
    return ('<inertial><origin xyz="%s"/><mass value="%s"/>'
            '<inertia ixx="%s" iyy="%s" izz="%s" ixy="%s" ixz="%s" iyz="%s"/></inertial>'
            % (v3(com), f(m), f(I[0][0]), f(I[1][1]), f(I[2][2]), f(I[0][1]), f(I[0][2]), f(I[1][2])))


class Robot:
    def __init__(self, name, comment, extension=False):
        self.name, self.comment, self.extension = name, comment, extension
        self.items = []

    def link(self, name, inert=None, visual=None):
        body = ""
        if inert:
            body += "\n    " + inert
        if visual:
            body += "\n    " + visual
        self.items.append('  <link name="%s">%s\n  </link>' % (name, body) if body else '  <link name="%s"/>' % name)

    def joint(self, name, type_, parent, child, xyz=(0, 0, 0), rpy=(0, 0, 0), axis=None, limit=None,
              damping=None, mimic=None):
        # (rpy as a string is written as it is: a CAD exporter's round-off)
        s = '  <joint name="%s" type="%s">\n    <parent link="%s"/><child link="%s"/>\n    <origin xyz="%s" rpy="%s"/>' % (
            name, type_, parent, child, v3(xyz), rpy if isinstance(rpy, str) else v3(rpy))
        if axis is not None:
            s += '\n    <axis xyz="%s"/>' % v3(axis)
        if limit is not None:  # (lower, upper, effort, velocity) or (effort, velocity)
            if len(limit) == 4:
                s += '\n    <limit lower="%s" upper="%s" effort="%s" velocity="%s"/>' % tuple(f(x) for x in limit)
            else:
                s += '\n    <limit effort="%s" velocity="%s"/>' % tuple(f(x) for x in limit)
        if damping is not None:
            s += '\n    <dynamics damping="%s" friction="0"/>' % f(damping)
        if mimic is not None:
            s += '\n    <mimic joint="%s" multiplier="%s" offset="%s"/>' % (mimic[0], f(mimic[1]), f(mimic[2]))
        self.items.append(s + "\n  </joint>")

    def raw(self, text):
        self.items.append(text)

    def write(self):
        head = '<?xml version="1.0"?>\n<!-- %s -->\n<!-- Written by test/zoo/generate_zoo.py; edit that, not this. -->\n' % self.comment
        head += '<robot name="%s"%s>\n' % (self.name, (" " + NS) if self.extension else "")
        with open(os.path.join(HERE, self.name + ".urdf"), "w") as out:
            out.write(head + "\n".join(self.items) + "\n</robot>\n")


def cyl_visual(length, radius, xyz=(0, 0, 0), rpy=(0, 0, 0)):
    return '<visual><origin xyz="%s" rpy="%s"/><geometry><cylinder radius="%s" length="%s"/></geometry></visual>' % (
        v3(xyz), v3(rpy), f(radius), f(length))


# ---------------------------------------------------------------- arm7
def arm7():
    r = Robot("arm7", "7-dof arm (iiwa-like): alternating z/y axes, limits, effort limits and damping on every "
              "joint, a massless world link, full inertia tensors")
    r.link("world")
    r.link("base", inertial(4.2, (-0.02, 0, 0.07), box(4.2, 0.2, 0.2, 0.14)), cyl_visual(0.15, 0.1, (0, 0, 0.075)))
    r.joint("world_to_base", "fixed", "world", "base")
    # (name, length to next joint along z, axis, mass, com, principal, rpy of principal axes, limit, effort)
    seg = [
        ("link1", 0.34 - 0.16, (0, 0, 1), 3.9, (0, -0.025, 0.11), rod(3.9, 0.2, 0.07, 2), (0.1, 0, 0), 2.9, 310),
        ("link2", 0.21, (0, 1, 0), 3.7, (0, 0.03, 0.05), rod(3.7, 0.22, 0.07, 2), (-0.15, 0.05, 0), 2.05, 310),
        ("link3", 0.19, (0, 0, 1), 3.1, (0, 0.02, 0.12), rod(3.1, 0.2, 0.065, 2), (0.05, 0.1, 0.2), 2.9, 170),
        ("link4", 0.21, (0, -1, 0), 2.6, (0, -0.03, 0.07), rod(2.6, 0.2, 0.06, 2), (0.2, 0, 0.1), 2.05, 170),
        ("link5", 0.18, (0, 0, 1), 1.8, (0, 0.015, 0.09), rod(1.8, 0.18, 0.055, 2), (0, -0.1, 0.05), 2.9, 105),
        ("link6", 0.07, (0, 1, 0), 1.5, (0, 0.002, 0.01), rod(1.5, 0.09, 0.06, 1), (0.1, 0.1, 0.1), 2.05, 40),
        ("link7", 0.04, (0, 0, 1), 0.35, (0, 0, 0.02), rod(0.35, 0.04, 0.04, 2), (0, 0, 0), 3.0, 40),
    ]
    parent, z = "base", 0.16
    for i, (name, length, axis, m, com, princ, rpy, lim, eff) in enumerate(seg):
        r.link(name, inertial(m, com, princ, rpy), cyl_visual(length, 0.06, (0, 0, length / 2)))
        r.joint("joint%d" % (i + 1), "revolute", parent, name, (0, 0, z), axis=axis,
                limit=(-lim, lim, eff, 1.5 + 0.1 * i), damping=0.5)
        parent, z = name, length
    r.link("flange")  # massless tool frame
    r.joint("flange_joint", "fixed", "link7", "flange", (0, 0, 0.045))
    r.write()


# ---------------------------------------------------------------- arm_gripper
def arm_gripper():
    r = Robot("arm_gripper", "7-dof arm with offset elbows (panda-like) and a two-finger prismatic gripper: "
              "finger_joint2 mimics finger_joint1; massless flange and tool frames")
    r.link("world")
    r.link("link0", inertial(3.1, (-0.04, 0, 0.06), box(3.1, 0.2, 0.15, 0.12)))
    r.joint("world_joint", "fixed", "world", "link0")
    # DH-like modified chain: (xyz, rpy) of each joint in its parent, limits
    chain = [
        ((0, 0, 0.32), (0, 0, 0), (-2.8, 2.8), 2.6, (0, -0.03, -0.07)),
        ((0, 0, 0), (-math.pi / 2, 0, 0), (-1.7, 1.7), 2.4, (0.003, -0.07, 0.03)),
        ((0, -0.31, 0), (math.pi / 2, 0, 0), (-2.8, 2.8), 2.2, (0.04, 0.03, -0.06)),
        ((0.08, 0, 0), (math.pi / 2, 0, 0), (-3.0, -0.08), 2.5, (-0.05, 0.1, 0.03)),
        ((-0.08, 0.37, 0), (-math.pi / 2, 0, 0), (-2.8, 2.8), 2.9, (0, 0.04, -0.1)),
        ((0, 0, 0), (math.pi / 2, 0, 0), (-0.1, 3.7), 1.4, (0.05, -0.01, 0.01)),
        ((0.09, 0, 0), (math.pi / 2, 0, 0), (-2.8, 2.8), 0.5, (0.01, 0.01, 0.08)),
    ]
    parent = "link0"
    for i, (xyz, rpy, lim, m, com) in enumerate(chain):
        name = "link%d" % (i + 1)
        r.link(name, inertial(m, com, box(m, 0.12, 0.12, 0.2), (0.1 * i, -0.05 * i, 0.07)))
        r.joint("arm_joint%d" % (i + 1), "revolute", parent, name, xyz, rpy, axis=(0, 0, 1),
                limit=(lim[0], lim[1], 80 if i < 4 else 12, 2.2), damping=0.3)
        parent = name
    r.link("flange")  # massless: no <inertial>
    r.joint("flange_joint", "fixed", "link7", "flange", (0, 0, 0.105))
    r.link("hand", inertial(0.7, (0, 0, 0.03), box(0.7, 0.05, 0.2, 0.06)))
    r.joint("hand_joint", "fixed", "flange", "hand", rpy=(0, 0, -math.pi / 4))
    for k, sign in ((1, 1), (2, -1)):
        name = "finger%d" % k
        r.link(name, inertial(0.03, (0, sign * 0.008, 0.025), box(0.03, 0.02, 0.015, 0.05)))
        r.joint("finger_joint%d" % k, "prismatic", "hand", name, (0, 0, 0.058), axis=(0, sign, 0),
                limit=(0, 0.04, 20, 0.2), damping=0.5, mimic=("finger_joint1", 1, 0) if k == 2 else None)
    r.link("tool_frame")  # massless
    r.joint("tool_joint", "fixed", "hand", "tool_frame", (0, 0, 0.1))
    r.write()


# ---------------------------------------------------------------- UR-style arm with a four-bar gripper
UR = [  # (joint, parent, child, xyz, rpy, axis, mass, com, principal)
    ("shoulder_pan", "base", "shoulder", (0, 0, 0.16), (0, 0, 0), (0, 0, 1), 3.6, (0, 0, 0), box(3.6, 0.12, 0.12, 0.15)),
    ("shoulder_lift", "shoulder", "upper_arm", (0, 0.13, 0), (0, math.pi / 2, 0), (0, 1, 0), 8.2,
     (0, 0, 0.21), rod(8.2, 0.43, 0.055, 2)),
    ("elbow", "upper_arm", "forearm", (0, -0.12, 0.43), (0, 0, 0), (0, 1, 0), 2.4, (0, 0, 0.19), rod(2.4, 0.39, 0.045, 2)),
    ("wrist_1", "forearm", "wrist_1_link", (0, 0, 0.39), (0, math.pi / 2, 0), (0, 1, 0), 1.2, (0, 0.1, 0), box(1.2, 0.07, 0.07, 0.08)),
    ("wrist_2", "wrist_1_link", "wrist_2_link", (0, 0.1, 0), (0, 0, 0), (0, 0, 1), 1.2, (0, 0, 0.09), box(1.2, 0.07, 0.07, 0.08)),
    ("wrist_3", "wrist_2_link", "wrist_3_link", (0, 0, 0.09), (0, 0, 0), (0, 1, 0), 0.2, (0, 0.06, 0), box(0.2, 0.06, 0.03, 0.06)),
]
CRANK = 0.05      # driver and follower crank length [m]
PIVOTS = 0.03     # distance between the two pivots on the palm, along the approach (z)


def ur_fourbar(loop):
    name = "ur_fourbar_loop" if loop else "ur_fourbar_mimic"
    how = ("closed by a mechanism_sim:joint loop per finger" if loop else
           "written with <mimic> (follower = driver, coupler = -driver)")
    r = Robot(name, "UR-style 6-dof arm with a two-finger parallelogram four-bar gripper, " + how, extension=loop)
    r.link("world")
    r.link("base", inertial(4.0, (0, 0, 0.05), box(4.0, 0.15, 0.15, 0.1)))
    r.joint("world_joint", "fixed", "world", "base")
    for (jn, p, c, xyz, rpy, axis, m, com, pr) in UR:
        r.link(c, inertial(m, com, pr))
        r.joint(jn, "revolute", p, c, xyz, rpy, axis, limit=(-6.2, 6.2, 150 if m > 2 else 28, 3.1), damping=0.2)
    r.link("tool0")
    r.joint("tool0_joint", "fixed", "wrist_3_link", "tool0", (0, 0.08, 0), (-math.pi / 2, 0, 0))
    r.link("palm", inertial(0.45, (0, 0, 0.03), box(0.45, 0.1, 0.05, 0.06)))
    r.joint("palm_joint", "fixed", "tool0", "palm")
    # Each finger: driver and follower cranks on the palm (axis x, pivots PIVOTS apart along z),
    # pointing along +-y at zero; the finger (coupler) is pinned to the driver's tip and, in the
    # loop version, to the follower's tip: a parallelogram, so follower = driver and the finger
    # turns by -driver relative to the driver (it translates).
    for side, s in (("left", 1), ("right", -1)):
        drv, fol, fin = side + "_driver", side + "_follower", side + "_finger"
        r.link(drv, inertial(0.04, (0, s * CRANK / 2, 0), rod(0.04, CRANK, 0.006, 1)))
        r.link(fol, inertial(0.03, (0, s * CRANK / 2, 0), rod(0.03, CRANK, 0.005, 1)))
        r.link(fin, inertial(0.06, (0, s * 0.005, 0.03), box(0.06, 0.01, 0.02, 0.07)))
        r.joint(drv + "_joint", "revolute", "palm", drv, (0, s * 0.02, 0.07), axis=(s, 0, 0),
                limit=(-0.5, 0.9, 10, 2.0), damping=0.02)
        r.joint(fol + "_joint", "revolute", "palm", fol, (0, s * 0.02, 0.07 + PIVOTS), axis=(s, 0, 0),
                limit=(-0.5, 0.9, 10, 2.0), mimic=None if loop else (drv + "_joint", 1, 0))
        r.joint(fin + "_joint", "revolute", drv, fin, (0, s * CRANK, 0), axis=(s, 0, 0),
                limit=(-0.9, 0.5, 10, 2.0), mimic=None if loop else (drv + "_joint", -1, 0))
        if loop:
            r.raw('  <mechanism_sim:joint name="%s_loop" type="revolute">\n'
                  '    <parent link="%s"/><child link="%s"/>\n'
                  '    <origin xyz="0 0 %s"/><child_origin xyz="0 %s 0"/>\n'
                  '    <axis xyz="%d 0 0"/>\n  </mechanism_sim:joint>' % (side, fin, fol, f(PIVOTS), f(s * CRANK), s))
    r.write()


# ---------------------------------------------------------------- humanoid
def humanoid():
    r = Robot("humanoid", "humanoid on a fixed torso (nao-sized): 26 joints with limits, the right hip mimics the "
              "left, mimic fingers, sensor frames as massless links (no <inertial>, or mass 0); the elbows' "
              "limits exclude 0, so the all-zero pose lies outside them")
    r.link("base_link")
    r.link("torso", inertial(1.1, (-0.004, 0, 0.04), box(1.1, 0.09, 0.14, 0.17)))
    r.joint("torso_joint", "fixed", "base_link", "torso")

    def frames(parent, names):
        for i, (n, xyz) in enumerate(names):
            if i % 3 == 2:  # every third frame says mass 0 (inertia 0) instead of leaving <inertial> out
                r.link(n, inertial(0, (0, 0, 0)))
            else:
                r.link(n)
            r.joint(n + "_fixedjoint", "fixed", parent, n, xyz)

    frames("torso", [("accelerometer", (-0.01, 0, -0.04)), ("gyrometer", (-0.01, 0.005, -0.04)),
                     ("chest_button", (0.05, 0, 0.06)), ("imu", (0, 0, 0))])
    # head
    r.link("neck", inertial(0.07, (0, 0, -0.02), box(0.07, 0.03, 0.03, 0.05)))
    r.joint("HeadYaw", "revolute", "torso", "neck", (0, 0, 0.125), axis=(0, 0, 1), limit=(-2.0, 2.0, 1.5, 8), damping=0.02)
    r.link("head", inertial(0.6, (0.002, 0, -0.005), box(0.6, 0.12, 0.13, 0.12), (0.05, 0, 0)))
    r.joint("HeadPitch", "revolute", "neck", "head", axis=(0, 1, 0), limit=(-0.6, 0.5, 1.5, 7), damping=0.02)
    frames("head", [("gaze", (0.05, 0, 0.06)), ("camera_top", (0.058, 0, 0.063)), ("camera_top_optical", (0.058, 0, 0.063)),
                    ("camera_bottom", (0.05, 0, 0.01)), ("camera_bottom_optical", (0.05, 0, 0.01)),
                    ("head_touch_front", (0.02, 0, 0.1)), ("head_touch_middle", (0, 0, 0.105)),
                    ("head_touch_rear", (-0.03, 0, 0.1)), ("sonar_left", (0.05, 0.04, -0.03)),
                    ("sonar_right", (0.05, -0.04, -0.03)), ("infrared_left", (0.06, 0.02, 0.05)),
                    ("infrared_right", (0.06, -0.02, 0.05))])
    # legs
    for side, s in (("L", 1), ("R", -1)):
        lower = side + "_"
        r.link(lower + "pelvis", inertial(0.07, (-0.008, s * 0.002, 0.02), box(0.07, 0.04, 0.04, 0.04)))
        r.joint(side + "HipYawPitch", "revolute", "torso", lower + "pelvis", (0, s * 0.05, -0.085),
                axis=(0, s / math.sqrt(2), -1 / math.sqrt(2)), limit=(-1.1, 0.7, 3, 4), damping=0.05,
                mimic=("LHipYawPitch", 1, 0) if side == "R" else None)
        r.link(lower + "hip", inertial(0.14, (-0.016, s * 0.0, -0.003), box(0.14, 0.05, 0.04, 0.05)))
        r.joint(side + "HipRoll", "revolute", lower + "pelvis", lower + "hip", axis=(1, 0, 0),
                limit=(-0.4 if s > 0 else -0.8, 0.8 if s > 0 else 0.4, 3, 4), damping=0.05)
        r.link(lower + "thigh", inertial(0.39, (0.001, -s * 0.002, -0.054), rod(0.39, 0.1, 0.04, 2), (0.03, 0, 0)))
        r.joint(side + "HipPitch", "revolute", lower + "hip", lower + "thigh", axis=(0, 1, 0),
                limit=(-1.5, 0.5, 3, 6), damping=0.05)
        r.link(lower + "tibia", inertial(0.29, (0.005, -s * 0.002, -0.05), rod(0.29, 0.1, 0.035, 2)))
        r.joint(side + "KneePitch", "revolute", lower + "thigh", lower + "tibia", (0, 0, -0.1), axis=(0, 1, 0),
                limit=(-0.09, 2.1, 3, 6), damping=0.05)
        r.link(lower + "ankle", inertial(0.13, (0.001, 0, 0.007), box(0.13, 0.04, 0.04, 0.04)))
        r.joint(side + "AnklePitch", "revolute", lower + "tibia", lower + "ankle", (0, 0, -0.103), axis=(0, 1, 0),
                limit=(-1.2, 0.9, 3, 6), damping=0.05)
        r.link(lower + "foot", inertial(0.17, (0.025, s * 0.003, -0.032), box(0.17, 0.16, 0.09, 0.02)))
        r.joint(side + "AnkleRoll", "revolute", lower + "ankle", lower + "foot", axis=(1, 0, 0),
                limit=(-0.39 if s > 0 else -0.77, 0.77 if s > 0 else 0.39, 3, 4), damping=0.05)
        frames(lower + "foot", [(lower + "sole", (0, 0, -0.046)),
                                (lower + "fsr_front_left", (0.07, 0.02, -0.046)),
                                (lower + "fsr_front_right", (0.07, -0.02, -0.046)),
                                (lower + "fsr_rear_left", (-0.03, 0.02, -0.046)),
                                (lower + "fsr_rear_right", (-0.03, -0.02, -0.046)),
                                (lower + "bumper_left", (0.07, 0.025, -0.03)),
                                (lower + "bumper_right", (0.07, -0.025, -0.03))])
    # arms
    for side, s in (("L", 1), ("R", -1)):
        p = side + "_"
        r.link(p + "shoulder", inertial(0.07, (-0.002, -s * 0.02, 0), box(0.07, 0.03, 0.04, 0.03)))
        r.joint(side + "ShoulderPitch", "revolute", "torso", p + "shoulder", (0, s * 0.098, 0.1), axis=(0, 1, 0),
                limit=(-2.0, 2.0, 1.3, 8), damping=0.03)
        r.link(p + "biceps", inertial(0.16, (0.002, s * 0.002, -0.03), rod(0.16, 0.09, 0.03, 2), (0, 0.1, 0)))
        r.joint(side + "ShoulderRoll", "revolute", p + "shoulder", p + "biceps", axis=(1, 0, 0),
                limit=(-0.3, 1.3, 1.3, 7) if s > 0 else (-1.3, 0.3, 1.3, 7), damping=0.03)
        r.link(p + "elbow", inertial(0.06, (0, 0, -0.02), box(0.06, 0.03, 0.03, 0.04)))
        r.joint(side + "ElbowYaw", "revolute", p + "biceps", p + "elbow", (0, 0, -0.105), axis=(0, 0, 1),
                limit=(-2.0, 2.0, 1.5, 8), damping=0.03)
        r.link(p + "forearm", inertial(0.08, (0, 0, -0.025), rod(0.08, 0.05, 0.025, 2)))
        # elbow bends about y; its range excludes 0 (straight arm): the zero pose is outside it
        r.joint(side + "ElbowRoll", "revolute", p + "elbow", p + "forearm", axis=(0, 1, 0),
                limit=(-1.5, -0.04, 1.5, 7), damping=0.03)
        r.link(p + "wrist", inertial(0.18, (0, 0, -0.04), rod(0.18, 0.06, 0.025, 2)))
        r.joint(side + "WristYaw", "revolute", p + "forearm", p + "wrist", (0, 0, -0.056), axis=(0, 0, 1),
                limit=(-1.8, 1.8, 0.4, 20), damping=0.01)
        r.link(p + "gripper", inertial(0.03, (0, 0, -0.02), box(0.03, 0.03, 0.03, 0.03)))
        r.joint(side + "Hand", "revolute", p + "wrist", p + "gripper", (0, 0, -0.06), axis=(0, 1, 0),
                limit=(0, 1, 0.3, 8), damping=0.01)
        # three fingers of two phalanges; every finger joint mimics the hand joint
        for k, y in ((1, 0.012), (2, -0.012), (3, 0.0)):
            for ph in (1, 2):
                n = "%sFinger%d%d" % (side, k, ph)
                r.link(n, inertial(0.004, (0, 0, -0.008), box(0.004, 0.008, 0.008, 0.016)))
                par = p + "gripper" if ph == 1 else "%sFinger%d1" % (side, k)
                xyz = (0.008 if k < 3 else -0.008, y, -0.03) if ph == 1 else (0, 0, -0.016)
                r.joint(n, "continuous", par, n, xyz, axis=(0, 1 if k < 3 else -1, 0), damping=0.001,
                        mimic=(side + "Hand", 0.9 if ph == 1 else 0.6, 0))
        frames(p + "gripper", [(p + "hand_touch_left", (0, 0.02, -0.02)), (p + "hand_touch_back", (-0.02, 0, -0.02)),
                               (p + "hand_touch_right", (0, -0.02, -0.02))])
    r.write()


# ---------------------------------------------------------------- quadruped
def quadruped():
    r = Robot("quadruped", "quadruped on a floating base: hip and thigh links with inertia, calves and toes "
              "point masses (inertia 0)")
    # MuJoCo (test_mujoco_oracle) refuses point masses on moving joints and fusing one into another:
    # it reads this element (urdfdom and mechanism_sim ignore it) and gives them 1e-12 kg m^2.
    r.raw('  <mujoco><compiler boundinertia="1e-12" fusestatic="false"/></mujoco>')
    r.link("world")
    r.link("trunk", inertial(11.0, (0.005, 0, 0.002), box(11.0, 0.55, 0.2, 0.12), (0, 0.02, 0)))
    r.joint("floating_base", "floating", "world", "trunk", (0, 0, 0.5))
    for leg, (x, y) in (("FR", (0.21, -0.05)), ("FL", (0.21, 0.05)), ("RR", (-0.21, -0.05)), ("RL", (-0.21, 0.05))):
        s = 1 if y > 0 else -1
        r.link(leg + "_hip", inertial(1.0, (-0.003, s * 0.01, 0), box(1.0, 0.08, 0.08, 0.06)))
        r.joint(leg + "_hip_joint", "revolute", "trunk", leg + "_hip", (x, y, 0), axis=(1, 0, 0),
                limit=(-0.8, 0.8, 20, 20), damping=0.1)
        r.link(leg + "_thigh", inertial(1.3, (-0.002, -s * 0.01, -0.03), rod(1.3, 0.25, 0.03, 2), (0.05, 0, 0)))
        r.joint(leg + "_thigh_joint", "revolute", leg + "_hip", leg + "_thigh", (0, s * 0.07, 0), axis=(0, 1, 0),
                limit=(-1.0, 2.5, 55, 20), damping=0.1)
        r.link(leg + "_calf", inertial(0.2, (0, 0, -0.16)))  # point mass
        r.joint(leg + "_calf_joint", "revolute", leg + "_thigh", leg + "_calf", (0, 0, -0.25), axis=(0, 1, 0),
                limit=(-2.6, -0.7, 55, 20), damping=0.1)
        r.link(leg + "_toe", inertial(0.06, (0, 0, 0)))  # point mass at the foot
        r.joint(leg + "_toe_joint", "fixed", leg + "_calf", leg + "_toe", (0, 0, -0.25))
    r.write()


# ---------------------------------------------------------------- wheeled base
def wheeled_base():
    r = Robot("wheeled_base", "wheeled base on a planar joint (gravity carried by it): two drive wheels, two "
              "swivelling casters (continuous), a pan-tilt head whose camera hangs forward of the tilt axis")
    r.link("world")
    r.link("chassis", inertial(18.0, (-0.02, 0, 0.12), box(18.0, 0.5, 0.4, 0.2), (0, 0, 0.05)))
    r.joint("base_planar", "planar", "world", "chassis", (0, 0, 0.1), axis=(0, 0, 1))
    for side, y in (("left", 0.22), ("right", -0.22)):
        r.link(side + "_wheel", inertial(1.2, (0, 0, 0), rod(1.2, 0.04, 0.1, 1)))
        r.joint(side + "_wheel_joint", "continuous", "chassis", side + "_wheel", (0, y, 0), axis=(0, 1, 0), damping=0.01)
    for name, x in (("front", 0.2), ("rear", -0.2)):
        r.link(name + "_caster", inertial(0.2, (-0.02, 0, -0.03), box(0.2, 0.04, 0.03, 0.05)))
        r.joint(name + "_caster_swivel", "continuous", "chassis", name + "_caster", (x, 0, -0.02), axis=(0, 0, 1),
                damping=0.005)
        r.link(name + "_caster_wheel", inertial(0.1, (0, 0, 0), rod(0.1, 0.02, 0.04, 1)))
        r.joint(name + "_caster_wheel_joint", "continuous", name + "_caster", name + "_caster_wheel",
                (-0.03, 0, -0.04), axis=(0, 1, 0), damping=0.001)
    r.link("mast", inertial(2.0, (0, 0, 0.3), rod(2.0, 0.6, 0.03, 2)))
    r.joint("mast_joint", "fixed", "chassis", "mast", (-0.1, 0, 0.2))
    r.link("pan_link", inertial(0.3, (0, 0, 0.02), box(0.3, 0.06, 0.06, 0.04)))
    r.joint("head_pan", "revolute", "mast", "pan_link", (0, 0, 0.6), axis=(0, 0, 1), limit=(-2.5, 2.5, 5, 3), damping=0.05)
    r.link("camera", inertial(0.5, (0.05, 0, -0.03), box(0.5, 0.05, 0.15, 0.04)))
    r.joint("head_tilt", "revolute", "pan_link", "camera", (0, 0, 0.05), axis=(0, 1, 0), limit=(-0.9, 1.4, 5, 3),
            damping=0.05)
    r.link("camera_optical")
    r.joint("camera_optical_joint", "fixed", "camera", "camera_optical", (0.07, 0, 0), (-math.pi / 2, 0, -math.pi / 2))
    r.write()


# ---------------------------------------------------------------- five-bar
def five_bar(ball=False):
    a, l1, l2 = 0.08, 0.16, 0.22   # half the base, proximal and distal lengths
    if ball:
        r = Robot("five_bar_ball", "the planar five-bar in a vertical plane (axes horizontal), as onshape-to-robot "
                  "exports it: joint origins with a CAD exporter's round-off, the loop closed by a ball (a spherical "
                  "mechanism_sim:joint) whose out-of-plane row is round-off", extension=True)
    else:
        r = Robot("five_bar", "planar five-bar parallel robot in a horizontal plane (axes vertical), two motors on "
                  "the base; the distal links meet at the end effector, closed by a mechanism_sim:joint", extension=True)
    # (onshape's planar 2-dof, ../shared/robots: pi/2 as the exporter writes it, and the
    # elbows' residue of its matrix-to-rpy conversion)
    motor_rpy = "1.57079632679489678 -0 0" if ball else (0, 0, 0)
    elbow_rpy = {"left": "0 -4.8148248609680896326e-34 -1.3877787807814456755e-17",
                 "right": "-4.1402727141222208915e-16 -5.0706060260327139801e-17 2.7755575615628106161e-17"}
    r.link("base")
    # zero pose: proximal links at 70 deg from the base line, distal links meeting above the middle
    th = math.radians(70)
    elbow = (a + l1 * math.cos(th), l1 * math.sin(th))     # right elbow, in the plane (x, y)
    ee_y = elbow[1] + math.sqrt(l2 * l2 - elbow[0] ** 2)
    for side, s in (("left", -1), ("right", 1)):
        ex, ey = s * elbow[0], elbow[1]
        px, py = ex - s * a, ey                                # proximal vector
        dx, dy = 0 - ex, ee_y - ey                             # distal vector
        ang_p, ang_d = math.atan2(py, px), math.atan2(dy, dx)
        mp, md = 0.25, 0.18
        r.link(side + "_proximal", inertial(mp, (px / 2, py / 2, 0), rod(mp, l1, 0.01, 0), (0, 0, ang_p)))
        r.joint(side + "_motor", "revolute", "base", side + "_proximal", (s * a, 0, 0), motor_rpy, axis=(0, 0, 1),
                limit=(-1.2, 1.2, 8, 6), damping=0.05)
        r.link(side + "_distal", inertial(md, (dx / 2, dy / 2, 0.01), rod(md, l2, 0.008, 0), (0, 0, ang_d)))
        r.joint(side + "_elbow", "continuous", side + "_proximal", side + "_distal", (px, py, 0.01),
                elbow_rpy[side] if ball else (0, 0, 0), axis=(0, 0, 1), damping=0.01)
        if side == "left":
            r.link("end_effector", inertial(0.1, (0, 0, 0.01), box(0.1, 0.03, 0.03, 0.03)))
            r.joint("end_effector_joint", "fixed", "left_distal", "end_effector", (dx, dy, 0))
            r.link("tool_frame")
            r.joint("tool_joint", "fixed", "end_effector", "tool_frame", (0, 0, 0.03))
    r.raw(_five_bar_loop(a, l1, l2, th, ee_y, ball))
    r.write()


def _five_bar_loop(a, l1, l2, th, ee_y, ball=False):
    ex, ey = a + l1 * math.cos(th), l1 * math.sin(th)
    if ball:
        return ('  <mechanism_sim:joint name="end_effector_ball" type="spherical">\n'
                '    <parent link="end_effector"/><child link="right_distal"/>\n'
                '    <origin xyz="0 0 0"/><child_origin xyz="%s"/>\n  </mechanism_sim:joint>' % v3((0 - ex, ee_y - ey, 0)))
    return ('  <mechanism_sim:joint name="end_effector_loop" type="revolute">\n'
            '    <parent link="end_effector"/><child link="right_distal"/>\n'
            '    <origin xyz="0 0 0"/><child_origin xyz="%s"/>\n    <axis xyz="0 0 1"/>\n'
            '    <dynamics damping="0.01"/>\n  </mechanism_sim:joint>' % v3((0 - ex, ee_y - ey, 0)))


if __name__ == "__main__":
    arm7()
    arm_gripper()
    ur_fourbar(loop=False)
    ur_fourbar(loop=True)
    humanoid()
    quadruped()
    wheeled_base()
    five_bar()
    five_bar(ball=True)
