"""A tiny ROS node for discovery checks across network namespaces.

  python ros_probe.py serve NAME            # a node called NAME, spinning until killed
  python ros_probe.py look NAME SECONDS     # exit 0 once a node NAME is discovered,
                                            # 1 if not within SECONDS

Discovery settings come from the environment (ROS_DOMAIN_ID,
ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_STATIC_PEERS), as for every node of the swarm.
"""

from __future__ import annotations

import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] not in ('serve', 'look'):
        print(__doc__, file=sys.stderr)
        return 2
    mode, name = argv[0], argv[1]
    rclpy.init()
    node = rclpy.create_node('probe_' + mode + '_' + name if mode == 'look' else name)
    try:
        if mode == 'serve':
            print(f'ros_probe: serving {name}', flush=True)
            rclpy.spin(node)
            return 0
        deadline = time.monotonic() + float(argv[2])
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.2)
            if name in node.get_node_names():
                print(f'ros_probe: {name} discovered', flush=True)
                return 0
        print(f'ros_probe: {name} not discovered in {argv[2]} s', flush=True)
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
