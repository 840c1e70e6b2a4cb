"""Publishers and subscriptions without rclpy's default QoS event handlers.

Not a node module: the nodes of every package (agent_node, composed_node, sim_node,
monitor_node, the launcher's supervisor) import these helpers from here.
"""

from __future__ import annotations

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks


def lean_publisher(node, msg_type, topic: str, qos_profile, **kwargs):
    """``node.create_publisher`` without rclpy's default QoS event handlers.

    rclpy gives every publisher and subscription default event handlers (incompatible
    QoS, incompatible type) that only log a warning; each is a Python waitable the
    executor adds to its wait set and polls after every wait. The per-robot topics of a
    swarm make hundreds of them (about 550 in a composed process of 50 agents, 250 in
    the simulator): profiled with py-spy on the 50-agent composed scenario, both
    executors spent 60-77 % of their time on wait sets and under 10 % in callbacks.
    What is given up: the warning when a peer's QoS or type does not match; every swarm
    topic takes its profile from ``swarm_mission.qos``, so peers agree by construction.
    """
    return node.create_publisher(
        msg_type, topic, qos_profile,
        event_callbacks=PublisherEventCallbacks(use_default_callbacks=False), **kwargs)


def lean_subscription(node, msg_type, topic: str, callback, qos_profile, **kwargs):
    """``node.create_subscription`` without the default QoS event handlers (see
    ``lean_publisher``)."""
    return node.create_subscription(
        msg_type, topic, callback, qos_profile,
        event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False), **kwargs)
