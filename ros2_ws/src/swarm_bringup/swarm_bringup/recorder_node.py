"""Record a run's ROS topics into an MCAP bag (swarm_bringup.bag), as they are published.

  python -m swarm_bringup.recorder_node --ros-args -p output:=results/demo/run.mcap \\
      -p use_sim_time:=true [-p topics:='[/swarm/goals,/agent_0/state]'] \\
      [-p exclude:='[/swarm/sensor_batch]']

Every ``discovery_period_s`` (wall time) the node looks at the graph and subscribes to
each topic it has not yet subscribed to (all topics, or those of ``topics``, less those
of ``exclude``; started in a namespace, e.g. ``/swarm_a``, only the topics under it, a
run's own when swarms share a domain) as raw CDR bytes (``raw=True``: no
deserialization), with the swarm's QoS profile of the topic made compatible with its
publishers (``bag.recording_qos``; transient local for the latched ``/swarm/shape`` and
``/swarm/goals``). A message's log and publish time is the node clock's time when it
arrives: sim time under ``use_sim_time``. The bag's open chunk is written out at least
every ``flush_period_s`` (wall time), so a killed recorder loses at most that; Ctrl-C
(SIGINT) closes the bag with its summary. A topic carrying several types or a type
without an installed ``.msg`` is skipped with one warning. Its executor waits at most
every 20 ms (``BatchingExecutor``): CPU time per message 0.31 ms instead of 0.60 with 12
composed agents (66 topics), but still 0.79 ms with 50 (223 topics; 0.83 without
batching), so about a third of a core in ``make demo`` (docs/recording.md).

Subscribes: every recorded topic. Publishes: nothing (besides rclpy's own).
"""

from __future__ import annotations

import importlib
import time

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.executors import SingleThreadedExecutor
import rclpy.logging
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile

from swarm_bringup.bag import BagError, BagWriter, FLUSH_PERIOD_S, recording_qos
from swarm_common.ros_support import declare_list_parameter, run_node

EXAMPLE_OUTPUT = 'results/demo/run.mcap'
BATCH_S = 0.02   # the least wall time between two waits of the executor


def message_class(type_name: str):
    """The Python class of ``pkg/msg/Type`` from its installed package."""
    package, _, name = type_name.split('/')
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except (ImportError, AttributeError):
        raise BagError(f'message type {type_name}: no Python class installed') from None


def _topic_list(value, name: str) -> list[str]:
    topics = list(value or [])
    bad = [t for t in topics if not t.startswith('/') or t.endswith('/') or ' ' in t]
    if bad:
        raise ValueError(f'parameter {name}: {bad[0]!r} is not an absolute topic name; '
                         f"write e.g. {name}:='[/swarm/goals,/agent_0/state]'")
    return topics


