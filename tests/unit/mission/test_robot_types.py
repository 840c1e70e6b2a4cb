"""Robot type table: Table 4.1 values and clear errors; what a user's file says is what
the brains get, also when the file changes within one process (it is parsed once per
version)."""

import os

import pytest

from swarm_agent.lqr import design_lqr
from swarm_common.robot_types import (
    DEFAULT_CONFIG,
    default_type_counts,
    load_lqr_design,
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


TABLE = """robot_types:
  1: {{mass: {mass}, dry_friction: 0.1, fluid_friction: 0.5, coverage_radius: 0.4}}
lqr_design: {{u_max: {u_max}}}
"""


def test_a_changed_table_is_read_again(tmp_path):
    path = tmp_path / 'types.yaml'
    path.write_text(TABLE.format(mass=2.0, u_max=3.0))
    assert load_robot_types(path)[1].mass == 2.0 and load_lqr_design(path).u_max == 3.0
    before = path.stat().st_mtime_ns
    path.write_text(TABLE.format(mass=2.5, u_max=3.0))   # same size, later
    os.utime(path, ns=(before + 10**9, before + 10**9))
    assert load_robot_types(path)[1].mass == 2.5
    path.write_text(TABLE.format(mass=2.5, u_max=12.0))  # another size
    assert load_lqr_design(path).u_max == 12.0


def test_gains_follow_the_type_and_the_design(tmp_path):
    types = load_robot_types(DEFAULT_CONFIG)
    design = load_lqr_design(DEFAULT_CONFIG)
    gains = {t: design_lqr(robot, design) for t, robot in types.items()}
    assert len({(g.k_v, g.k_e) for g in gains.values()}) == len(types)   # masses differ
    path = tmp_path / 'types.yaml'
    path.write_text(TABLE.format(mass=2.0, u_max=3.0))
    slow = design_lqr(load_robot_types(path)[1], load_lqr_design(path))
    path.write_text(TABLE.format(mass=2.0, u_max=6.0))
    fast = design_lqr(load_robot_types(path)[1], load_lqr_design(path))
    assert fast.k_e > slow.k_e > 0.0      # eq. 3.111: a larger force bound, stiffer gains


def test_a_table_without_types_is_named(tmp_path):
    path = tmp_path / 'empty.yaml'
    path.write_text('lqr_design: {}\n')
    with pytest.raises(RobotTypeError, match='empty.yaml has no "robot_types"'):
        load_robot_types(path)
    with pytest.raises(RobotTypeError, match='cannot read robot type table'):
        load_robot_types(tmp_path / 'missing.yaml')
