"""ROS helper for nodes: publishers and subscriptions without default QoS event handlers.

rclpy gives every publisher and subscription default event handlers (incompatible QoS,
incompatible type) that only log a warning. Each one is a Python ``Waitable`` that the
executor adds to its wait set and polls after every wait. The per-robot topics of a
swarm make hundreds of them: the simulator of 50 robots has about 250 publishers and
subscriptions, a composed process of 50 agents about 550. Profiled with py-spy on the
50-agent composed scenario, the executors of both processes spent 60-77 % of their time
building and polling wait sets and less than 10 % in the callbacks. Without the default
handlers the wait sets hold only the entities themselves.

What is given up: the one-line warning when a peer's QoS or type does not match. Every
swarm topic takes its profile from ``swarm_mission.qos``, so the peers agree by
construction; nodes keep the default handlers on their few swarm-wide topics.
"""

from __future__ import annotations

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks


def lean_publisher(node, msg_type, topic: str, qos, **kwargs):
    """``node.create_publisher`` without the default QoS event handlers."""
    return node.create_publisher(
        msg_type, topic, qos,
        event_callbacks=PublisherEventCallbacks(use_default_callbacks=False), **kwargs)


def lean_subscription(node, msg_type, topic: str, callback, qos, **kwargs):
    """``node.create_subscription`` without the default QoS event handlers."""
    return node.create_subscription(
        msg_type, topic, callback, qos,
        event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False), **kwargs)
