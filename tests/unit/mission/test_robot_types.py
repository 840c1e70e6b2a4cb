"""Robot type table: Table 4.1 values and clear errors."""

import pytest

from swarm_common.robot_types import (
    default_type_counts,
    load_robot_types,
    parse_type_counts,
    robot_type,
    RobotTypeError,
)


def test_table_4_1_values():
    types = load_robot_types()
    assert sorted(types) == [1, 2, 3]
    assert [types[t].mass for t in (1, 2, 3)] == [0.8, 1.0, 1.5]
    assert [types[t].coverage_radius for t in (1, 2, 3)] == [0.15, 0.3, 0.5]
    assert types[2].dry_friction == 0.18 and types[3].fluid_friction == 0.13


def test_unknown_type_names_known_ids():
    with pytest.raises(RobotTypeError, match=r'unknown robot type 7.*\[1, 2, 3\]'):
        robot_type(load_robot_types(), 7)


def test_type_counts():
    assert parse_type_counts('1:20,2:20,3:10') == {1: 20, 2: 20, 3: 10}
    assert default_type_counts(50) == {1: 20, 2: 20, 3: 10}
    assert sum(default_type_counts(13).values()) == 13
    with pytest.raises(RobotTypeError, match='TYPE:COUNT'):
        parse_type_counts('1-20')
    with pytest.raises(RobotTypeError):
        default_type_counts(0)
