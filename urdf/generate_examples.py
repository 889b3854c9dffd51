#!/usr/bin/env python3
"""Writes the example mechanisms in this folder. Each closes at the URDF's zero
configuration: link frames stay parallel to the world frame there and joint origins
are pure translations, so the numbers below are positions in metres."""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
NS = 'xmlns:mechanism_sim="https://mechanism-sim.github.io/urdf-extension"'


def f(x):
    return "%.9f" % x


def v(p):
    return " ".join(f(c) for c in p)


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def add(a, b):
    return [a[i] + b[i] for i in range(3)]


def scale(a, s):
    return [c * s for c in a]


def norm(a):
    return math.sqrt(sum(c * c for c in a))


def rod_rpy(u):
    """rpy turning a cylinder's z axis onto direction u."""
    u = scale(u, 1.0 / norm(u))
    pitch = math.atan2(math.hypot(u[0], u[1]), u[2])
    yaw = math.atan2(u[1], u[0])
    return [0.0, pitch, yaw]


def inertia(m, L, r=0.01):
    i = m * (L * L / 12.0 + r * r / 4.0)
    return '<inertia ixx="%s" iyy="%s" izz="%s" ixy="0" ixz="0" iyz="0"/>' % (f(i), f(i), f(i))


def rod_link(name, a, b, m=0.5, color="0.2 0.5 0.8 1", radius=0.008):
    """A link whose frame sits at a (world-aligned) and whose rod runs to b."""
    d = sub(b, a)
    mid = scale(d, 0.5)
    L = norm(d)
    return f'''  <link name="{name}">
    <inertial><origin xyz="{v(mid)}"/><mass value="{f(m)}"/>{inertia(m, L)}</inertial>
    <visual><origin xyz="{v(mid)}" rpy="{v(rod_rpy(d))}"/><geometry><cylinder radius="{radius}" length="{f(L)}"/></geometry>
      <material name="{name}_color"><color rgba="{color}"/></material></visual>
  </link>
'''


def box_link(name, size, m=1.0, color="0.8 0.3 0.2 1", offset=(0, 0, 0)):
    i = m * (size[0] ** 2 + size[1] ** 2 + size[2] ** 2) / 18.0
    return f'''  <link name="{name}">
    <inertial><origin xyz="{v(offset)}"/><mass value="{f(m)}"/><inertia ixx="{f(i)}" iyy="{f(i)}" izz="{f(i)}" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><origin xyz="{v(offset)}"/><geometry><box size="{v(size)}"/></geometry>
      <material name="{name}_color"><color rgba="{color}"/></material></visual>
  </link>
'''


def base_link(name="base"):
    return f'''  <link name="{name}">
    <visual><geometry><box size="0.04 0.04 0.01"/></geometry><material name="base_color"><color rgba="0.4 0.4 0.4 1"/></material></visual>
  </link>
'''


def joint(name, jtype, parent, child, xyz, axis=None, limit=None, extra=""):
    s = f'  <joint name="{name}" type="{jtype}">\n    <parent link="{parent}"/><child link="{child}"/>\n    <origin xyz="{v(xyz)}"/>\n'
    if axis:
        s += f'    <axis xyz="{v(axis)}"/>\n'
    if limit:
        s += f'    <limit lower="{f(limit[0])}" upper="{f(limit[1])}" effort="{f(limit[2])}" velocity="{f(limit[3])}"/>\n'
    return s + extra + "  </joint>\n"


def circle_intersection(B, rB, D, rD, up=True):
    """Intersection of circles in the x-z plane (y = 0)."""
    dx, dz = D[0] - B[0], D[2] - B[2]
    d = math.hypot(dx, dz)
    a = (rB * rB - rD * rD + d * d) / (2 * d)
    h = math.sqrt(rB * rB - a * a)
    px, pz = B[0] + a * dx / d, B[2] + a * dz / d
    s = 1 if up else -1
    return [px - s * h * dz / d, 0.0, pz + s * h * dx / d]


def write(name, body, comment):
    with open(os.path.join(HERE, name), "w") as out:
        out.write(f'<?xml version="1.0"?>\n<!-- {comment} -->\n<!-- Written by generate_examples.py. -->\n')
        out.write(f'<robot name="{name[:-5]}" {NS}>\n{body}</robot>\n')


Y = [0, 1, 0]

# ---- planar four-bar: crank AB, coupler BC, rocker DC, ground AD; closed by 'loop' at D.
A, D = [0, 0, 0], [0.4, 0, 0]
B = [0.1 * math.cos(math.radians(60)), 0, 0.1 * math.sin(math.radians(60))]
C = circle_intersection(B, 0.35, D, 0.3)


