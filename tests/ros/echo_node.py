"""Test helper process: echo every swarm_msgs message type and serve SetShape.

Subscribes ``echo_in/<Type>`` for every message type of swarm_msgs and republishes the
received message unchanged on ``echo_out/<Type>``; answers ``set_shape`` with the
received shape's name and a version derived from it.
"""

from __future__ import annotations

import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, QoSReliabilityPolicy

import swarm_msgs.msg
from swarm_msgs.srv import SetShape

QOS = QoSProfile(depth=10, reliability=QoSReliabilityPolicy.RELIABLE,
                 durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)


def message_types() -> list[str]:
    """Names of every message class in swarm_msgs."""
    return sorted(n for n in dir(swarm_msgs.msg)
                  if not n.startswith('_') and hasattr(getattr(swarm_msgs.msg, n),
                                                       'get_fields_and_field_types'))


class EchoNode(Node):
    """Republish what arrives; see the module docstring."""

    def __init__(self) -> None:
        super().__init__('swarm_msgs_echo')
        self._pubs = {}
        self._subs = []
        for name in message_types():
            cls = getattr(swarm_msgs.msg, name)
            self._pubs[name] = self.create_publisher(cls, f'echo_out/{name}', QOS)
            self._subs.append(self.create_subscription(
                cls, f'echo_in/{name}', lambda m, n=name: self._pubs[n].publish(m), QOS))
        self._srv = self.create_service(SetShape, 'set_shape', self._on_set_shape)

    def _on_set_shape(self, request, response):
        response.success = len(request.shape.outer.x) >= 3
        response.message = 'echo:' + request.shape.name
        response.version = request.shape.version + 1
        return response


def main(args=None) -> None:
    rclpy.init(args=args)
    node = EchoNode()
    print('echo ready', flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main(sys.argv)
