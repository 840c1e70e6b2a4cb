"""The live view's server (swarm_sim.foxglove_view): a Foxglove WebSocket client connects,
sees the advertised channels and receives the scene and the status."""

from __future__ import annotations

import json
import socket
import struct

import pytest

pytest.importorskip('foxglove')
websockets_client = pytest.importorskip('websockets.sync.client')

from swarm_common.goals import Goal  # noqa: E402
from swarm_sim import live_view as lv  # noqa: E402
from swarm_sim.foxglove_view import LiveViewServer, to_scene_update  # noqa: E402

# foxglove-sdk serves the Foxglove WebSocket protocol v1 under the subprotocol name
# 'foxglove.sdk.v1' (the same protocol as 'foxglove.websocket.v1', which it refuses);
# a client that speaks both, as the Foxglove app does, offers both.
SUBPROTOCOL = 'foxglove.sdk.v1'
OFFERED = ['foxglove.websocket.v1', SUBPROTOCOL]
MESSAGE_DATA = 0x01   # server -> client binary opcode (Foxglove WebSocket protocol v1)
STAMP_NS = 1_700_000_000_123_456_789


def _view() -> lv.SwarmView:
    return lv.SwarmView(goals=[Goal(id=0, type=1, x=2.0, y=2.0, radius=0.15)],
                        robots=[lv.RobotView(4, 1, 0.15, estimate=(1.0, 1.0),
                                             mode=lv.MODE_NORMAL, assigned_goal=0,
                                             settled=True)])


def test_the_scene_update_carries_every_entity():
    data = to_scene_update(lv.scene_entities(_view()), STAMP_NS).encode()
    for entity_id in (b'goals', b'agent_4', b'assignment'):
        assert entity_id in data
    assert b'map' in data


@pytest.fixture
def server():
    srv = LiveViewServer(port=0)
    yield srv
    srv.stop()


def _advertised(ws) -> dict[str, dict]:
    channels: dict[str, dict] = {}
    while {lv.SCENE_TOPIC, lv.STATUS_TOPIC} - set(channels):
        msg = json.loads(ws.recv(timeout=10))
        if msg['op'] == 'advertise':
            channels.update({c['topic']: c for c in msg['channels']})
    return channels


def test_a_client_receives_the_channels_and_the_messages(server):
    uri = f'ws://127.0.0.1:{server.port}'
    with websockets_client.connect(uri, subprotocols=OFFERED, open_timeout=10) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        channels = _advertised(ws)
        scene, status = channels[lv.SCENE_TOPIC], channels[lv.STATUS_TOPIC]
        assert (scene['schemaName'], scene['encoding']) == ('foxglove.SceneUpdate', 'protobuf')
        assert status['encoding'] == 'json'
        assert json.loads(status['schema'])['properties'].keys() == \
            lv.STATUS_SCHEMA['properties'].keys()
        assert not server.watched()          # connected, subscribed to nothing yet
        ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
            {'id': 1, 'channelId': scene['id']}, {'id': 2, 'channelId': status['id']}]}))
        got: dict[int, tuple[int, bytes]] = {}
        for _ in range(50):          # the subscription is served once the server has it
            server.publish(_view(), STAMP_NS)
            try:
                frame = ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            while True:
                if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
                    sub, log_time = struct.unpack_from('<IQ', frame, 1)
                    got[sub] = (log_time, frame[13:])
                try:
                    frame = ws.recv(timeout=0.2)
                except TimeoutError:
                    break
            if set(got) == {1, 2}:
                break
        assert server.watched()
    assert set(got) == {1, 2}
    assert got[1][0] == STAMP_NS and b'agent_4' in got[1][1]
    assert json.loads(got[2][1]) == lv.status(_view())
    assert json.loads(got[2][1])['settled'] == 1


def test_a_port_that_is_taken_is_named_in_one_line():
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(OSError) as err:
            LiveViewServer(port=port)
    text = str(err.value)
    assert f'127.0.0.1:{port}' in text and 'port:=' in text and '\n' not in text
