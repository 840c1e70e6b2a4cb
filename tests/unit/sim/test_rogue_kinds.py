"""The rogue transmitters of ``swarm_sim.rogue``: what each sends, how the authenticated
receivers count it, and what it does to a swarm with and without authentication.

Frame level: a receiver (``FrameAuth`` under the development key) that has heard a
source's genuine frames rejects the rogue's forgeries as ``auth_bad_tag`` (a tag of
zeros matches HMAC-SHA256 truncated to 8 bytes with probability 2**-64), its verbatim
replays as ``auth_replay`` while the counter is inside the window of 64 and as
``auth_too_old`` once the source has sealed 64 newer frames.

Swarm level: 12 robots enter the 8 m square in +/-8 m (every pair within the 25 m radio
range and no loss, so every robot heard every genuine frame a replay copies). With
authentication each rogue from t = 2 s leaves the run equal to the clean run in every
recorded number (the rogue draws nothing from the medium's random stream). Without it,
forged cost rows (from t = 0) of phantom agents at 0 m from every goal take every goal
in the Hungarian assignment (it minimises the summed cost; thesis 3.2.2.2): no real
agent is ever assigned, so every robot stays where it was placed.
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

from swarm_agent.agent_factory import swarm_keyring
from swarm_agent.frame_auth import FrameAuth, WINDOW
from swarm_agent.mesh_messages import CostRow
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_agent.wire import (
    decode_routed,
    encode_heartbeat,
    encode_routed,
    parse_chunk,
    split_message,
)
from swarm_common.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario
from swarm_sim.rogue import (
    check_rogue,
    FloodFrames,
    ForgedCostRows,
    make_rogue,
    PHANTOM_BASE,
    ReplayFrames,
    ROGUE_KINDS,
)

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'


def _auth() -> FrameAuth:
    return FrameAuth(swarm_keyring(None), clock=lambda: 1000.0)


def _heartbeat(sender: FrameAuth, source: int, k: int) -> Packet:
    return sender.seal(Packet(source, BROADCAST, int(Kind.HEARTBEAT), k, 1,
                              encode_heartbeat(k, b'info')))


def test_forged_cost_rows_copy_the_round_and_are_bad_tags_to_a_receiver():
    sender, receiver = _auth(), _auth()
    row = CostRow.from_costs(7, 2, goal_version=3, round_=11, costs=np.array([4.0, 5.5, 9.0]))
    genuine = sender.seal(Packet(7, BROADCAST, int(Kind.FLOOD), 1, 32, encode_routed(
        7, 1, split_message(row.encode(), 0)[0])))
    assert receiver.open(genuine) is not None
    rogue = ForgedCostRows()
    rogue.overhear(0.5, genuine)
    rogue.overhear(0.6, genuine)                   # a round is forged once
    forged = rogue.frames(0.6)
    assert len(forged) == 3 and rogue.frames_sent == 3   # one phantom per goal
    for k, packet in enumerate(forged):
        assert receiver.open(packet) is None
        origin, _, chunk = decode_routed(packet.payload[:-17])
        phantom = CostRow.decode(parse_chunk(chunk)[0])
        assert origin == packet.source == phantom.agent_id == PHANTOM_BASE + k
        assert (phantom.agent_type, phantom.goal_version, phantom.round) == (2, 3, 11)
        assert phantom.quantised == (0, 0, 0)
    assert receiver.stats == {'auth_bad_tag': 3}
    assert rogue.frames(0.7) == []


def test_replays_are_verbatim_and_counted_as_replays_then_too_old():
    sender, receiver = _auth(), _auth()
    rogue = ReplayFrames(delay_s=2.0)
    frames = [_heartbeat(sender, 5, k) for k in range(WINDOW + 10)]
    for k, packet in enumerate(frames[:10]):
        assert receiver.open(packet) is not None
        rogue.overhear(0.1 * k, packet)
    assert rogue.frames(2.0) == frames[:1]        # captured at 0.0, 2 s later
    replayed = rogue.frames(3.0)
    assert replayed[0] is frames[1] and len(replayed) == 9
    assert all(receiver.open(p) is None for p in [frames[0], *replayed])
    assert receiver.stats == {'auth_replay': 10}
    for packet in frames[10:]:                    # the source moves WINDOW frames on
        receiver.open(packet)
    assert receiver.open(frames[0]) is None
    assert receiver.stats == {'auth_replay': 10, 'auth_too_old': 1}


def test_a_flood_sends_ten_frames_for_each_heard_half_replays_half_bad_tags():
    sender, receiver = _auth(), _auth()
    rogue = FloodFrames()
    for k in range(3):
        packet = _heartbeat(sender, 5, k)
        assert receiver.open(packet) is not None
        rogue.overhear(0.0, packet)
    out = rogue.frames(0.02)
    assert len(out) == 30 and rogue.frames_sent == 30
    assert all(receiver.open(p) is None for p in out)
    assert receiver.stats == {'auth_replay': 15, 'auth_bad_tag': 15}


def test_the_rogue_setting_names_a_kind_or_says_which_exist():
    assert [make_rogue(k, [3, 4]).__class__.__name__ for k in ROGUE_KINDS] == [
        'ForgedAdverts', 'ForgedCostRows', 'ReplayFrames', 'FloodFrames']
    assert check_rogue(0) == 0.0 and check_rogue(4.0) == 4.0
    for bad in (2.5, 5, -1):
        with pytest.raises(ValueError, match='1 adverts, 2 costs, 3 replay, 4 flood'):
            check_rogue(bad)
    with pytest.raises(ValueError, match='unknown rogue'):
        make_rogue('jam', [1])


def _run(auth: bool, kind: str | None, start_s: float = 2.0
         ) -> tuple[HeadlessSwarm, object]:
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 5, 2: 4, 3: 3},
                        n_beacons=3, half_size=8.0, seed=1, duration_s=20.0,
                        settle_hold_s=20.0, auth=auth)
    swarm = HeadlessSwarm(scenario)
    if kind is not None:
        scenario.rogues = [make_rogue(kind, swarm.ids, trailer=auth, start_s=start_s)]
    return swarm, swarm.run()


@pytest.fixture(scope='module')
def clean():
    return _run(True, None)[1]


@pytest.mark.parametrize('kind, rejections', [('costs', {'auth_bad_tag'}),
                                              ('replay', {'auth_replay'}),
                                              ('flood', {'auth_bad_tag', 'auth_replay'})])
def test_with_authentication_a_rogue_changes_nothing(clean, kind, rejections):
    swarm, attacked = _run(True, kind)
    rogue = swarm.scenario.rogues[0]
    rejected = attacked.metrics['frames_rejected']
    assert set(rejected) == rejections
    # Each frame reaches the 12 robots and the mission's radio; its source (a replay's,
    # a flood copy's) ignores nothing, the other 11 robots reject it.
    assert sum(rejected.values()) >= 11 * rogue.frames_sent > 0
    for key in ('positions', 'estimates', 'goal_ids', 'digests', 'modes'):
        np.testing.assert_array_equal(getattr(attacked, key), getattr(clean, key), key)
    assert attacked.metrics['medium'] == clean.metrics['medium']


def test_without_authentication_phantom_cost_rows_take_every_goal(clean):
    assert clean.metrics['fraction_inside'] == 1.0 and (clean.goal_ids[-1] >= 0).all()
    swarm, attacked = _run(False, 'costs', start_s=0.0)
    assert swarm.scenario.rogues[0].frames_sent >= 12    # a row per goal and round
    assert (attacked.goal_ids == -1).all()               # nobody assigned, ever
    moved = np.hypot(*(attacked.positions[-1] - attacked.positions[0]).T)
    assert moved.max() < 0.5                             # parked where placed
    assert attacked.metrics['fraction_inside'] < 0.75


def test_the_world_runs_the_rogue_setting_as_sim_node_does():
    """sim_node's run-time parameter ``rogue`` (World.apply_setting): the rogue hears the
    medium's deliveries and its frames join the next deliveries, to every living robot."""
    swarm = HeadlessSwarm(Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 3},
                                   n_beacons=3, half_size=4.0))
    world = swarm.world
    world.rogue_trailer = False               # sim_node's rogue_trailer: agents without auth
    for _ in range(5):
        world.step()
        world.sense()
    world.apply_setting('rogue', 3.0)
    (rogue,) = world.rogues
    assert isinstance(rogue, ReplayFrames) and not rogue.trailer
    assert rogue.start_s == pytest.approx(world.t)
    frame = Packet(swarm.ids[0], BROADCAST, int(Kind.HEARTBEAT), 1, 1, b'beat')
    sent_at = world.t
    world.medium.transmit(sent_at, frame)
    replays = []
    while world.t < sent_at + 2.5:
        world.step()
        readings = world.sense()
        if readings.rogue:
            replays.append((readings.t, readings.rogue,
                            [d for d in readings.rx if d[1] in readings.rogue]))
    ((t, frames, deliveries),) = replays
    assert frames == [frame] and 2.0 <= t - sent_at <= 2.0 + 0.05   # one step's slack
    assert deliveries == [(t, frame, list(swarm.ids))]
    world.apply_setting('rogue', 0.0)
    assert world.rogues == []
    with pytest.raises(ValueError, match='rogue must be 0'):
        world.apply_setting('rogue', 2.5)


def test_sim_node_parameters_start_a_rogue_or_name_the_bad_value(tmp_path):
    from swarm_common.fleet import RobotSpec, save_fleet
    from swarm_sim.sim_parameters import SIM_PARAMETERS, world_from_parameters

    save_fleet(tmp_path / 'fleet.yaml', [RobotSpec(i, 1, i < 3, 2.0 * i, 0.0)
                                         for i in range(4)])
    params = {name: spec.default for name, spec in SIM_PARAMETERS.items()}
    params.update(fleet_file=str(tmp_path / 'fleet.yaml'), backend='pointmass')
    assert world_from_parameters(params)[2].rogues == []
    params.update(rogue=2.0, rogue_trailer=False)
    (rogue,) = world_from_parameters(params)[2].rogues
    assert isinstance(rogue, ForgedCostRows) and not rogue.trailer
    params['rogue'] = 1.5
    with pytest.raises(ValueError, match='rogue must be 0'):
        world_from_parameters(params)
