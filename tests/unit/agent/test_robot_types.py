"""The robot type table (swarm_common.robot_types): what a user's file says is what the
brains get, also when the file changes within one process (it is parsed once per
version); a bad file is one clear error naming it."""

from __future__ import annotations

import os

import pytest

from swarm_agent.lqr import design_lqr
from swarm_common.robot_types import (
    DEFAULT_CONFIG,
    load_lqr_design,
    load_robot_types,
    RobotTypeError,
)

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
