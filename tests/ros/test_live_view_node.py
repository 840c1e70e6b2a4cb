"""live_view_node in-process: the swarm's topics (shape, goals, truth, an agent's state
and routes) become the view, and a Foxglove client connected to the node's port receives
the status of that view; bad input is one line and exit 2."""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys

import pytest

rclpy = pytest.importorskip('rclpy')
websockets_client = pytest.importorskip('websockets.sync.client')

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile  # noqa: E402
from shapely.geometry import box  # noqa: E402
from spin import ros_context, spin_until  # noqa: E402

from swarm_common import qos  # noqa: E402
from swarm_common.conversions import goals_to_msg, shape_to_msg  # noqa: E402
from swarm_common.goals import Goal  # noqa: E402
from swarm_common.shapes import Shape  # noqa: E402
from swarm_msgs.msg import (  # noqa: E402
    AgentState,
    AgentTruth,
    FormationShape,
    GoalArray,
    RouteEntry,
    RouteTable,
    SwarmTruth,
)
from swarm_sim import live_view as lv  # noqa: E402
from swarm_sim.live_view_node import LiveViewNode  # noqa: E402

GOALS = [Goal(id=0, type=1, x=2.0, y=2.0, radius=0.15), Goal(id=1, type=2, x=-2.0, y=0.0,
                                                            radius=0.3)]


def _publish_swarm(probe):
    state_qos, latched = QoSProfile(**qos.STATE), QoSProfile(**qos.LATCHED)
    pubs = {
        'shape': probe.create_publisher(FormationShape, '/swarm/shape', latched),
        'goals': probe.create_publisher(GoalArray, '/swarm/goals', latched),
        'truth': probe.create_publisher(SwarmTruth, '/swarm/truth', state_qos),
        'state': probe.create_publisher(AgentState, '/agent_3/state', state_qos),
        'routes': probe.create_publisher(RouteTable, '/agent_3/routes', state_qos),
    }
    pubs['shape'].publish(shape_to_msg(Shape('square', box(-5, -5, 5, 5)), version=1))
    pubs['goals'].publish(goals_to_msg(GOALS, version=1, shape_version=1, method='bubble'))

    def again() -> None:
        pubs['truth'].publish(SwarmTruth(agents=[
            AgentTruth(id=3, type=1, alive=True, position=[1.3, 1.4]),
            AgentTruth(id=5, type=2, is_beacon=True, alive=True, position=[4.0, 0.0])]))
        pubs['state'].publish(AgentState(id=3, type=1, mode=AgentState.MODE_LOST,
                                         position=[1.0, 1.0], assigned_goal=0,
                                         goal_version=1))
        pubs['routes'].publish(RouteTable(owner=3, routes=[
            RouteEntry(destination=5, next_hop=5, hop_count=1)]))
    return again


def test_the_topics_become_the_view_a_client_receives():
    with ros_context() as (context, executor):
        node = LiveViewNode(context=context, parameter_overrides=[
            Parameter('port', value=0), Parameter('agent_ids', value=[3, 5]),
            Parameter('rate_hz', value=50.0)])
        probe = rclpy.create_node('probe', context=context)
        executor.add_node(node)
        executor.add_node(probe)
        try:
            again = _publish_swarm(probe)

            def heard() -> bool:
                again()
                view = node.view()
                return (view.shape is not None and len(view.goals) == 2
                        and set(view.links) == {(3, 5)}
                        and any(r.estimate is not None for r in view.robots)
                        and all(r.truth is not None for r in view.robots))
            assert spin_until(executor, heard, timeout=30.0)
            robots = {r.id: r for r in node.view().robots}
            assert robots[3].estimate == (1.0, 1.0) and robots[3].truth == (1.3, 1.4)
            assert (robots[3].mode, robots[3].assigned_goal) == (lv.MODE_LOST, 0)
            assert robots[3].radius == pytest.approx(0.15)                # Table 4.1 type 1
            assert robots[5].is_beacon and robots[5].mode == lv.NOT_HEARD
            assert robots[5].radius == pytest.approx(0.3)                 # Table 4.1 type 2

            # An assignment made for another goal list than the one shown is not drawn.
            stale = probe.create_publisher(AgentState, '/agent_3/state',
                                           QoSProfile(**qos.STATE))

            def dropped() -> bool:
                stale.publish(AgentState(id=3, type=1, position=[1.0, 1.0], assigned_goal=1,
                                         goal_version=2))
                (r3,) = [r for r in node.view().robots if r.id == 3]
                return r3.assigned_goal == lv.NO_GOAL
            assert spin_until(executor, dropped, timeout=30.0)
            probe.destroy_publisher(stale)

            def restored() -> bool:                  # back to the goal list shown
                again()
                (r3,) = [r for r in node.view().robots if r.id == 3]
                return r3.assigned_goal == 0
            assert spin_until(executor, restored, timeout=30.0)

            with websockets_client.connect(f'ws://127.0.0.1:{node.server.port}',
                                           subprotocols=['foxglove.sdk.v1'],
                                           open_timeout=10) as ws:
                channel = None
                while channel is None:
                    msg = json.loads(ws.recv(timeout=10))
                    if msg['op'] == 'advertise':
                        channel = next((c['id'] for c in msg['channels']
                                        if c['topic'] == lv.STATUS_TOPIC), None)
                ws.send(json.dumps({'op': 'subscribe',
                                    'subscriptions': [{'id': 7, 'channelId': channel}]}))
                expected = {'agents': 2, 'heard': 1, 'settled': 0, 'assigned': 1,
                            'links': 1, 'normal': 0, 'lost': 1, 'return_home': 0}
                status = None

                def received() -> bool:              # the latest status, while publishing
                    nonlocal status
                    if status == expected:
                        return True
                    again()
                    try:
                        frame = ws.recv(timeout=0.05)
                    except TimeoutError:
                        return False
                    if isinstance(frame, bytes) and struct.unpack_from('<I', frame, 1)[0] == 7:
                        status = json.loads(frame[13:])
                    return status == expected
                spin_until(executor, received, timeout=30.0)
            assert status == expected
        finally:
            node.close()
            node.destroy_node()
            probe.destroy_node()


def test_bad_input_is_one_line_and_exit_2():
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        for args, names in ((['-p', f'port:={port}'], f'127.0.0.1:{port}'),
                            (['-p', 'rate_hz:=0.0'], 'rate_hz'),
                            (['-p', 'fleet_file:=/nonexistent/fleet.yaml'],
                             '/nonexistent/fleet.yaml')):
            proc = subprocess.run([sys.executable, '-m', 'swarm_sim.live_view_node',
                                   '--ros-args', *args], capture_output=True, text=True,
                                  timeout=60)
            assert proc.returncode == 2, proc.stderr[-2000:]
            assert 'Traceback' not in proc.stderr + proc.stdout
            lines = [line for line in proc.stderr.splitlines() if line.strip()]
            assert len(lines) == 1 and names in lines[0], proc.stderr
