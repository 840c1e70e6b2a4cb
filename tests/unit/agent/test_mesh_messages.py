"""Mesh application messages: compact, exact round trips, malformed bytes rejected."""

import numpy as np
import pytest

from swarm_agent import wire
from swarm_agent.mesh_messages import CostRow, MeshMessageError, NeighbourInfo


def test_neighbour_info_round_trip_fits_one_xbee_frame():
    info = NeighbourInfo(agent_type=3, is_beacon=True, mode=2, position=(12.5, -40.25),
                         velocity=(0.5, -0.125), settled=True)
    data = info.encode()
    assert len(data) <= 100
    assert NeighbourInfo.decode(data) == info


def test_cost_row_quantises_to_centimetres_and_keeps_unreachable():
    costs = np.array([0.0, 1.234, 57.891, np.inf])
    row = CostRow.from_costs(7, 2, 3, 41, costs)
    back = CostRow.decode(row.encode())
    assert back == row
    np.testing.assert_allclose(back.costs[:3], [0.0, 1.23, 57.89], atol=1e-9)
    assert np.isinf(back.costs[3])
    # 20 goals of one type (the thesis swarm) fit in one frame.
    assert len(CostRow.from_costs(1, 1, 1, 1, np.ones(20)).encode()) <= wire.MAX_WHOLE


def test_narrow_rows_save_fragments_and_long_paths_stay_exact():
    """With 16-bit centimetre costs (up to 655.34 m) a row of 32 goals is one flood frame
    (14 + 64 bytes: the 78 of ``wire.MAX_WHOLE``) and the 40 goals of types 1 and 2 of a
    100-robot thesis swarm take two fragments, not three. A longer path switches the row
    to 32-bit costs, still exact to the centimetre."""
    assert len(wire.split_message(CostRow.from_costs(3, 1, 2, 9, np.ones(32)).encode(),
                                  0)) == 1
    short = np.linspace(0.0, 655.34, 40)
    short[7] = np.inf
    row = CostRow.from_costs(3, 1, 2, 9, short)
    assert len(wire.split_message(row.encode(), 0)) == 2
    assert CostRow.decode(row.encode()) == row
    long = short.copy()
    long[0] = 655.35          # 65535 cm: no longer a 16-bit cost
    wide = CostRow.from_costs(3, 1, 2, 9, long)
    back = CostRow.decode(wide.encode())
    assert back == wide and back.quantised[0] == 65535 and np.isinf(back.costs[7])
    assert len(wire.split_message(wide.encode(), 0)) == 3


@pytest.mark.parametrize('bad', [b'', b'\x01', b'\x02' + bytes(5), bytes(24)])
def test_malformed_bytes_are_rejected(bad):
    with pytest.raises(MeshMessageError):
        NeighbourInfo.decode(bad)
    with pytest.raises(MeshMessageError):
        CostRow.decode(bad)


def test_truncated_cost_row_is_rejected():
    data = CostRow.from_costs(1, 1, 1, 1, np.ones(5)).encode()
    with pytest.raises(MeshMessageError, match='must be'):
        CostRow.decode(data[:-1])


def test_non_finite_position_is_rejected():
    data = NeighbourInfo(1, False, 0, (float('nan'), 0.0), (0.0, 0.0)).encode()
    with pytest.raises(MeshMessageError, match='non-finite'):
        NeighbourInfo.decode(data)
