"""Every parameter a node lists can be read back through its parameter services, as
``ros2 param dump`` reads them: list_parameters, then get_parameters of all the names.

rclpy answers a get_parameters request that names a parameter declared without a value
(a type only) with no values at all, so such a parameter empties the whole dump. The
composed container (``agent_ids``) and the recorder (``topics``, ``exclude``) declare
their optional lists read-only, the empty list unless given; an empty ``agent_ids`` runs
the whole fleet.
"""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip('rclpy')

from rcl_interfaces.msg import ParameterType  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.parameter_client import AsyncParameterClient  # noqa: E402
from spin import ros_context, spin_until  # noqa: E402

from swarm_agent.agent_node import make_executor  # noqa: E402
from swarm_agent.composed_node import ComposedAgents  # noqa: E402
from swarm_bringup.recorder_node import RecorderNode  # noqa: E402
from swarm_common.fleet import RobotSpec, save_fleet  # noqa: E402

ROBOTS = [RobotSpec(0, 1, True, 0.0, 0.0), RobotSpec(1, 2, False, 5.0, 0.0)]


def _dump(executor, probe, node_name: str) -> tuple[list[str], list]:
    """(names, values) of ``node_name`` read as ``ros2 param dump`` reads them."""
    client = AsyncParameterClient(probe, node_name)
    assert spin_until(executor, client.services_are_ready), f'no services of {node_name}'
    listed = client.list_parameters()
    assert spin_until(executor, listed.done)
    names = sorted(listed.result().result.names)
    got = client.get_parameters(names)
    assert spin_until(executor, got.done)
    return names, list(got.result().values)


def test_the_composed_container_and_the_recorder_dump_every_parameter(tmp_path):
    fleet_file = tmp_path / 'fleet.yaml'
    save_fleet(fleet_file, ROBOTS)
    with ros_context(make_executor) as (context, executor):
        container = ComposedAgents(executor, context=context, parameter_overrides=[
            Parameter('fleet_file', value=str(fleet_file))])
        recorder = RecorderNode(context=context, parameter_overrides=[
            Parameter('output', value=str(tmp_path / 'run.mcap'))])
        probe = rclpy.create_node('probe', context=context)
        for node in (container, recorder, probe):
            executor.add_node(node)
        try:
            assert sorted(container.agents) == [0, 1], 'empty agent_ids: the whole fleet'
            for name, lists in (('/agents_container', {'agent_ids'}),
                                ('/recorder', {'topics', 'exclude'})):
                names, values = _dump(executor, probe, name)
                assert lists <= set(names)
                assert len(values) == len(names), \
                    f'{name}: {len(names)} parameters listed, {len(values)} values read'
                unset = [n for n, v in zip(names, values)
                         if v.type == ParameterType.PARAMETER_NOT_SET]
                assert not unset, f'{name}: declared without a value: {unset}'
            assert list(container.get_parameter('agent_ids').value) == []
            assert recorder.only == set() and recorder.exclude == set()
            # Read at start only, so read-only: a change would be accepted and ignored.
            for node, name, value in ((container, 'agent_ids', [0]),
                                      (recorder, 'topics', ['/clock'])):
                result = node.set_parameters([Parameter(name, value=value)])[0]
                assert not result.successful and 'read-only' in result.reason
        finally:
            container.destroy_all()
            for node in (container, recorder, probe):
                node.destroy_node()


def test_agent_ids_given_run_only_those_agents(tmp_path):
    fleet_file = tmp_path / 'fleet.yaml'
    save_fleet(fleet_file, ROBOTS)
    with ros_context(make_executor) as (context, executor):
        container = ComposedAgents(executor, context=context, parameter_overrides=[
            Parameter('fleet_file', value=str(fleet_file)),
            Parameter('agent_ids', value=[1])])
        try:
            assert sorted(container.agents) == [1]
            assert list(container.get_parameter('agent_ids').value) == [1]
        finally:
            container.destroy_all()
            container.destroy_node()
