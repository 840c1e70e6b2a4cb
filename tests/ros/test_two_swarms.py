"""Two swarms side by side in one ROS domain, each under its own namespace, no crosstalk.

Each swarm is a world (``sim_node``, point masses), a ``mission_node`` and its agents,
in one rclpy context whose global arguments are the launch plan's for its namespace
(``swarm_bringup.launch_plan.scoped``: ``__ns`` and the remappings of ``/clock`` and
``/tf``), as ``ros_arguments`` gives every process of a namespaced run. Swarm A runs
three ``agent_node`` nodes (ids 0-2), swarm B one ``composed_node`` of four (ids 10-13),
so both modes are in the test. The names the nodes use are all relative, so:

- nothing of either swarm is outside its namespace (no ``/radio/tx``, ``/swarm/goals``,
  ``/clock`` or ``/tf`` at the root), and each swarm's radio, goals and clock topics
  have only that swarm's nodes on them;
- each agent knows only its own swarm: its goal list has its mission's goal count (3 or
  4), its DSDV table and the cost rows of its assignment only its own swarm's ids;
- both worlds advance and both swarms agree on an assignment of every agent to a goal;
- the composed swarm still publishes each robot's ``agent_K/state`` and ``agent_K/odom``.
"""

from __future__ import annotations

import time

import pytest

rclpy = pytest.importorskip('rclpy')

from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402

from swarm_agent.agent_node import AgentNode  # noqa: E402
from swarm_agent.composed_node import ComposedAgents  # noqa: E402
from swarm_bringup.launch_plan import NodeSpec, ros_arguments, scoped, SwarmRun  # noqa: E402
from swarm_common import qos  # noqa: E402
from swarm_common.fleet import RobotSpec, save_fleet  # noqa: E402
from swarm_mission.mission_node import MissionNode  # noqa: E402
from swarm_msgs.msg import AgentState  # noqa: E402
from swarm_sim.sim_node import SimNode  # noqa: E402

SIM_SECONDS = 12.0   # both worlds' time at the end: past the first consensus rounds
WALL_LIMIT_S = 240.0

FLEETS = {
    '/swarm_a': [RobotSpec(0, 1, True, -4.0, -3.0), RobotSpec(1, 1, True, 4.0, -3.0),
                 RobotSpec(2, 2, True, 0.0, 4.0)],
    '/swarm_b': [RobotSpec(10, 1, True, -4.0, -3.0), RobotSpec(11, 1, True, 4.0, -3.0),
                 RobotSpec(12, 2, True, 0.0, 4.0), RobotSpec(13, 2, False, 1.0, 1.0)],
}


def _context(namespace: str, fleet_file: str) -> rclpy.Context:
    """A context with the global ROS arguments of a process of the namespaced plan."""
    run = SwarmRun(fleet_file=fleet_file, shape='', namespace=namespace)
    args = ros_arguments(NodeSpec('swarm_sim', 'sim_node', 'sim', **scoped(run)))
    assert args[:3] == ['--ros-args', '-r', f'__ns:={namespace}']
    context = rclpy.Context()
    rclpy.init(args=['test', *args], context=context)
    return context


def _swarm(namespace: str, tmp_path, shape: str) -> dict:
    fleet = FLEETS[namespace]
    fleet_file = tmp_path / f'{namespace.strip("/")}.yaml'
    save_fleet(fleet_file, fleet)
    context = _context(namespace, str(fleet_file))
    executor = SingleThreadedExecutor(context=context)
    composed = namespace == '/swarm_b'
    sim_time = Parameter('use_sim_time', value=True)
    sim = SimNode(context=context, parameter_overrides=[
        Parameter('fleet_file', value=str(fleet_file)), Parameter('backend', value='pointmass'),
        Parameter('real_time_factor', value=0.0), Parameter('half_size', value=15.0),
        Parameter('sensor_batch', value=composed)])
    mission = MissionNode(context=context, parameter_overrides=[
        sim_time, Parameter('shape', value=shape),
        Parameter('fleet_file', value=str(fleet_file))])
    nodes = [sim, mission]
    if composed:
        container = ComposedAgents(executor, context=context, parameter_overrides=[
            sim_time, Parameter('fleet_file', value=str(fleet_file)),
            Parameter('sensor_batch', value=True), Parameter('status_log_period_s', value=0.0)])
        nodes.append(container)
        agents = list(container.agents.values())
    else:
        agents = [AgentNode(f'agent_{r.id}', context=context, parameter_overrides=[
            sim_time, Parameter('agent_id', value=r.id), Parameter('agent_type', value=r.type),
            Parameter('is_beacon', value=r.is_beacon), Parameter('initial_x', value=r.x),
            Parameter('initial_y', value=r.y), Parameter('seed', value=r.id),
            Parameter('status_log_period_s', value=0.0)]) for r in fleet]
        nodes += agents
    for node in nodes:
        if node not in agents or not composed:
            executor.add_node(node)
    return {'context': context, 'executor': executor, 'sim': sim, 'agents': agents,
            'nodes': nodes, 'ids': {r.id for r in fleet}, 'fleet': fleet}


