#!/usr/bin/env python3
"""The node under load (issue 8, item 5): effort commands at up to 10 kHz, 50 tf listeners
and two clients calling reset, pause, unpause and advance at random, all at once, for
~load_seconds. Then: the node is the same live process and still publishes; joint_states
and tf stamps never repeat or run backwards (the node stamps with wall time here, and
doc/node.md "Time, pausing and pacing" promises that a pause, an advance or a reset moves
the origin so that they never do); every joint_states message shows one whole command, never
an older one than it showed before, and the last command sent is the one applied; every tf
listener has every frame and is current; every service call returned within call_timeout. A
call whose connection closed before the response ("transport error", rare: rospy and roscpp
under this load) is made once more and counted; at most one in 1,000 calls may need it.

A second instance, /clock/mechanism_sim, owns /clock (its tf remapped to /clock/tf), and a
third client calls its services likewise. There a reset takes time back to 0 by design,
so: its joint_states stamps never go back except to exactly 0, the i-th time with at least
i resets called (they repeat while paused), and its tf stamps strictly increase per frame
except for the same drops to 0.

Commands: command k sets crank_joint to  s (k + 1) 2^-24  and rocker_joint to
-s (k + 1) 2^-23  (s = +1 for even k, -1 for odd), names in alternating order. Both dofs
have no damping, friction, limit or effort limit, so joint_states reports the command
applied in the last step bit for bit; both decode to the same k or the node mixed two
commands. A reset zeroes the commands (MechanismModel::reset), so (0, 0) is allowed
once a reset has been called, and then the next commands are newer ones.

Run with --listener-process N FRAME...: N tf2 listeners in this process, for the test
below (it starts listener_processes of them: rospy shares one /tf connection between the
subscribers of a process, several processes make the node serve several connections)."""
import json
import os
import random
import select
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import xmlrpc.client

import rosgraph
import rosnode
import rospy
import rostest
import tf2_ros
from sensor_msgs.msg import JointState
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from mechanism_sim.srv import StepSimulation

PKG = "mechanism_sim"
OPS = ("reset", "pause", "unpause", "advance")
NODE, CLOCK_NODE = "/mechanism_sim", "/clock/mechanism_sim"  # wall-clock stamps; owns /clock
ROOT, FRAMES = "base", ["crank", "coupler", "rocker"]  # four_bar.urdf: base -> crank -> coupler -> rocker
DOF_A, DOF_B = "crank_joint", "rocker_joint"
SCALE_A, SCALE_B = 2.0 ** -24, -(2.0 ** -23)


def encode(k):
    s = 1.0 if k % 2 == 0 else -1.0
    return s * (k + 1) * SCALE_A, s * (k + 1) * SCALE_B


def decode(a, b):
    """k of a command, None for (0, 0) (no command since the start or a reset), or a
    string saying what is wrong."""
    if a == 0.0 and b == 0.0:
        return None
    ka, kb = abs(a) / SCALE_A - 1, abs(b) / abs(SCALE_B) - 1
    if ka != int(ka) or ka != kb or encode(int(ka)) != (a, b):
        return "efforts %r, %r are not one command" % (a, b)
    return int(ka)


def calls_between(c0, c1):
    """The service calls started between two messages (from the counts at each)."""
    return {op: b - a for op, a, b in zip(OPS, c0, c1) if b > a}


def describe_backwards(back):
    """Stamp steps that repeat or go back: how many, by how much, what calls preceded them."""
    if not back:
        return "none"
    worst = max(s0 - s1 for s0, s1, _ in back)
    return "%d repeat, the others go back by up to %.3f ms; the first (ns, next ns, calls started "\
           "between): %s" % (sum(1 for s0, s1, _ in back if s0 == s1), worst / 1e6, back[:5])


# ---------------------------------------------------------------- listener process
class CountingListener(tf2_ros.TransformListener):
    def __init__(self, buf):
        self.messages = 0
        super().__init__(buf)

    def callback(self, data):
        self.messages += 1
        super().callback(data)