def four_bar(loop):
    s = base_link()
    s += rod_link("crank", A, B, 0.3)
    s += rod_link("coupler", [0, 0, 0], sub(C, B), 0.6, "0.2 0.8 0.3 1")
    s += rod_link("rocker", [0, 0, 0], sub(D, C), 0.5, "0.8 0.6 0.2 1")
    s += joint("crank_joint", "continuous", "base", "crank", A, Y)
    s += joint("coupler_joint", "continuous", "crank", "coupler", B, Y)
    s += joint("rocker_joint", "continuous", "coupler", "rocker", sub(C, B), Y)
    s += loop
    s += '  <mechanism_sim:initial joint="crank_joint" velocity="4.0"/>\n'
    return s


write("four_bar.urdf", four_bar(f'''  <mechanism_sim:joint name="loop" type="revolute">
    <parent link="base"/><child link="rocker"/>
    <origin xyz="{v(D)}"/><child_origin xyz="{v(sub(D, C))}"/>
    <axis xyz="0 1 0"/>
  </mechanism_sim:joint>
'''), "Planar four-bar (crank-rocker) of four revolute joints; the loop closes with a mechanism_sim:joint.")
write("four_bar_driven.urdf", four_bar(f'''  <mechanism_sim:joint name="loop" type="revolute">
    <parent link="base"/><child link="rocker"/>
    <origin xyz="{v(D)}"/><child_origin xyz="{v(sub(D, C))}"/>
    <axis xyz="0 1 0"/>
  </mechanism_sim:joint>
''').replace('  <mechanism_sim:initial joint="crank_joint" velocity="4.0"/>\n',
             '  <mechanism_sim:drive joint="crank_joint" velocity="3.0"/>\n'),
      "The four-bar with its crank driven at 3 rad/s: its bearing loads (joint reactions) are shown in rviz.")
write("four_bar_gazebo.urdf", four_bar(f'''  <gazebo>
    <joint name="loop" type="revolute">
      <pose>{v(sub(D, C))} 0 0 0</pose>
      <parent>base</parent><child>rocker</child>
      <axis><xyz>0 1 0</xyz></axis>
    </joint>
  </gazebo>
'''), "The same four-bar with its loop closed by a Gazebo (SDF) joint, as Gazebo-ready URDFs do.")

# ---- slider-crank: crank r about -y (so its angle lifts x towards z), rod l, offset e.
r, l, e = 0.1, 0.35, 0.02
Xs = r + math.sqrt(l * l - e * e)  # slider pin x at theta = 0
s = base_link()
s += rod_link("crank", [0, 0, 0], [r, 0, 0], 0.4)
s += rod_link("rod", [0, 0, 0], [Xs - r, 0, e], 0.5, "0.2 0.8 0.3 1")
s += box_link("slider", [0.06, 0.04, 0.03], 0.8)
s += '''  <link name="flywheel">
    <inertial><mass value="3.0"/><inertia ixx="0.0075" iyy="0.015" izz="0.0075" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="0.1" length="0.01"/></geometry><material name="steel"><color rgba="0.7 0.7 0.75 1"/></material></visual>
  </link>
'''
s += joint("crank_joint", "continuous", "base", "crank", [0, 0, 0], [0, -1, 0])
s += joint("flywheel_mount", "fixed", "crank", "flywheel", [0, -0.02, 0])
s += joint("rod_joint", "continuous", "crank", "rod", [r, 0, 0], [0, -1, 0])
s += joint("slider_joint", "prismatic", "base", "slider", [Xs, 0, e], [1, 0, 0], (-0.5, 0.5, 100, 10))
s += f'''  <mechanism_sim:joint name="wrist_pin" type="revolute">
    <parent link="slider"/><child link="rod"/>
    <origin/><child_origin xyz="{v([Xs - r, 0, e])}"/>
    <axis xyz="0 -1 0"/>
  </mechanism_sim:joint>
'''
write("slider_crank.urdf", s + '  <mechanism_sim:initial joint="crank_joint" velocity="14.0"/>\n',
      f"Offset slider-crank with a flywheel: crank {r} m, rod {l} m, offset {e} m; the slider pin closes the loop.")
write("slider_crank_driven.urdf", s + f'  <mechanism_sim:drive joint="crank_joint" velocity="{2 * math.pi!r}"/>\n',
      "The slider-crank with its crank driven at 60 rpm (a drive: prescribed motion); the drive's effort is the torque the motor must give.")