class RecorderNode(Node):
    """Subscribes to the graph's topics and writes what arrives into one bag."""

    def __init__(self, **kwargs) -> None:
        super().__init__('recorder', **kwargs)
        positive = FloatingPointRange(from_value=0.01, to_value=3600.0)
        self.declare_parameter('output', '', ParameterDescriptor(
            description=f'path of the MCAP bag to write, e.g. {EXAMPLE_OUTPUT}',
            read_only=True))
        topics = declare_list_parameter(self, 'topics', Parameter.Type.STRING_ARRAY,
                               'absolute names of the topics to record (empty: all)')
        exclude = declare_list_parameter(self, 'exclude', Parameter.Type.STRING_ARRAY,
                                'absolute names of topics not to record')
        self.declare_parameter('flush_period_s', FLUSH_PERIOD_S, ParameterDescriptor(
            description='wall seconds between flushes of the bag (the most a crash loses)',
            floating_point_range=[positive], read_only=True))
        self.declare_parameter('discovery_period_s', 1.0, ParameterDescriptor(
            description='wall seconds between looks for new topics',
            floating_point_range=[positive], read_only=True))
        output = self.get_parameter('output').value
        if not output:
            raise ValueError(f'parameter output is empty; give the bag path, e.g. '
                             f'-p output:={EXAMPLE_OUTPUT}')
        self.only = set(_topic_list(topics, 'topics'))
        self.exclude = set(_topic_list(exclude, 'exclude'))
        self.bag = BagWriter(output, self.get_parameter('flush_period_s').value)
        self.subscriptions_by_topic: dict[str, object] = {}
        self.skipped: set[str] = set()
        # Wall-clock timers: flushing and discovery go on while sim time stands still.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(min(0.25, self.bag.flush_period_s), self.bag.flush_if_due,
                          clock=steady)
        self.create_timer(self.get_parameter('discovery_period_s').value, self.discover,
                          clock=steady)
        self.get_logger().info(f'recording {"all topics" if not self.only else sorted(self.only)}'
                               f' into {output}')

    def discover(self) -> None:
        """Subscribe to every wanted topic not yet recorded that has a publisher (in a
        namespace, only the topics under it: another swarm's are not this run's)."""
        scope = self.get_namespace().rstrip('/') + '/'
        for topic, types in self.get_topic_names_and_types():
            if not topic.startswith(scope) or \
                    topic in self.subscriptions_by_topic or topic in self.skipped or \
                    topic in self.exclude or (self.only and topic not in self.only):
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue   # only subscribers so far: the publisher's QoS is not known
            if len(types) != 1:
                self._skip(topic, f'it carries several types {types}')
                continue
            try:
                msg_type = message_class(types[0])
                self.bag.add_topic(topic, types[0])
            except BagError as exc:
                self._skip(topic, str(exc))
                continue
            offers = [(int(p.qos_profile.reliability), int(p.qos_profile.durability))
                      for p in publishers]
            self.subscriptions_by_topic[topic] = self.create_subscription(
                msg_type, topic, lambda data, t=topic: self.on_message(t, data),
                QoSProfile(**recording_qos(topic, offers)), raw=True)

    def _skip(self, topic: str, why: str) -> None:
        self.skipped.add(topic)
        self.get_logger().warning(f'not recording {topic}: {why}')

    def on_message(self, topic: str, data: bytes) -> None:
        self.bag.write(topic, data, self.get_clock().now().nanoseconds)

    def close(self) -> None:
        """Close the bag (summary and indexes written)."""
        if not self.bag.closed:
            self.bag.close()
            total = sum(self.bag.counts.values())
            # Not the node's logger: after Ctrl-C its /rosout publisher is gone.
            rclpy.logging.get_logger('recorder_node').info(
                f'wrote {total} messages of {len(self.bag.counts)} topics into '
                f'{self.bag.path}')


class BatchingExecutor(SingleThreadedExecutor):
    """A SingleThreadedExecutor that waits at most once per ``batch_s``.

    Each wait rebuilds a wait set of every subscription (about 3 ms for 200 of them,
    profiled), and at a few hundred messages a second each wait found about one: the
    recorder spent that per message. Pausing up to ``batch_s`` before a wait lets the
    messages of every topic gather in their queues (each profile's depth holds
    ``batch_s`` of its rate), so one wait serves many.
    """

    def __init__(self, batch_s: float = BATCH_S, **kwargs) -> None:
        super().__init__(**kwargs)
        self.batch_s = batch_s
        self._next_wait = 0.0

    def _wait_for_ready_callbacks(self, *args, **kwargs):
        pause = self._next_wait - time.monotonic()
        if pause > 0.0:
            time.sleep(pause)
        self._next_wait = time.monotonic() + self.batch_s
        yield from super()._wait_for_ready_callbacks(*args, **kwargs)


def main(args=None) -> None:
    run_node(lambda: RecorderNode(), 'recorder_node', args, executor=BatchingExecutor,
             stop=RecorderNode.close)


if __name__ == '__main__':
    main()
