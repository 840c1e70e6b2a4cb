"""Contacts in the pybullet world: robot bodies that touch are counted once per contact,
and the closest approach of coverage circles is measured at every physics step
(swarm_sim.world, swarm_sim.metrics.SeparationTracker)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip('pybullet')

from swarm_common.fleet import RobotSpec  # noqa: E402
from swarm_common.robot_types import GRAVITY, load_robot_types  # noqa: E402
from swarm_sim.metrics import SeparationTracker  # noqa: E402
from swarm_sim.world import PybulletBackend  # noqa: E402

TYPES = load_robot_types()
DT = 0.01


def test_robots_driven_into_each_other_touch_once_per_approach():
    # Two type-2 robots (coverage radius 0.3 m) 1.2 m apart on flat ground, pushed
    # together with twice their dry friction, pulled apart, pushed together again. Their
    # bodies (spheres within the coverage circles) touch when the circles overlap by a
    # quarter: two contacts, each counted once however many steps it lasts.
    rtype = TYPES[2]
    push = 2.0 * rtype.dry_friction * rtype.mass * GRAVITY
    fleet = [RobotSpec(0, 2, False, -0.6, 0.0), RobotSpec(1, 2, False, 0.6, 0.0)]
    world = PybulletBackend(fleet, TYPES, terrain='flat', half_size=10.0)
    radii = np.full(2, rtype.coverage_radius)
    tracker = SeparationTracker()
    try:
        for direction, seconds in ((1.0, 3.0), (-1.0, 1.0), (1.0, 5.0)):
            force = np.array([[direction * push, 0.0], [-direction * push, 0.0]])
            for _ in range(int(round(seconds / DT))):
                world.step(DT, force)
                tracker.update(world.positions(), radii)
                world.count_body_contacts(tracker.overlapping_pairs())
            gap = np.linalg.norm(np.diff(world.positions(), axis=0))
            if direction > 0:
                assert gap < 2 * rtype.coverage_radius          # pressed together
            else:
                assert gap > 2 * rtype.coverage_radius          # apart
        assert world.body_contacts == 2
        assert tracker.contacts == 2 and tracker.min_ratio < 1.0
    finally:
        world.close()
