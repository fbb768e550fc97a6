"""Plain rclpy, two processes: `pub MODE` publishes good JointStates at 20 Hz with one bad payload at k=20;
`sub` prints the arrival gaps. No gwr_predictor code."""
import sys, time
import rclpy
from rclpy.node import Node
from sensor_msgs.msg import JointState
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy, DurabilityPolicy

qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.VOLATILE)
rclpy.init()
node = Node(sys.argv[1])
if sys.argv[1] == "sub":
    last = [None]; seen = []
    def cb(msg):
        now = time.monotonic()
        seen.append((msg.header.stamp.sec, now))
    node.create_subscription(JointState, "t", cb, qos)
    end = time.monotonic() + float(sys.argv[2])
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    ks = [k for k, _ in seen]
    gaps = [(seen[i][0], round(seen[i][1] - seen[i-1][1], 3)) for i in range(1, len(seen)) if seen[i][1] - seen[i-1][1] > 0.2]
    print(f"sub: {len(seen)} received, missing {sorted(set(range(1, 61)) - set(ks))}, gaps > 0.2 s before k: {gaps}")
else:
    pub = node.create_publisher(JointState, "t", qos)
    while pub.get_subscription_count() < 1:
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(0.5)
    for k in range(1, 61):
        if k == 20:
            pub.publish(b"" if sys.argv[2] == "empty" else b"\x00\x01\x00\x00")
        m = JointState(); m.header.stamp.sec = k
        pub.publish(m)
        time.sleep(0.05)
    time.sleep(1.0)
