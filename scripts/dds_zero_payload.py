"""Plain rclpy, no gwr_predictor code: what a 0-byte payload does to a reliable JointState stream.

Subscribers saw `arm_angles` / `predictions` stall for 6-9 s after a hostile publisher sent a 0-byte
payload. This script shows it is Fast DDS (rmw_fastrtps_cpp) behaviour of the *sending* writer:

    python scripts/dds_zero_payload.py            # runs both cases below, prints one line each

- `same`: one publisher sends 80 JointStates at 20 Hz and a 0-byte payload before the 20th: the
  subscriber gets nothing from that publisher for seconds, then the held samples all at once;
- `other`: a second publisher sends the 0-byte payload while the first streams: the first
  publisher's stream arrives without a gap.

So a node is not stalled by someone else's empty message; only the offending publisher's own
later samples are held (and delivered late, none lost while it lives). The nodes need no change.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.VOLATILE)
N = 80


def subscriber(seconds: float) -> None:
    node = Node("zero_payload_sub")
    seen: list[tuple[int, float]] = []
    node.create_subscription(JointState, "zero_payload", lambda m: seen.append((m.header.stamp.sec, time.monotonic())),
                             QOS)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    gaps = [round(seen[i][1] - seen[i - 1][1], 2) for i in range(1, len(seen)) if seen[i][1] - seen[i - 1][1] > 0.2]
    print(f"received {len(seen)} of {N} genuine messages; gaps longer than 0.2 s: {gaps or 'none'}", flush=True)


def publisher(mode: str) -> None:
    node = Node(f"zero_payload_pub_{mode}")
    pub = node.create_publisher(JointState, "zero_payload", QOS)
    while pub.get_subscription_count() < 1:
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(0.5)
    for k in range(1, N + 1):
        if k == 20 and mode in ("same", "hostile"):
            pub.publish(b"")  # a serialized message of 0 bytes
        if mode == "hostile":
            return
        msg = JointState()
        msg.header.stamp.sec = k
        pub.publish(msg)
        time.sleep(0.05)
    time.sleep(1.0)


def main() -> int:
    if len(sys.argv) > 1:
        rclpy.init()
        role = sys.argv[1]
        subscriber(float(sys.argv[2])) if role == "sub" else publisher(role)
        rclpy.shutdown()
        return 0
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    for case, pubs in (("same", ["same"]), ("other", ["good", "hostile"])):
        sub = subprocess.Popen([sys.executable, __file__, "sub", "12"], env=env)
        time.sleep(1.5)
        procs = [subprocess.Popen([sys.executable, __file__, p], env=env) for p in pubs]
        for p in procs:
            p.wait(60)
        print(f"case {case}: ", end="", flush=True)
        sub.wait(60)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