def test_two_namespaced_swarms_share_a_domain_without_crosstalk(tmp_path):
    square = tmp_path / 'square.json'
    square.write_text('{"outer": [[-3, -3], [3, -3], [3, 3], [-3, 3]]}')
    swarms = {ns: _swarm(ns, tmp_path, str(square)) for ns in FLEETS}
    b = swarms['/swarm_b']
    # A probe in swarm B's namespace: the composed agents' own state and odom topics.
    probe = rclpy.create_node('probe', context=b['context'])
    b['executor'].add_node(probe)
    heard: dict[str, set[int]] = {'state': set(), 'odom': set()}
    for r in b['fleet']:
        probe.create_subscription(AgentState, f'agent_{r.id}/state',
                                  lambda m: heard['state'].add(m.id), QoSProfile(**qos.STATE))
        probe.create_subscription(Odometry, f'agent_{r.id}/odom',
                                  lambda m, k=r.id: heard['odom'].add(k), QoSProfile(**qos.STATE))
    try:
        deadline = time.monotonic() + WALL_LIMIT_S
        while min(s['sim'].world.t for s in swarms.values()) < SIM_SECONDS \
                and time.monotonic() < deadline:
            for swarm in swarms.values():
                swarm['executor'].spin_once(timeout_sec=0.005)
        times = {ns: round(s['sim'].world.t, 1) for ns, s in swarms.items()}
        assert min(times.values()) >= SIM_SECONDS, f'worlds reached only {times} s'

        # Every topic of the graph is a swarm's own or ROS's global log and events.
        topics = {name for name, _ in probe.get_topic_names_and_types()}
        outside = sorted(t for t in topics if not t.startswith(('/swarm_a/', '/swarm_b/'))
                         and t not in ('/rosout', '/parameter_events'))
        assert outside == [], outside
        for ns in FLEETS:
            for topic in ('radio/tx', 'swarm/goals', 'clock', 'tf'):
                publishers = probe.get_publishers_info_by_topic(f'{ns}/{topic}')
                assert publishers, f'{ns}/{topic} has no publisher'
                assert {p.node_namespace for p in publishers} == {ns}, (ns, topic)
            radio_readers = probe.get_subscriptions_info_by_topic(f'{ns}/radio/tx')
            assert {p.node_namespace for p in radio_readers} == {ns}

        for ns, swarm in swarms.items():
            n = len(swarm['fleet'])
            for node in swarm['agents']:
                brain = node.brain
                # Its own mission's goals (3 or 4 robots, as many goals).
                assert len(brain.goals) == n, (ns, brain.config.agent_id, len(brain.goals))
                # Only its own swarm on the radio: routes and cost rows.
                routed = {route.destination for route in brain.router.routes()}
                assert routed <= swarm['ids'], (ns, brain.config.agent_id, routed)
                assert brain.goal_id != -1, (ns, brain.config.agent_id)
            for agent_type in (1, 2):
                group = [node.brain for node in swarm['agents']
                         if node.brain.config.agent_type == agent_type]
                assert {br.rows_used for br in group} == {len(group)}, ns
                assert len({br.assignment_digest for br in group}) == 1, ns
        assert heard == {'state': b['ids'], 'odom': b['ids']}
    finally:
        for swarm in swarms.values():
            swarm['executor'].shutdown()
            for node in swarm['nodes']:
                if isinstance(node, SimNode):
                    node.close()
                node.destroy_node()
            rclpy.try_shutdown(context=swarm['context'])