def listener_process(n, frames, timeout=150.0):
    """N listeners until a line on stdin (or timeout); then one JSON line: per listener,
    the messages it received and the stamp of each frame's latest transform from ROOT."""
    rospy.init_node("tf_listeners", anonymous=True, disable_signals=True)
    buffers = [tf2_ros.Buffer() for _ in range(n)]
    listeners = [CountingListener(b) for b in buffers]
    print("ready", flush=True)
    select.select([sys.stdin], [], [], timeout)
    result = []
    for b, listener in zip(buffers, listeners):
        entry = {"messages": listener.messages, "stamps": {}}
        for f in frames:
            try:
                entry["stamps"][f] = b.lookup_transform(ROOT, f, rospy.Time(0)).header.stamp.to_sec()
            except tf2_ros.TransformException as e:
                entry["stamps"][f] = "missing: %s" % e
        result.append(entry)
    print(json.dumps(result), flush=True)
    os._exit(0)  # rospy's threads need not be waited for


# ---------------------------------------------------------------- the test
class Load:
    """Runs the load once and keeps what the tests check."""

    def __init__(self):
        def p(name, default):
            return rospy.get_param("~" + name, default)

        self.load_seconds = float(p("load_seconds", 30.0))
        self.rate = float(p("command_rate", 10000.0))
        self.processes = int(p("listener_processes", 5))
        self.per_process = int(p("listeners_per_process", 10))
        self.call_timeout = float(p("call_timeout", 10.0))
        self.start = time.monotonic()
        self.deadline = self.start + float(p("deadline", 100.0))  # the whole test, setup included
        self.lock = threading.Lock()
        self.stop_load = threading.Event()
        self.problems = []  # found while running (a stuck call, a dead node)
        self.sent_k = -1  # the last command k handed to publish()
        self.started = {n: {op: 0 for op in OPS} for n in (NODE, CLOCK_NODE)}  # calls started
        self.js = []  # (stamp ns, effort a, effort b, sent_k, resets started, receipt time, calls started)
        self.tf_backwards = []  # (frame, previous stamp, stamp, calls started between)
        self.tf_last, self.tf_messages = {}, 0
        self.clock_js, self.clock_tf = [], {}  # CLOCK_NODE: (stamp ns, calls started); by frame
        self.calls = {n: {op: {"ok": 0, "refused": 0} for op in OPS} for n in (NODE, CLOCK_NODE)}
        self.errors, self.durations, self.inflight = [], [], {}
        self.transport_drops = []  # connections closed before the response (retried once)
        self.publish_seconds = 0.0

    def remaining(self, at_most):
        return max(0.1, min(at_most, self.deadline - time.monotonic()))

    # ---- what the node sends
    def on_joint_states(self, msg):
        a = msg.effort[msg.name.index(DOF_A)]
        b = msg.effort[msg.name.index(DOF_B)]
        with self.lock:
            calls = tuple(self.started[NODE].values())
            self.js.append((msg.header.stamp.to_nsec(), a, b, self.sent_k, calls[0], time.monotonic(), calls))

    def on_tf(self, msg):
        with self.lock:
            self.tf_messages += 1
            calls = tuple(self.started[NODE].values())
            for t in msg.transforms:
                stamp = t.header.stamp.to_nsec()
                last = self.tf_last.get(t.child_frame_id)
                if last is not None and stamp <= last[0]:
                    self.tf_backwards.append((t.child_frame_id, last[0], stamp, calls_between(last[1], calls)))
                self.tf_last[t.child_frame_id] = (stamp, calls)

    def on_clock_joint_states(self, msg):
        with self.lock:
            self.clock_js.append((msg.header.stamp.to_nsec(), tuple(self.started[CLOCK_NODE].values())))

    def on_clock_tf(self, msg):
        with self.lock:
            calls = tuple(self.started[CLOCK_NODE].values())
            for t in msg.transforms:
                self.clock_tf.setdefault(t.child_frame_id, []).append((t.header.stamp.to_nsec(), calls))

    # ---- what the test sends
    def publish_commands(self, pub):
        names_ab, names_ba = [DOF_A, DOF_B], [DOF_B, DOF_A]
        start, k = time.monotonic(), 0
        while not self.stop_load.is_set():
            if k >= (time.monotonic() - start) * self.rate:
                time.sleep(0.0002)
                continue
            a, b = encode(k)
            msg = JointState(name=names_ab, effort=[a, b]) if k % 2 == 0 else JointState(name=names_ba, effort=[b, a])
            self.sent_k = k
            pub.publish(msg)
            k += 1
        self.publish_seconds = time.monotonic() - start

    def call(self, who, node, op, fn, *args):
        """One service call, timed and watched; 'refused' when the node answers with an error."""
        t0 = time.monotonic()
        with self.lock:
            self.inflight[who] = (op, t0)
            self.started[node][op] += 1
        outcome = "ok"
        try:
            try:
                fn(*args)
            except rospy.ServiceException as e:
                # A connection closed before the response came (rospy: "transport error
                # completing service call"): once in about 8,000 calls in one CI run, the node
                # alive and logging nothing. It is counted (test_service_calls_all_returned
                # bounds it) and the call is made once more; a second failure is an error.
                if "transport error" not in str(e):
                    raise
                with self.lock:
                    self.transport_drops.append("%s: %s" % (op, e))
                fn(*args)
        except rospy.ServiceException as e:
            outcome = "refused"
            # only advance may refuse (while running); a failed connection is an error too
            if op != "advance" or "responded with an error" not in str(e):
                self.errors.append("%s: %s" % (op, e))
        except Exception as e:  # a node gone
            outcome = "refused"
            self.errors.append("%s: %r" % (op, e))
        dt = time.monotonic() - t0
        with self.lock:
            del self.inflight[who]
            self.calls[node][op][outcome] += 1
            self.durations.append((dt, op))

    def client(self, who, node):
        rnd = random.Random(who)
        empty = {op: rospy.ServiceProxy(node + "/" + op, Empty) for op in ("reset", "pause", "unpause")}
        advance = rospy.ServiceProxy(node + "/advance", StepSimulation)
        while not self.stop_load.is_set():
            op = rnd.choice(["reset", "pause", "unpause", "advance"])
            if op == "advance":
                self.call(who, node, op, advance, rnd.randint(0, 50))  # 0 steps: a sample again
            else:
                self.call(who, node, op, empty[op])
            time.sleep(rnd.uniform(0.0, 0.01))

    def node_pids(self):
        pids = []
        for node in (NODE, CLOCK_NODE):
            uri = rosnode.get_api_uri(rosgraph.Master("/node_load_test"), node, skip_cache=True)
            code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/node_load_test")
            pids.append(pid if code == 1 else None)
        return pids

    def alive(self):
        """Both node processes exist and are not zombies."""
        for pid in self.pids:
            try:
                with open("/proc/%d/stat" % pid) as f:
                    if f.read().split(")")[-1].split()[0] == "Z":
                        return False
            except (OSError, TypeError):
                return False
        return True

    def watch(self, until):
        """Until `until` (monotonic) or a problem: every call returns within call_timeout,
        the node process lives."""
        while time.monotonic() < until:
            time.sleep(0.1)
            with self.lock:
                stuck = [(who, op, time.monotonic() - t0) for who, (op, t0) in self.inflight.items()
                         if time.monotonic() - t0 > self.call_timeout]
            if stuck:
                self.problems.append("service call(s) not returned within %.0f s: %s" % (self.call_timeout, stuck))
                return
            if not self.alive():
                self.problems.append("a node process is gone (%s)" % self.pids)
                return

    def run(self):
        for node in (NODE, CLOCK_NODE):
            for name in OPS:
                rospy.wait_for_service(node + "/" + name, self.remaining(30.0))
        self.pids = self.node_pids()
        assert self.alive(), "no live processes for the nodes: %s" % self.pids
        rospy.Subscriber("/joint_states", JointState, self.on_joint_states, queue_size=1000)
        rospy.Subscriber("/tf", TFMessage, self.on_tf, queue_size=1000)
        rospy.Subscriber("/clock/joint_states", JointState, self.on_clock_joint_states, queue_size=1000)
        rospy.Subscriber("/clock/tf", TFMessage, self.on_clock_tf, queue_size=1000)
        pub = rospy.Publisher(NODE + "/effort_command", JointState, queue_size=10000)

        # listeners: processes of listeners_per_process each
        self.listener_logs, self.listeners = [], []
        for _ in range(self.processes):
            log = tempfile.TemporaryFile(mode="w+")
            proc = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--listener-process",
                                     str(self.per_process)] + FRAMES, stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, stderr=log, text=True)
            self.listeners.append(proc)
            self.listener_logs.append(log)
        for proc in self.listeners:
            ready, _, _ = select.select([proc.stdout], [], [], self.remaining(60.0))
            assert ready and proc.stdout.readline().strip() == "ready", "a listener process did not start"
        t = time.monotonic()
        while pub.get_num_connections() < 1 and time.monotonic() < t + self.remaining(20.0):
            time.sleep(0.05)
        assert pub.get_num_connections() >= 1, "the node did not subscribe to effort_command"
        time.sleep(1.0)  # listeners and subscribers connected

        # the load
        self.load_start = time.monotonic()
        threads = [threading.Thread(target=self.publish_commands, args=(pub,), daemon=True)]
        threads += [threading.Thread(target=self.client, args=(who, node), daemon=True)
                    for who, node in (("client1", NODE), ("client2", NODE), ("clock client", CLOCK_NODE))]
        for th in threads:
            th.start()
        self.watch(min(self.load_start + self.load_seconds, self.deadline - 40.0))
        self.stop_load.set()
        for th in threads[1:]:  # the clients finish their last call (or the watch reported it)
            th.join(self.remaining(self.call_timeout + 1.0))
        threads[0].join(self.remaining(5.0))
        self.load_end = time.monotonic()
        self.clients_done = not any(th.is_alive() for th in threads)
        self.commands = self.sent_k + 1

        # the end: running, and one last command
        self.call("final", NODE, "unpause", rospy.ServiceProxy(NODE + "/unpause", Empty))
        self.final_k = self.sent_k + 1
        a, b = encode(self.final_k)
        self.sent_k = self.final_k
        pub.publish(JointState(name=[DOF_A, DOF_B], effort=[a, b]))
        final_sent, self.final_seen = time.monotonic(), None
        while self.final_seen is None and time.monotonic() < final_sent + self.remaining(15.0):
            with self.lock:
                if self.js and self.js[-1][5] > final_sent and (self.js[-1][1], self.js[-1][2]) == (a, b):
                    self.final_seen = time.monotonic()
            time.sleep(0.01)
        tail_start = time.monotonic()
        self.watch(tail_start + 1.0)  # still alive; messages after the final one
        with self.lock:
            self.after_final = [m for m in self.js if self.final_seen and m[5] > self.final_seen]
            self.tail = [m for m in self.js if m[5] > tail_start]

        # listeners report
        with self.lock:
            self.tf_newest = max(stamp for stamp, _ in self.tf_last.values()) / 1e9 if self.tf_last else 0.0
        self.listener_results = []
        for proc, log in zip(self.listeners, self.listener_logs):
            try:
                out, _ = proc.communicate("stop\n", timeout=self.remaining(30.0))
                self.listener_results += json.loads(out.strip().splitlines()[-1])
            except (subprocess.TimeoutExpired, ValueError, IndexError) as e:
                self.problems.append("a listener process did not report: %r" % e)
                proc.kill()
            log.seek(0)
        self.listener_stderr = "".join(log.read() for log in self.listener_logs)
        self.pids_at_end = self.node_pids()
        self.run_seconds = time.monotonic() - self.start
        self.report()

    def report(self):
        d = sorted(self.durations)
        ops = "; ".join("%s: %s" % (node, ", ".join("%s %d ok / %d refused" % (op, c["ok"], c["refused"])
                                                   for op, c in calls.items())) for node, calls in self.calls.items())
        msgs = [r["messages"] for r in self.listener_results] or [0]
        lines = [
            "commands: %d in %.1f s = %.0f Hz (target %.0f Hz), then the final command %d" % (
                self.commands, self.publish_seconds, self.commands / max(self.publish_seconds, 1e-9), self.rate,
                self.final_k),
            "final command seen after %.3f s" % (self.final_seen - self.load_end) if self.final_seen else
            "final command NOT seen",
            "service calls: %s; %d errors, %d dropped connections retried; duration median %.1f ms, 99%% %.1f ms, "
            "longest %.3f s (%s)" % (ops, len(self.errors), len(self.transport_drops), 1e3 * d[len(d) // 2][0],
                                     1e3 * d[len(d) * 99 // 100][0], d[-1][0], d[-1][1]),
            "tf listeners: %d in %d processes, %d-%d messages each" % (len(self.listener_results), self.processes,
                                                                      min(msgs), max(msgs)),
            "joint_states: %d messages, tf: %d messages; load %.1f s, whole test %.1f s" % (
                len(self.js), self.tf_messages, self.load_end - self.load_start, self.run_seconds),
            "/clock instance: %d joint_states messages, %d of them back to 0 after a reset" % (
                len(self.clock_js), sum(1 for (s0, _), (s1, _) in zip(self.clock_js, self.clock_js[1:]) if s1 < s0)),
        ]
        sys.stderr.write("".join("node_load: %s\n" % line for line in lines))
        with open(os.path.join(os.environ.get("ROS_LOG_DIR", "/tmp"), "node_load_summary.txt"), "w") as f:
            f.write("\n".join(lines) + "\n")


class NodeUnderLoad(unittest.TestCase):
    load = None

    @classmethod
    def setUpClass(cls):
        cls.load = Load()
        try:
            cls.load.run()
        finally:
            for proc in getattr(cls.load, "listeners", []):
                if proc.poll() is None:
                    proc.kill()

    def test_nothing_stuck_node_alive(self):
        L = self.load
        self.assertEqual(L.problems, [])
        self.assertTrue(L.clients_done, "a client or the publisher did not finish")
        self.assertTrue(L.alive(), "the node process is gone")
        self.assertEqual(L.pids_at_end, L.pids, "the nodes are not the processes they were")
        self.assertGreater(len(L.tail), 20, "joint_states stopped after the load (messages in its last second)")
        self.assertLess(L.run_seconds, 110.0)

    def test_commands_outnumber_publishes(self):
        """The load is a flood: several commands arrive between two joint_states messages, so
        each message must pick the newest whole command. The rate itself is the test's own
        publisher's and is reported, not asserted (bench/ measures speed)."""
        L = self.load
        sent = [m[3] for m in L.js]  # the last command k sent when each message arrived
        gaps = [k1 - k0 for k0, k1 in zip(sent, sent[1:])]
        gaps = sorted(g for g in gaps if g > 0)
        self.assertTrue(gaps, "no command was sent between two joint_states messages")
        self.assertGreater(gaps[len(gaps) // 2], 1, "median commands sent between messages")

    def test_service_calls_all_returned(self):
        L = self.load
        self.assertEqual(L.errors, [])
        total = sum(c["ok"] + c["refused"] for node in L.calls.values() for c in node.values())
        self.assertLessEqual(len(L.transport_drops), max(1, total // 1000),
                             "connections dropped before the response, of %d calls: %s" % (total, L.transport_drops))
        for node, calls in L.calls.items():
            for op, c in calls.items():
                self.assertGreater(c["ok"], 0, (node, op))
        self.assertLess(max(L.durations)[0], L.call_timeout)

    def test_joint_states_stamps_strictly_increase(self):
        js = self.load.js
        back = [(s0, s1, calls_between(c0, c1)) for (s0, *_, c0), (s1, *_, c1) in zip(js, js[1:]) if s1 <= s0]
        self.assertFalse(back, "%d of %d joint_states stamps repeat or go back: %s" % (
            len(back), len(js), describe_backwards(back)))

    def test_tf_stamps_strictly_increase_per_frame(self):
        L = self.load
        self.assertEqual(set(L.tf_last), set(FRAMES))
        back = [(s0, s1, calls) for _, s0, s1, calls in L.tf_backwards]
        self.assertFalse(back, "%d of %d tf stamps repeat or go back: %s" % (
            len(back), 3 * L.tf_messages, describe_backwards(back)))

    def test_every_message_one_command_never_an_older_one(self):
        L = self.load
        last, seen, bad = -1, set(), []
        for i, (_, a, b, sent_k, resets, *_) in enumerate(L.js):
            k = decode(a, b)
            if isinstance(k, str):
                bad.append((i, k))
            elif k is None:
                if last >= 0 and resets == 0:
                    bad.append((i, "commands zeroed with no reset called"))
            elif k > sent_k:
                bad.append((i, "command %d applied before it was sent (last sent %d)" % (k, sent_k)))
            elif k < last:
                bad.append((i, "command %d applied after command %d" % (k, last)))
            else:
                last = k
                seen.add(k)
        self.assertEqual(bad[:10], [], "%d bad messages" % len(bad))
        self.assertGreater(len(seen), 100, "the node applied only %d distinct commands" % len(seen))

    def test_last_command_is_applied(self):
        L = self.load
        self.assertIsNotNone(L.final_seen, "joint_states never showed the last command %d" % L.final_k)
        self.assertGreater(len(L.after_final), 20)
        final = encode(L.final_k)
        others = [(a, b) for _, a, b, *_ in L.after_final if (a, b) != final]
        self.assertEqual(others[:5], [], "after the last command joint_states showed other efforts")

    def test_clock_instance_time_goes_back_only_to_0_at_a_reset(self):
        """Each drop goes to exactly 0, and by the i-th drop at least i resets were called
        (a message from before a reset may arrive after the call went out, so a drop is
        matched to resets in order, not to the calls between two messages)."""
        L = self.load
        reset = OPS.index("reset")

        def wrong_drops(seq, repeats_allowed):
            bad, drops = [], 0
            for (s0, _), (s1, c1) in zip(seq, seq[1:]):
                if s1 < s0:
                    drops += 1
                    if s1 != 0 or c1[reset] < drops:
                        bad.append((s0, s1, "drop %d with %d resets called" % (drops, c1[reset])))
                elif s1 == s0 and not repeats_allowed:
                    bad.append((s0, s1, "repeat"))
            return bad, drops

        bad, drops = wrong_drops(L.clock_js, True)  # joint_states repeat while paused
        self.assertFalse(bad, "%d of %d joint_states stamps go back, not to 0 at a reset: %s" % (
            len(bad), len(L.clock_js), bad[:5]))
        self.assertGreater(drops, 0, "no reset took the /clock instance's time back: not exercised")
        self.assertEqual(set(L.clock_tf), set(FRAMES))
        for frame, seq in L.clock_tf.items():
            bad, _ = wrong_drops(seq, False)
            self.assertFalse(bad, "%s: %d of %d tf stamps repeat or go back, not to 0 at a reset: %s" % (
                frame, len(bad), len(seq), bad[:5]))

    def test_every_listener_has_every_frame_and_is_current(self):
        L = self.load
        self.assertEqual(len(L.listener_results), L.processes * L.per_process)
        for i, r in enumerate(L.listener_results):
            self.assertGreater(r["messages"], 0, "listener %d" % i)
            for f in FRAMES:
                stamp = r["stamps"][f]
                self.assertIsInstance(stamp, float, "listener %d, frame %s: %s" % (i, f, stamp))
                self.assertGreater(stamp, L.tf_newest - 5.0, "listener %d, frame %s is stale" % (i, f))
        for warning in ("TF_REPEATED_DATA", "TF_OLD_DATA"):
            self.assertNotIn(warning, L.listener_stderr)


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--listener-process":
        listener_process(int(sys.argv[2]), rospy.myargv(sys.argv)[3:])
    rospy.init_node("node_load_test")
    rostest.rosrun(PKG, "node_load", NodeUnderLoad)
