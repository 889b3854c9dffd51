#!/usr/bin/env python3
"""~joint_trajectory on test/urdf/pendulum_trajectory.urdf (I = 0.52 kg m^2 about the pivot,
m g l = 9.81 N m, hanging at rest at q = 0). The test plans the path itself: with
positions, velocities and accelerations at every point the node's path is the quintic
Hermite interpolant through them (doc/trajectories.md), written here with the Hermite basis.
The efforts published in joint_states must be the inverse dynamics of that path,
tau = I q'' + m g l sin q."""
import math
import threading
import time
import unittest

import rospy
import rostest
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from node_client import connected_publisher

PKG = "mechanism_sim"
I, MGL = 0.52, 2 * 9.81 * 0.5
A, T = 0.8, 2.0  # q(t) = A (1 - cos(w t))^2 / 4, w = 2 pi / T: from rest back to rest
W = 2 * math.pi / T


def planned(t):
    c, s = math.cos(W * t), math.sin(W * t)
    return A * (1 - c) ** 2 / 4, A / 2 * (1 - c) * s * W, A / 2 * W * W * (s * s + (1 - c) * c)


POINTS = [(0.1 * i,) + planned(0.1 * i) for i in range(21)]  # (t, q, v, a)


def path(t):
    """The quintic Hermite path through POINTS: q, q'' at t (after the end: at rest)."""
    if t <= 0:
        return 0.0, 0.0
    if t >= POINTS[-1][0]:
        return POINTS[-1][1], 0.0
    i = min(int(t / 0.1), len(POINTS) - 2)
    (t0, q0, v0, a0), (t1, q1, v1, a1) = POINTS[i], POINTS[i + 1]
    h = t1 - t0
    s = (t - t0) / h
    H = [1 - 10 * s**3 + 15 * s**4 - 6 * s**5, s - 6 * s**3 + 8 * s**4 - 3 * s**5,
         (s**2 - 3 * s**3 + 3 * s**4 - s**5) / 2, (s**3 - 2 * s**4 + s**5) / 2,
         -4 * s**3 + 7 * s**4 - 3 * s**5, 10 * s**3 - 15 * s**4 + 6 * s**5]
    D = [-60 * s + 180 * s**2 - 120 * s**3, -36 * s + 96 * s**2 - 60 * s**3,
         (2 - 18 * s + 36 * s**2 - 20 * s**3) / 2, (6 * s - 24 * s**2 + 20 * s**3) / 2,
         -24 * s + 84 * s**2 - 60 * s**3, 60 * s - 180 * s**2 + 120 * s**3]
    q = H[0] * q0 + H[1] * h * v0 + H[2] * h * h * a0 + H[3] * h * h * a1 + H[4] * h * v1 + H[5] * q1
    q_ddot = (D[0] * q0 + D[5] * q1) / h**2 + (D[1] * v0 + D[4] * v1) / h + D[2] * a0 + D[3] * a1
    return q, q_ddot


def message(points, stamp=rospy.Time(0), names=("pivot",)):
    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp = stamp
    for p in points:
        pt = JointTrajectoryPoint(positions=[p[1]], time_from_start=rospy.Duration.from_sec(p[0]))
        if len(p) > 2:
            pt.velocities, pt.accelerations = [p[2]], [p[3]]
        msg.points.append(pt)
    return msg


class Trajectory(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("trajectory_test")
        cls.lock = threading.Lock()
        cls.samples, cls.errors = [], []
        rospy.Subscriber("/joint_states", JointState, cls.on_state, queue_size=1000)
        rospy.Subscriber("/rosout", Log, cls.on_log, queue_size=100)
        cls.pub = connected_publisher("/mechanism_sim/joint_trajectory", JointTrajectory)
        rospy.wait_for_message("/joint_states", JointState, 10.0)

    @classmethod
    def on_state(cls, js):
        i = js.name.index("pivot")
        with cls.lock:
            cls.samples.append((js.header.stamp, js.position[i], js.effort[i]))

    @classmethod
    def on_log(cls, log):
        if log.level >= Log.ERROR and log.name.endswith("mechanism_sim"):
            with cls.lock:
                cls.errors.append(log.msg)

    def wait_error(self, text, timeout=5.0):
        deadline = time.time() + timeout
        while time.time() < deadline:
            with self.lock:
                found = [e for e in self.errors if text in e]
            if found:
                return found[0]
            time.sleep(0.05)
        self.fail("no ROS_ERROR with '%s' (seen: %s)" % (text, self.errors))

    def test_1_stamped_trajectory_efforts_are_the_inverse_dynamics(self):
        with self.lock:
            last = self.samples[-1][0]
        start = last + rospy.Duration(0.3)  # on the node's step grid: its stamps are origin + n h
        self.pub.publish(message(POINTS, start))
        # in mid-path, a message whose times do not increase: rejected, nothing changes
        while rospy.Time.now() < start + rospy.Duration(0.8):
            time.sleep(0.02)
        self.pub.publish(message([(0.0, 0.1), (0.5, 0.2), (0.5, 0.3)]))
        self.assertIn("point 3", self.wait_error("times must increase"))
        while True:
            with self.lock:
                if self.samples[-1][0] > start + rospy.Duration(T + 0.3):
                    break
            time.sleep(0.05)
        with self.lock:
            samples = [s for s in self.samples if s[0] > start - rospy.Duration(0.2)]
        worst_q = worst_tau = 0.0
        n = 0
        for stamp, q, tau in samples:
            t = (stamp - start).to_sec()
            q_p, q_ddot = path(t)
            worst_q = max(worst_q, abs(q - q_p))
            worst_tau = max(worst_tau, abs(tau - (I * q_ddot + MGL * math.sin(q_p))))
            n += 1
        peak = max(abs(s[2]) for s in samples)
        rospy.loginfo("trajectory: %d samples, |q - path| %.2e rad, |tau - inverse dynamics| %.2e N m (peak %.2f)",
                      n, worst_q, worst_tau, peak)
        self.assertGreater(n, 200)
        self.assertGreater(peak, 1.0)  # the path needs effort: a free pendulum would not pass
        self.assertLess(worst_q, 1e-9)
        self.assertLess(worst_tau, 1e-6)

    def test_2_zero_stamp_starts_on_receipt_and_far_starts_are_rejected(self):
        # at rest at 0 (test 1 ended there): a first point 0.5 rad away is refused
        self.pub.publish(message([(0.0, 0.5), (1.0, 0.6)]))
        self.assertIn("start tolerance 0.1", self.wait_error("is 0.5 from its position"))
        # positions only, zero stamp: a clamped spline from now to rest at 0.3 rad in 0.5 s
        self.pub.publish(message([(0.0, 0.0), (0.5, 0.3)]))
        time.sleep(1.5)
        with self.lock:
            stamp, q, tau = self.samples[-1]
        self.assertAlmostEqual(q, 0.3, places=9)
        self.assertAlmostEqual(tau, MGL * math.sin(0.3), places=6)  # held against gravity


if __name__ == "__main__":
    rostest.rosrun(PKG, "trajectory_test", Trajectory)