# ---- screw jack: the screw turns in the base's nut and lifts a platform kept from turning by a guide.
lead = 0.005
s = base_link()
s += f'''  <link name="screw">
    <inertial><origin xyz="0 0 0.1"/><mass value="0.8"/><inertia ixx="0.003" iyy="0.003" izz="0.0004" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.012" length="0.2"/></geometry><material name="steel"><color rgba="0.7 0.7 0.75 1"/></material></visual>
  </link>
'''
s += box_link("platform", [0.12, 0.12, 0.01], 5.0, "0.8 0.3 0.2 1")
s += joint("screw_joint", "continuous", "base", "screw", [0, 0, 0.05], [0, 0, 1])
s += joint("platform_bearing", "continuous", "screw", "platform", [0, 0, 0.2], [0, 0, 1])
s += f'''  <!-- URDF says continuous (for viewers); the simulator turns it into a screw. -->
  <mechanism_sim:joint name="screw_joint" type="screw" lead="{lead}"/>
  <mechanism_sim:joint name="guide" type="prismatic">
    <parent link="base"/><child link="platform"/>
    <origin xyz="0 0 0.25"/>
    <axis xyz="0 0 1"/>
  </mechanism_sim:joint>
  <mechanism_sim:initial joint="screw_joint" velocity="40.0"/>
'''
write("screw_jack.urdf", s, f"Screw jack: a screw of lead {lead} m/rev lifts a 5 kg platform held from turning by a prismatic guide.")

# ---- cylindrical joint: a sleeve turns and slides on a horizontal rod, a bob hangs from it,
# a spring pulls the sleeve back along the rod.
s = base_link()
s += f'''  <link name="rail">
    <visual><origin xyz="0 0 0" rpy="0 1.5707963 0"/><geometry><cylinder radius="0.006" length="0.6"/></geometry><material name="steel"><color rgba="0.7 0.7 0.75 1"/></material></visual>
  </link>
  <link name="sleeve">
    <inertial><origin xyz="0 0 -0.15"/><mass value="0.6"/><inertia ixx="0.002" iyy="0.002" izz="0.0005" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><origin xyz="0 0 0" rpy="0 1.5707963 0"/><geometry><cylinder radius="0.015" length="0.05"/></geometry><material name="sleeve_color"><color rgba="0.2 0.5 0.8 1"/></material></visual>
    <visual><origin xyz="0 0 -0.075"/><geometry><cylinder radius="0.004" length="0.15"/></geometry><material name="sleeve_color"/></visual>
    <visual><origin xyz="0 0 -0.15"/><geometry><sphere radius="0.025"/></geometry><material name="sleeve_color"/></visual>
  </link>
  <joint name="rail_mount" type="fixed"><parent link="base"/><child link="rail"/><origin xyz="0 0 0.3"/></joint>
  <joint name="sleeve_joint" type="continuous"><parent link="rail"/><child link="sleeve"/><origin xyz="0 0 0"/><axis xyz="1 0 0"/></joint>
  <mechanism_sim:joint name="sleeve_joint" type="cylindrical"/>
  <mechanism_sim:spring name="return_spring" stiffness="60" damping="0.2" rest_length="0.2">
    <from link="rail" xyz="-0.3 0 0"/><to link="sleeve" xyz="0 0 0"/>
  </mechanism_sim:spring>
  <mechanism_sim:initial joint="sleeve_joint.rotation" position="0.8"/>
  <mechanism_sim:initial joint="sleeve_joint.translation" velocity="0.3"/>
'''
write("cylindrical_pendulum.urdf", s, "A pendulum on a cylindrical joint: it swings about a rail and slides along it against a spring.")

# ---- Cardan drive shaft: input about x, output about an axis 30 degrees off, joined by a cross.
beta = math.radians(30)
a2 = [math.cos(beta), 0, math.sin(beta)]
U = [0, 0, 0.2]
P1 = add(U, [-0.25, 0, 0])
P2 = add(U, scale(a2, 0.25))
s = base_link()
s += rod_link("input_shaft", [0, 0, 0], sub(U, P1), 1.0, radius=0.012)
s += rod_link("output_shaft", [0, 0, 0], sub(U, P2), 1.0, "0.8 0.6 0.2 1", radius=0.012)
s += joint("input_joint", "continuous", "base", "input_shaft", P1, [1, 0, 0])
s += joint("output_joint", "continuous", "base", "output_shaft", P2, a2)
s += f'''  <mechanism_sim:joint name="cross" type="universal">
    <parent link="input_shaft"/><child link="output_shaft"/>
    <origin xyz="{v(sub(U, P1))}"/><child_origin xyz="{v(sub(U, P2))}"/>
    <axis xyz="0 1 0"/><axis2 xyz="{v([-math.sin(beta), 0, math.cos(beta)])}"/>
  </mechanism_sim:joint>
  <mechanism_sim:gravity xyz="0 0 0"/>
  <mechanism_sim:initial joint="input_joint" velocity="6.0"/>
'''
write("cardan_shaft.urdf", s, "Cardan (universal-joint) drive: shafts at 30 degrees joined by a cross; the output speed fluctuates.")

