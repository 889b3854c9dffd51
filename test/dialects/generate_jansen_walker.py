"""Writes test/dialects/jansen_walker_drake.urdf (run by hand: python3 THIS > FILE): a
Jansen-linkage walker shaped like Drake's strandbeest. Twelve legs (six crank phases, each
leg and its mirror image) on one crank; each leg is a tree of six bars closed by three
<drake:ball_constraint>s; every bar lies along its parent at the zero pose, and each leg
joint is limited to its closed angle +- 0.5 rad, so the zero pose lies outside most limits
and the limits pick the branch. Jansen's lengths (cm); the crank phases are ones at which
this reading of the linkage closes."""
import numpy as np, sys
S = 0.01  # Jansen's numbers in cm
a, l, m, j, b, c, d, e, f, g, h, i, k = 38, 7.8, 15, 50, 41.5, 39.3, 40.1, 55.8, 39.4, 36.7, 65.7, 49, 61.9
def circ(p0, r0, p1, r1, side):
    dd = np.linalg.norm(p1 - p0); x = (dd*dd + r0*r0 - r1*r1) / (2*dd); y = np.sqrt(r0*r0 - x*x)
    u = (p1 - p0) / dd; n = np.array([-u[1], u[0]])
    return p0 + x*u + side*y*n
def leg(theta, mirror):
    O = np.zeros(2); P = np.array([-a, -l]); M = m*np.array([np.cos(theta), np.sin(theta)])
    Q = circ(M, j, P, b, -1); R = circ(M, k, P, c, 1)
    Sp = circ(P, d, Q, e, -1); T = circ(Sp, f, R, g, -1); U = circ(T, h, R, i, -1)
    pts = dict(O=O, P=P, M=M, Q=Q, R=R, S=Sp, T=T, U=U)
    if mirror: pts = {n: np.array([-v[0], v[1]]) for n, v in pts.items()}
    return {n: S*v for n, v in pts.items()}
def Ry(psi):  # rotation about +y: (x, z) plane; x' = x cos + z sin, z' = -x sin + z cos
    return np.array([[np.cos(psi), np.sin(psi)], [-np.sin(psi), np.cos(psi)]])
def ang(v):  # psi so that Ry(psi) @ (0, 1) is v's direction: (sin psi, cos psi)
    return np.arctan2(v[0], v[1])
out = []
W = out.append
W('<?xml version="1.0"?>')
W('<!-- mechanism_sim test fixture written by generate_jansen_walker.py: a Jansen-linkage')
W('     walker shaped like Drake\'s strandbeest (legs closed by <drake:ball_constraint>s, joints')
W('     limited around their closed angles, the zero pose outside the limits). -->')
W('<robot name="jansen_walker" xmlns:drake="http://drake.mit.edu">')
def inertial(mass, com, length):
    I = mass*length*length/12 + 1e-5
    return ('<inertial><origin xyz="%.9f 0 %.9f"/><mass value="%g"/><inertia ixx="%.6g" iyy="%.6g" izz="1e-05" ixy="0" ixz="0" iyz="0"/></inertial>'
            % (com[0], com[1], mass, I, I))
W('  <link name="frame">' + inertial(2.0, (0, 0), 0.5) + '</link>')
W('  <joint name="frame_weld" type="fixed"><parent link="world"/><child link="frame"/><origin xyz="0 0 1"/></joint>')
W('  <link name="crank">' + inertial(0.5, (0, 0), 0.3) + '</link>')
W('  <joint name="crank_joint" type="continuous"><parent link="frame"/><child link="crank"/><axis xyz="0 1 0"/></joint>')
legs = []
for phase in (0.0, 1.05, 2.09, 4.19, 5.24, 0.52):
    for mirror in (0, 1):
        legs.append((phase, mirror))
balls = []
for n, (phase, mirror) in enumerate(legs):
    p = leg(phase, mirror); pre = "leg%d" % (n + 1)
    # bodies: (name, parent, joint point, direction point, other points); angles psi in the world
    bodies = [("j", "crank", "M", "Q", []), ("k", "j", "M", "R", []), ("c", "k", "R", "P", []),
              ("g", "k", "R", "T", ["U"]), ("b", "j", "Q", "P", ["S"]), ("f", "b", "S", "T", [])]
    psi = {"crank": 0.0}; origin = {"crank": np.zeros(2)}
    for name, parent, jp, dp, others in bodies:
        psi[name] = ang(p[dp] - p[jp]); origin[name] = p[jp]
    def local(body, point):  # the point in body coordinates (x, z)
        return Ry(psi[body]).T @ (point - origin[body]) if body != "crank" else point - origin[body]
    for name, parent, jp, dp, others in bodies:
        L = np.linalg.norm(p[dp] - p[jp])
        W('  <link name="%s_%s">%s</link>' % (pre, name, inertial(0.1, (0, L/2), L)))
        jo = local(parent, p[jp]) if parent == "crank" else (Ry(psi[parent]).T @ (p[jp] - origin[parent]))
        q = psi[name] - psi[parent]
        q = (q + np.pi) % (2*np.pi) - np.pi
        pname = parent if parent == "crank" else "%s_%s" % (pre, parent)
        if parent == "crank":
            W('  <joint name="%s_joint_%s" type="continuous"><parent link="crank"/><child link="%s_%s"/><origin xyz="%.9f 0 %.9f"/><axis xyz="0 1 0"/></joint>'
              % (pre, name, pre, name, jo[0], jo[1]))
        else:
            lo, hi = q - 0.5, q + 0.5
            W('  <joint name="%s_joint_%s" type="revolute"><parent link="%s"/><child link="%s_%s"/><origin xyz="%.9f 0 %.9f"/><axis xyz="0 1 0"/><limit lower="%.4f" upper="%.4f" effort="0" velocity="100"/></joint>'
              % (pre, name, pname, pre, name, jo[0], jo[1], lo, hi))
    def ball(A, pA, B, pB):
        W('  <drake:ball_constraint><drake:ball_constraint_body_A name="%s"/><drake:ball_constraint_p_AP value="%.9f 0 %.9f"/><drake:ball_constraint_body_B name="%s"/><drake:ball_constraint_p_BQ value="%.9f 0 %.9f"/></drake:ball_constraint>'
          % (A, pA[0], pA[1], B, pB[0], pB[1]))
    ball(pre + "_c", local("c", p["P"]), "frame", p["P"])
    ball(pre + "_b", local("b", p["P"]), pre + "_c", local("c", p["P"]))
    ball(pre + "_f", local("f", p["T"]), pre + "_g", local("g", p["T"]))
W('</robot>')
print("\n".join(out))
