"""The live view's scene (swarm_sim.live_view): what a Foxglove client is sent."""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest
from shapely.geometry import box
from shapely.geometry import Point as ShapelyPoint
import yaml

from swarm_common.goals import Goal
from swarm_common.robot_types import TYPE_COLOURS
from swarm_common.shapes import Shape
from swarm_sim import live_view as lv

LAYOUT = (pathlib.Path(__file__).resolve().parents[3]
          / 'ros2_ws/src/swarm_sim/config/foxglove_layout.json')


def _view() -> lv.SwarmView:
    region = box(-5, -5, 5, 5).difference(ShapelyPoint(0, 0).buffer(1.0))   # one hole
    shape = Shape('square with a hole', region, obstacles=(box(20, 20, 22, 22),))
    goals = [Goal(id=0, type=1, x=2.0, y=2.0, radius=0.15),
             Goal(id=1, type=3, x=-2.0, y=0.0, radius=0.5)]
    robots = [
        # heard, lost, assigned goal 0, 0.5 m from its true position (3-4-5 triangle)
        lv.RobotView(4, 1, 0.15, estimate=(1.0, 1.0), truth=(1.3, 1.4), mode=lv.MODE_LOST,
                     assigned_goal=0),
        # a beacon not heard yet: drawn where the simulator has it
        lv.RobotView(7, 3, 0.5, is_beacon=True, truth=(4.0, 0.0)),
        lv.RobotView(9, 2, 0.3, estimate=(8.0, 0.0), mode=lv.MODE_NORMAL, alive=False),
        lv.RobotView(11, 2, 0.3),                      # neither heard nor seen
    ]
    return lv.SwarmView(shape=shape, goals=goals, robots=robots,
                        links=[(4, 7), (7, 9), (4, 11)])


def _by_id(entities):
    return {e.id: e for e in entities}


def test_shape_obstacles_and_goals_are_drawn_from_the_inputs():
    ents = _by_id(lv.scene_entities(_view()))
    assert len(ents['shape'].lines[0].points) == 4                     # the square's corners
    assert len(ents['shape'].lines) == 2                               # contour and hole
    hole = np.array(ents['shape'].lines[1].points)[:, :2]
    assert np.hypot(hole[:, 0], hole[:, 1]) == pytest.approx(1.0, abs=1e-9)
    assert all(ln.kind == 'loop' for ln in ents['shape'].lines)
    assert len(ents['obstacles'].lines) == 1
    discs = ents['goals'].discs
    assert [(d.x, d.y, d.radius) for d in discs] == [(2.0, 2.0, 0.15), (-2.0, 0.0, 0.5)]
    assert discs[1].colour == pytest.approx((*TYPE_COLOURS[3], 0.25))


def test_each_robot_shows_its_estimate_type_mode_and_truth():
    ents = _by_id(lv.scene_entities(_view()))
    assert {k for k in ents if k.startswith('agent_')} == {'agent_4', 'agent_7'}
    a4 = ents['agent_4']
    disc, ball = a4.discs[0], a4.balls[0]
    assert (disc.x, disc.y, disc.radius) == (1.0, 1.0, 0.15)           # coverage at estimate
    assert disc.colour[:3] == pytest.approx(TYPE_COLOURS[1])
    assert ball.colour[:3] == lv.MODE_COLOURS[lv.MODE_LOST]
    ring = np.array(a4.lines[0].points)[:, :2]                         # the true position
    assert ring.mean(axis=0) == pytest.approx((1.3, 1.4))
    assert np.hypot(*(ring - (1.3, 1.4)).T) == pytest.approx(0.15)
    assert a4.metadata['error_m'] == '0.500' and a4.metadata['mode'] == 'lost'
    a7 = ents['agent_7']
    assert (a7.discs[0].x, a7.discs[0].y) == (4.0, 0.0)
    assert a7.balls[0].colour[:3] == lv.UNHEARD
    assert a7.lines[0].colour == lv.BEACON_RGBA and len(a7.lines) == 1  # beacon, no truth ring
    assert a7.labels[0].text == '7'


def test_links_and_assignment_join_the_robots_drawn():
    ents = _by_id(lv.scene_entities(_view()))
    links = ents['links'].lines[0]
    assert links.kind == 'list'
    assert [p[:2] for p in links.points] == [(1.0, 1.0), (4.0, 0.0)]   # only 4-7 is drawn
    (line,) = ents['assignment'].lines
    assert [p[:2] for p in line.points] == [(1.0, 1.0), (2.0, 2.0)]     # robot 4 -> goal 0


def test_status_counts_the_swarm():
    assert lv.status(_view()) == {'agents': 3, 'heard': 1, 'settled': 0, 'assigned': 1,
                                  'links': 2, 'normal': 0, 'lost': 1, 'return_home': 0}
    assert set(lv.status(_view())) == set(lv.STATUS_SCHEMA['properties'])


def test_an_empty_swarm_has_no_entities_and_zero_counts():
    assert lv.scene_entities(lv.SwarmView()) == []
    assert set(lv.status(lv.SwarmView()).values()) == {0}


def test_links_are_the_one_hop_routes_of_the_dsdv_tables():
    routes = {1: [(2, 1), (3, 2), (1, 0)], 2: [(1, 1)], 3: [(2, 255)], 4: [(5, 1)]}
    assert lv.links_from_routes(routes) == {(1, 2), (4, 5)}


def test_circle_points_lie_on_the_circle():
    pts = np.array(lv.circle_points(2.0, -1.0, 0.3, 0.1, segments=12))
    assert len(pts) == 12 and set(pts[:, 2]) == {0.1}
    assert np.hypot(pts[:, 0] - 2.0, pts[:, 1] + 1.0) == pytest.approx(0.3)
    assert math.isclose(pts[0, 0], 2.3)


def test_shipped_layout_is_the_generated_one_and_shows_the_channels():
    shipped = json.loads(LAYOUT.read_text(encoding='utf-8'))
    assert shipped == lv.foxglove_layout()
    panels = shipped['configById']
    assert panels['3D!swarm']['topics'] == {lv.SCENE_TOPIC: {'visible': True}}
    plotted = {p['value'].split('.')[-1] for p in panels['Plot!status']['paths']}
    assert plotted <= set(lv.STATUS_SCHEMA['properties']) and 'settled' in plotted
    assert {shipped['layout']['first'], shipped['layout']['second']} == set(panels)


def test_the_rviz_config_shows_the_markers_in_the_map_frame():
    rviz = LAYOUT.with_name('swarm.rviz')
    manager = yaml.safe_load(rviz.read_text(encoding='utf-8'))['Visualization Manager']
    arrays = [d for d in manager['Displays']
              if d['Class'] == 'rviz_default_plugins/MarkerArray']
    assert [d['Topic']['Value'] for d in arrays] == ['/swarm/markers']
    assert set(arrays[0]['Namespaces']) == {'robots', 'modes', 'goals', 'shape', 'obstacles',
                                            'links'}
    assert manager['Global Options']['Fixed Frame'] == lv.FRAME