# ---- spatial RSSR: crank about z, rocker about x, coupler with a ball joint at each end.
O1, O2 = [0, 0, 0.1], [0.3, 0.25, 0.2]
Acr = add(O1, [0.08, 0, 0])
Bro = add(O2, [0, -0.15, 0])
s = base_link()
s += rod_link("crank", [0, 0, 0], sub(Acr, O1), 0.3)
s += rod_link("coupler", [0, 0, 0], sub(Bro, Acr), 0.4, "0.2 0.8 0.3 1")
s += rod_link("rocker", [0, 0, 0], sub(Bro, O2), 0.4, "0.8 0.6 0.2 1")
s += joint("crank_joint", "continuous", "base", "crank", O1, [0, 0, 1])
s += joint("ball_a", "continuous", "crank", "coupler", sub(Acr, O1), [0, 0, 1])
s += joint("rocker_joint", "continuous", "base", "rocker", O2, [1, 0, 0])
s += f'''  <mechanism_sim:joint name="ball_a" type="spherical"/>
  <mechanism_sim:joint name="ball_b" type="spherical">
    <parent link="rocker"/><child link="coupler"/>
    <origin xyz="{v(sub(Bro, O2))}"/><child_origin xyz="{v(sub(Bro, Acr))}"/>
  </mechanism_sim:joint>
  <mechanism_sim:initial joint="crank_joint" velocity="5.0"/>
'''
write("rssr_linkage.urdf", s, "Spatial RSSR linkage: revolute crank, ball-jointed coupler, revolute rocker on a skew axis.")

# ---- parallel-jaw gripper: a slider pushes two links that drive two jaws on rails (two loops).
S, JL, JR = [0, 0, 0.1], [-0.05, 0, 0.02], [0.05, 0, 0.02]
s = base_link()
s += box_link("slider", [0.03, 0.03, 0.03], 0.3)
s += rod_link("link_left", [0, 0, 0], sub(JL, S), 0.1)
s += rod_link("link_right", [0, 0, 0], sub(JR, S), 0.1)
s += box_link("jaw_left", [0.01, 0.04, 0.06], 0.2, "0.2 0.8 0.3 1", (0, 0, -0.03))
s += box_link("jaw_right", [0.01, 0.04, 0.06], 0.2, "0.2 0.8 0.3 1", (0, 0, -0.03))
s += joint("slider_joint", "prismatic", "base", "slider", S, [0, 0, 1], (-0.05, 0.05, 200, 1))
s += joint("left_pivot", "continuous", "slider", "link_left", [0, 0, 0], Y)
s += joint("right_pivot", "continuous", "slider", "link_right", [0, 0, 0], Y)
s += joint("jaw_left_joint", "prismatic", "base", "jaw_left", JL, [-1, 0, 0], (-0.01, 0.045, 100, 1))
s += joint("jaw_right_joint", "prismatic", "base", "jaw_right", JR, [1, 0, 0], (-0.01, 0.045, 100, 1))
for side, J in (("left", JL), ("right", JR)):
    s += f'''  <mechanism_sim:joint name="{side}_jaw_pin" type="revolute">
    <parent link="link_{side}"/><child link="jaw_{side}"/>
    <origin xyz="{v(sub(J, S))}"/>
    <axis xyz="0 1 0"/>
  </mechanism_sim:joint>
'''
s += '''  <!-- An actuator pulls the slider down, opening the jaws against their stops. -->
  <mechanism_sim:spring name="actuator" stiffness="0" damping="5" force="20">
    <from link="base" xyz="0 0 -0.2"/><to link="slider" xyz="0 0 0"/>
  </mechanism_sim:spring>
'''
write("parallel_gripper.urdf", s, "Parallel-jaw gripper: a slider drives both jaws through two closed loops; the jaws stop at their limits.")
