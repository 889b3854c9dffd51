#!/usr/bin/env python3
"""One live status line of a running mechanism_sim node: simulation time, real-time factor,
largest constraint violation (position, velocity). Used by scripts/demo."""
import argparse
import sys
import time

import rosgraph
import rospy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped

parser = argparse.ArgumentParser()
parser.add_argument("--node", default="/mechanism_sim")
parser.add_argument("--duration", type=float, default=0.0, help="stop after this many seconds (0: until Ctrl-C)")
args = parser.parse_args(rospy.myargv()[1:])

state = {"rtf": float("nan"), "time": 0.0, "p": 0.0, "v": 0.0, "worst": 0.0, "seen": False}


def on_violation(msg):
    state["p"], state["v"], state["seen"] = msg.vector.x, msg.vector.y, True
    state["worst"] = max(state["worst"], msg.vector.x, msg.vector.y)


def on_diagnostics(msg):
    for status in msg.status:
        if "constraints" not in status.name:
            continue
        values = {kv.key: kv.value for kv in status.values}
        state["rtf"] = float(values.get("real-time factor", "nan"))
        state["time"] = float(values.get("simulation time [s]", "0"))


# roslaunch starts the master: wait for it quietly (rospy would warn "master may not be
# running yet"), then for the node's first diagnostics before printing a line.
start = time.time()
while not rosgraph.is_master_online():
    if time.time() - start > 30:
        print("no ROS master after 30 s", file=sys.stderr)
        sys.exit(1)
    time.sleep(0.1)
rospy.init_node("mechanism_sim_status", anonymous=True, disable_signals=True)
rospy.Subscriber(args.node + "/constraint_violation", Vector3Stamped, on_violation)
rospy.Subscriber("/diagnostics", DiagnosticArray, on_diagnostics)
tty = sys.stdout.isatty()
try:
    while not rospy.is_shutdown():
        if args.duration and time.time() - start > args.duration:
            break
        if not state["seen"] and time.time() - start > 30:
            print("no status from %s after 30 s" % args.node, file=sys.stderr)
            sys.exit(1)
        if not state["seen"] or state["rtf"] != state["rtf"]:  # nothing measured yet: no line of nan
            time.sleep(0.1)
            continue
        line = "t %8.2f s   real-time factor %5.2f   violation %.1e (position) %.1e (velocity)   worst %.1e" % (
            state["time"], state["rtf"], state["p"], state["v"], state["worst"])
        print(("\r" + line) if tty else line, end="" if tty else "\n", flush=True)
        time.sleep(0.25 if tty else 1.0)
except KeyboardInterrupt:
    pass
print()
