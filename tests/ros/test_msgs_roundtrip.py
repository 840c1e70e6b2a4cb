"""Two processes exchange every swarm_msgs type; every field must survive the trip."""

from __future__ import annotations

import pathlib
import random
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from msg_fill import as_plain, fill  # noqa: E402

import swarm_msgs.msg  # noqa: E402
from swarm_msgs.msg import FormationShape  # noqa: E402
from swarm_msgs.srv import SetShape  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent


def _types() -> list[str]:
    return sorted(n for n in dir(swarm_msgs.msg)
                  if not n.startswith('_')
                  and hasattr(getattr(swarm_msgs.msg, n), 'get_fields_and_field_types'))


def test_every_message_type_round_trips_between_processes(processes):
    from echo_node import QOS

    names = _types()
    assert {'RadioPacket', 'RouteTable', 'AgentState', 'GoalArray', 'FormationShape',
            'RangeArray', 'SwarmTruth'} <= set(names)
    echo = processes.python(str(HERE / 'echo_node.py'))
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('roundtrip_tester', context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        rng = random.Random(7)
        sent = {n: fill(getattr(swarm_msgs.msg, n)(), rng) for n in names}
        got: dict[str, object] = {}
        pubs = {n: node.create_publisher(getattr(swarm_msgs.msg, n), f'echo_in/{n}', QOS)
                for n in names}
        subs = [node.create_subscription(getattr(swarm_msgs.msg, n), f'echo_out/{n}',
                                         lambda m, n=n: got.__setitem__(n, m), QOS)
                for n in names]
        assert subs
        deadline = time.monotonic() + 60.0
        while len(got) < len(names) and time.monotonic() < deadline:
            assert echo.poll() is None, 'echo process died'
            for n in names:
                if n not in got:
                    pubs[n].publish(sent[n])
            executor.spin_once(timeout_sec=0.2)
        assert set(got) == set(names), f'never echoed: {sorted(set(names) - set(got))}'
        for n in names:
            assert as_plain(got[n]) == as_plain(sent[n]), f'{n} changed in transit'

        client = node.create_client(SetShape, 'set_shape')
        assert client.wait_for_service(timeout_sec=30.0)
        request = SetShape.Request(shape=fill(FormationShape(), rng))
        request.shape.outer.x = [0.0, 1.0, 1.0]
        request.shape.outer.y = [0.0, 0.0, 1.0]
        future = client.call_async(request)
        executor.spin_until_future_complete(future, timeout_sec=30.0)
        response = future.result()
        assert response is not None
        assert response.success
        assert response.message == 'echo:' + request.shape.name
        assert response.version == request.shape.version + 1
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
