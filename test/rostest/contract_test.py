#!/usr/bin/env python3
"""The node as its users meet it: joint_states, tf, /clock, services, effort commands,
several instances, and a bad model exiting with its error."""
import os
import signal
import subprocess
import time
import unittest

import rospy
import rostest
import tf2_ros
import yaml
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Empty

from mechanism_sim.srv import StepSimulation

PKG = "mechanism_sim"
SRC = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def joint_states(ns, timeout=10.0):
    return rospy.wait_for_message("/%s/joint_states" % ns, JointState, timeout)


def service(ns, name, kind=Empty):
    full = "/%s/mechanism_sim/%s" % (ns, name)
    rospy.wait_for_service(full, 10.0)
    return rospy.ServiceProxy(full, kind)


class NodeContract(unittest.TestCase):
    def test_joint_states_name_every_dof_in_file_order(self):
        a = joint_states("a")
        self.assertEqual(a.name, ["crank_joint", "coupler_joint", "rocker_joint", "loop"])
        b = joint_states("b")
        self.assertEqual(b.name, ["crank_joint", "rod_joint", "slider_joint", "wrist_pin"])
        for msg in (a, b):
            self.assertEqual(len(msg.position), len(msg.name))
            self.assertEqual(len(msg.velocity), len(msg.name))
            self.assertEqual(len(msg.effort), len(msg.name))

    def test_tf_follows_the_urdf_tree_with_prefixes(self):
        buf = tf2_ros.Buffer()
        tf2_ros.TransformListener(buf)
        deadline = time.time() + 10
        parents = {}
        while time.time() < deadline:
            frames = yaml.safe_load(buf.all_frames_as_yaml()) or {}
            parents = {k: v["parent"] for k, v in frames.items()}
            if {"a/rocker", "b/slider", "b/flywheel"} <= set(parents):
                break
            time.sleep(0.2)
        self.assertEqual(parents.get("a/crank"), "a/base")
        self.assertEqual(parents.get("a/coupler"), "a/crank")
        self.assertEqual(parents.get("a/rocker"), "a/coupler")
        self.assertEqual(parents.get("b/rod"), "b/crank")
        self.assertEqual(parents.get("b/slider"), "b/base")
        self.assertEqual(parents.get("b/flywheel"), "b/crank")  # fixed joint, on /tf_static
        self.assertNotIn("base", parents)  # nothing unprefixed

    def test_clock_is_published_by_the_instance_that_owns_it(self):
        c1 = rospy.wait_for_message("/clock", Clock, 10.0).clock
        time.sleep(0.5)
        c2 = rospy.wait_for_message("/clock", Clock, 10.0).clock
        self.assertGreater(c2, c1)
        self.assertLess(c2.to_sec(), 1e6)  # simulation time, not wall time
        stamp = joint_states("a").header.stamp.to_sec()
        self.assertLess(stamp, 1e6)  # a's messages carry simulation time

    def test_pause_step_unpause(self):
        service("a", "pause")()
        time.sleep(0.3)
        t0 = rospy.wait_for_message("/clock", Clock, 10.0).clock.to_sec()
        p0 = joint_states("a").position
        time.sleep(0.3)
        self.assertEqual(joint_states("a").position, p0)  # paused: nothing moves
        after = service("a", "advance", StepSimulation)(10).time
        self.assertAlmostEqual(after - t0, 0.010, places=9)
        self.assertNotEqual(joint_states("a").position, p0)
        service("a", "unpause")()
        t1 = rospy.wait_for_message("/clock", Clock, 10.0).clock.to_sec()
        time.sleep(0.5)
        self.assertGreater(rospy.wait_for_message("/clock", Clock, 10.0).clock.to_sec(), t1 + 0.3)
        with self.assertRaises(rospy.ServiceException):  # stepping needs a paused simulation
            service("a", "advance", StepSimulation)(5)

    def test_reset_returns_to_the_initial_state(self):
        time.sleep(0.5)
        self.assertGreater(abs(joint_states("b").position[0] - 0.5), 0.05)  # it has moved
        service("b", "pause")()
        service("b", "reset")()
        time.sleep(0.2)
        msg = joint_states("b")
        stamps = [joint_states("b").header.stamp for _ in range(3)]
        service("b", "unpause")()
        # b has no /clock: stamps keep following wall time through a pause and a reset
        self.assertLess(stamps[0], stamps[1])
        self.assertLess(stamps[1], stamps[2])
        self.assertLess(abs(stamps[2].to_sec() - time.time()), 1.0)
        # initial_positions holds crank_joint at 0.5; the file gives it 14 rad/s
        self.assertAlmostEqual(msg.position[0], 0.5, places=9)
        self.assertAlmostEqual(msg.velocity[0], 14.0, places=9)

    def test_effort_commands_bad_ones_rejected_whole(self):
        pub = rospy.Publisher("/b/mechanism_sim/effort_command", JointState, queue_size=10)
        time.sleep(1.0)

        def effort_of(name):
            msg = joint_states("b")
            return msg.effort[msg.name.index(name)]

        def send(names, efforts):
            pub.publish(JointState(name=names, effort=efforts))
            time.sleep(0.5)

        send(["slider_joint"], [2.5])
        self.assertAlmostEqual(effort_of("slider_joint"), 2.5, places=9)
        send(["slider_joint", "nope"], [7.0, 1.0])                # unknown joint
        send(["slider_joint"], [float("nan")])                     # not finite
        send(["slider_joint", "crank_joint"], [7.0])               # mismatched arrays
        self.assertAlmostEqual(effort_of("slider_joint"), 2.5, places=9)
        send(["slider_joint"], [0.0])

    def test_ctrl_c_shuts_the_node_down_within_a_second(self):
        model = os.path.join(SRC, "urdf", "four_bar.urdf")
        proc = subprocess.Popen(["rosrun", PKG, "mechanism_sim_node", "__ns:=probe", "_model_file:=" + model],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            joint_states("probe", 20.0)
            time.sleep(1.0)
            start = time.time()
            os.kill(proc.pid, signal.SIGINT)  # rosrun execs the node: this is the node
            proc.wait(timeout=5)
            self.assertLess(time.time() - start, 1.0)
            self.assertEqual(proc.returncode, 0)
        finally:
            if proc.poll() is None:
                proc.kill()

    def test_bad_model_ends_the_node_with_the_loader_error(self):
        bad = os.path.join(SRC, "test", "invalid", "negative_mass.urdf")
        result = subprocess.run(["rosrun", PKG, "mechanism_sim_node", "__name:=bad_model", "_model_file:=" + bad],
                                capture_output=True, text=True, timeout=30)
        self.assertEqual(result.returncode, 1, result.stdout + result.stderr)
        self.assertIn("negative_mass.urdf:", result.stdout + result.stderr)
        self.assertIn("mass is negative", result.stdout + result.stderr)


if __name__ == "__main__":
    rospy.init_node("node_contract_test")
    rostest.rosrun(PKG, "node_contract", NodeContract)
