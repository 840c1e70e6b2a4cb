"""The RViz view of the swarm (swarm_sim.markers): what /swarm/markers shows."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import box
from shapely.geometry import Point as ShapelyPoint

pytest.importorskip('visualization_msgs')

from visualization_msgs.msg import Marker  # noqa: E402

from swarm_common.goals import Goal  # noqa: E402
from swarm_common.robot_types import TYPE_COLOURS  # noqa: E402
from swarm_sim.markers import marker_count, MODE_COLOURS, swarm_markers, UNHEARD  # noqa: E402


def _by(array, ns):
    return {m.id: m for m in array.markers if m.ns == ns and m.action != Marker.DELETEALL}


def test_every_layer_of_the_view_is_drawn_from_the_inputs():
    ids, types, radii = [4, 7, 9], [1, 2, 3], [0.5, 0.75, 1.0]
    pos = np.array([[0.0, 0.0], [3.0, 0.0], [10.0, 0.0]])
    links = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], dtype=bool)
    region = box(-5, -5, 5, 5).difference(ShapelyPoint(0, 0).buffer(1.0))   # one hole
    goals = [Goal(id=0, type=1, x=1.0, y=1.0, radius=0.5),
             Goal(id=1, type=3, x=-2.0, y=0.0, radius=1.0)]
    view = swarm_markers(None, ids, types, radii, pos, [True, True, False],
                         modes={4: 0, 7: 2}, goals=goals, region=region,
                         obstacles=[box(20, 20, 22, 22)], links=links)
    robots, modes = _by(view, 'robots'), _by(view, 'modes')
    assert sorted(robots) == ids and robots[9].action == Marker.DELETE   # removed robot
    assert robots[7].scale.x == pytest.approx(1.5)                     # coverage diameter
    assert (robots[7].color.r, robots[7].color.g) == pytest.approx(TYPE_COLOURS[2][:2])
    assert (modes[4].color.g, modes[7].color.r) == pytest.approx(
        (MODE_COLOURS[0][1], MODE_COLOURS[2][0]))
    assert marker_count(view, 'goals') == 2 and _by(view, 'goals')[1].scale.x == 2.0
    assert marker_count(view, 'shape') == 2              # the contour and its hole
    assert marker_count(view, 'obstacles') == 1
    (lines,) = _by(view, 'links').values()
    assert len(lines.points) == 2                        # 7-9 is gone with robot 9
    assert {(p.x, p.y) for p in lines.points} == {(0.0, 0.0), (3.0, 0.0)}
    cleared = [m.ns for m in view.markers if m.action == Marker.DELETEALL]
    assert sorted(cleared) == ['goals', 'links', 'obstacles', 'shape']


def test_agents_not_heard_yet_are_grey_and_an_empty_world_is_only_robots():
    view = swarm_markers(None, [0], [1], [0.5], np.zeros((1, 2)), [True])
    (mode,) = _by(view, 'modes').values()
    assert (mode.color.r, mode.color.g, mode.color.b) == pytest.approx(UNHEARD)
    assert [marker_count(view, ns) for ns in ('goals', 'shape', 'obstacles', 'links')] == \
        [0, 0, 0, 0]
