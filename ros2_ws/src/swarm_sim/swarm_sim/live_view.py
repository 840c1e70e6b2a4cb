"""Live view of a running swarm: the scene, the status and the Foxglove layout.

Plain data in, the scene out (issue 21), so the drawing is tested without a server or
ROS. ``live_view_node`` fills a ``SwarmView`` from the swarm's topics, and
``swarm_sim.foxglove_view`` serves it on a Foxglove WebSocket:

``/swarm/scene``  (foxglove.SceneUpdate, drawn by the 3D panel without configuration)
  ``shape``       the formation contour and its holes (line loops, dark grey)
  ``obstacles``   the workspace obstacles (line loops, brown)
  ``goals``       a faint disc per goal state, its coverage radius, its type's colour
  ``agent_K``     one entity per robot: a disc of its coverage radius (Table 4.1) at the
                  position it estimates, in its type's colour; a ball above it in the
                  colour of its mode (thesis 3.1.3: green normal, orange lost, red
                  returning home, grey not heard yet); a white ring for a beacon; its id;
                  in simulation a black ring at its true position and a line from the
                  truth to the estimate (the localization error). Its metadata (type,
                  mode, beacon, goal, settled, error) shows when the robot is clicked.
  ``links``       one line per radio link (a direct DSDV neighbour, one hop)
  ``assignment``  one line from each robot to the goal state it is assigned
``/swarm/status`` (JSON) counts: agents heard, settled, in each mode, assigned, links.

Every scene update deletes the previous entities first, so robots removed by a fault,
goals of an older partition and broken links disappear. Type colours are those of the
figures, the RViz markers and the pybullet bodies
(``swarm_common.robot_types.TYPE_COLOURS``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
import math

import numpy as np
from shapely.geometry import Polygon

from swarm_common.goals import Goal
from swarm_common.robot_types import OTHER_COLOUR, TYPE_COLOURS
from swarm_common.shapes import Shape

# Mode colours (AgentState.MODE_*), shared with swarm_sim.markers.
MODE_NORMAL, MODE_LOST, MODE_RETURN_HOME = 0, 1, 2
NOT_HEARD = -1
MODE_COLOURS = {MODE_NORMAL: (0.1, 0.8, 0.1), MODE_LOST: (1.0, 0.55, 0.0),
                MODE_RETURN_HOME: (0.9, 0.0, 0.0)}
UNHEARD = (0.75, 0.75, 0.75)
MODE_NAMES = {MODE_NORMAL: 'normal', MODE_LOST: 'lost', MODE_RETURN_HOME: 'return_home',
              NOT_HEARD: 'not_heard'}
NO_GOAL = -1

SCENE_TOPIC = '/swarm/scene'
STATUS_TOPIC = '/swarm/status'
FRAME = 'map'
CIRCLE_SEGMENTS = 32

SHAPE_RGBA = (0.1, 0.1, 0.1, 1.0)
OBSTACLE_RGBA = (0.35, 0.25, 0.15, 1.0)
LINK_RGBA = (0.3, 0.3, 0.9, 0.5)
TRUTH_RGBA = (0.0, 0.0, 0.0, 0.9)
BEACON_RGBA = (1.0, 1.0, 1.0, 1.0)
LABEL_RGBA = (0.05, 0.05, 0.05, 1.0)

RGBA = tuple[float, float, float, float]
XYZ = tuple[float, float, float]


def rgba(rgb: Sequence[float], alpha: float = 1.0) -> RGBA:
    """An (r, g, b) colour with its opacity."""
    return float(rgb[0]), float(rgb[1]), float(rgb[2]), float(alpha)


def type_colour(type_id: int) -> tuple[float, float, float]:
    """The colour of a robot type (figures, markers, bodies)."""
    return TYPE_COLOURS.get(int(type_id), OTHER_COLOUR)


def mode_colour(mode: int) -> tuple[float, float, float]:
    """The colour of an agent mode; grey when the agent was not heard yet."""
    return MODE_COLOURS.get(int(mode), UNHEARD)


def polygon_rings(polygon: Polygon) -> list[np.ndarray]:
    """The (K, 2) vertices of the exterior and then of each hole, closing vertex dropped."""
    return [np.asarray(ring.coords, dtype=float)[:-1]
            for ring in [polygon.exterior, *polygon.interiors]]


def link_pairs(links: np.ndarray, alive: Sequence[bool]) -> list[tuple[int, int]]:
    """Index pairs (i < j) of a symmetric boolean adjacency whose two ends are alive."""
    ii, jj = np.nonzero(np.triu(np.asarray(links, dtype=bool), k=1))
    return [(int(i), int(j)) for i, j in zip(ii, jj) if alive[i] and alive[j]]


def circle_points(x: float, y: float, radius: float, z: float,
                  segments: int = CIRCLE_SEGMENTS) -> tuple[XYZ, ...]:
    """``segments`` points on a circle (a line loop closes it)."""
    a = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    return tuple((float(x + radius * c), float(y + radius * s), float(z))
                 for c, s in zip(np.cos(a), np.sin(a)))


# ---------------------------------------------------------------- the swarm's state


@dataclass(frozen=True)
class RobotView:
    """What the view knows of one robot.

    ``estimate``: the position its agent reports (AgentState.position); ``truth``: the
    simulator's (SwarmTruth, simulation only); ``mode``: an AgentState mode or
    ``NOT_HEARD``; ``radius``: its coverage radius in metres (Table 4.1).
    """

    id: int
    type: int
    radius: float
    is_beacon: bool = False
    estimate: tuple[float, float] | None = None
    truth: tuple[float, float] | None = None
    mode: int = NOT_HEARD
    assigned_goal: int = NO_GOAL
    settled: bool = False
    alive: bool = True

    def where(self) -> tuple[float, float] | None:
        """Where the robot is drawn: its estimate, else its true position."""
        return self.estimate if self.estimate is not None else self.truth


@dataclass(frozen=True)
class SwarmView:
    """The swarm at one instant: shape, goals, robots and radio links (robot id pairs)."""

    shape: Shape | None = None
    goals: Sequence[Goal] = ()
    robots: Sequence[RobotView] = ()
    links: Iterable[tuple[int, int]] = ()


# ---------------------------------------------------------------- scene primitives


@dataclass(frozen=True)
class Disc:
    """A flat upright cylinder standing on z: a coverage circle."""

    x: float
    y: float
    radius: float
    height: float
    colour: RGBA
    z: float = 0.0


@dataclass(frozen=True)
class Ball:
    """A sphere of ``diameter`` centred at (x, y, z)."""

    x: float
    y: float
    z: float
    diameter: float
    colour: RGBA


@dataclass(frozen=True)
class Lines:
    """Lines through ``points``: 'loop' (closed ring), 'strip' or 'list' (pairs)."""

    kind: str
    points: tuple[XYZ, ...]
    colour: RGBA
    thickness: float


@dataclass(frozen=True)
class Label:
    """A text that faces the camera, ``size`` in pixels."""

    x: float
    y: float
    z: float
    text: str
    colour: RGBA = LABEL_RGBA
    size: float = 14.0


@dataclass
class Entity:
    """One scene entity: an id, its primitives and key/value metadata."""

    id: str
    discs: list[Disc] = field(default_factory=list)
    balls: list[Ball] = field(default_factory=list)
    lines: list[Lines] = field(default_factory=list)
    labels: list[Label] = field(default_factory=list)
    metadata: dict[str, str] = field(default_factory=dict)


def _outlines(entity_id: str, polygons: Iterable[Polygon], colour: RGBA, thickness: float,
              z: float) -> Entity:
    out = Entity(entity_id)
    for polygon in polygons:
        for ring in polygon_rings(polygon):
            out.lines.append(Lines('loop', tuple((float(x), float(y), z) for x, y in ring),
                                   colour, thickness))
    return out


def robot_entity(robot: RobotView) -> Entity | None:
    """The entity of one robot (see the module docstring); None when it is not drawn
    (removed by a fault, or neither heard nor seen)."""
    at = robot.where()
    if not robot.alive or at is None:
        return None
    x, y = float(at[0]), float(at[1])
    r = float(robot.radius)
    ent = Entity(f'agent_{robot.id}')
    ent.discs.append(Disc(x, y, r, 0.1, rgba(type_colour(robot.type), 0.7)))
    ent.balls.append(Ball(x, y, 0.35, max(0.15, 0.4 * r), rgba(mode_colour(robot.mode))))
    if robot.is_beacon:
        ent.lines.append(Lines('loop', circle_points(x, y, r, 0.12), BEACON_RGBA, 0.04))
    ent.labels.append(Label(x, y, 0.6, str(robot.id)))
    ent.metadata = {'type': str(robot.type), 'mode': MODE_NAMES.get(robot.mode, 'unknown'),
                    'beacon': str(robot.is_beacon).lower(),
                    'assigned_goal': str(robot.assigned_goal),
                    'settled': str(robot.settled).lower()}
    if robot.truth is not None and robot.estimate is not None:
        tx, ty = float(robot.truth[0]), float(robot.truth[1])
        ent.lines.append(Lines('loop', circle_points(tx, ty, r, 0.14), TRUTH_RGBA, 0.03))
        ent.lines.append(Lines('strip', ((tx, ty, 0.14), (x, y, 0.14)), TRUTH_RGBA, 0.03))
        ent.metadata['error_m'] = f'{math.hypot(x - tx, y - ty):.3f}'
    return ent


def scene_entities(view: SwarmView) -> list[Entity]:
    """Every entity of the live view (see the module docstring)."""
    out: list[Entity] = []
    if view.shape is not None:
        out.append(_outlines('shape', [view.shape.region], SHAPE_RGBA, 0.08, 0.02))
        if view.shape.obstacles:
            out.append(_outlines('obstacles', view.shape.obstacles, OBSTACLE_RGBA, 0.12, 0.5))
    goals = {int(g.id): g for g in view.goals}
    if goals:
        out.append(Entity('goals', discs=[
            Disc(float(g.x), float(g.y), float(g.radius), 0.02, rgba(type_colour(g.type), 0.25))
            for g in goals.values()], metadata={'count': str(len(goals))}))
    drawn = {}
    for robot in view.robots:
        ent = robot_entity(robot)
        if ent is not None:
            out.append(ent)
            drawn[int(robot.id)] = robot
    link_points: list[XYZ] = []
    for a, b in view.links:
        if a in drawn and b in drawn and a != b:
            (ax, ay), (bx, by) = drawn[a].where(), drawn[b].where()
            link_points += [(float(ax), float(ay), 0.2), (float(bx), float(by), 0.2)]
    if link_points:
        out.append(Entity('links', lines=[Lines('list', tuple(link_points), LINK_RGBA, 0.03)],
                          metadata={'count': str(len(link_points) // 2)}))
    assignment = []
    for robot in drawn.values():
        goal = goals.get(int(robot.assigned_goal))
        if goal is not None:
            x, y = robot.where()
            assignment.append(Lines('strip', ((float(x), float(y), 0.08),
                                              (float(goal.x), float(goal.y), 0.08)),
                                    rgba(type_colour(robot.type), 0.9), 0.04))
    if assignment:
        out.append(Entity('assignment', lines=assignment,
                          metadata={'count': str(len(assignment))}))
    return out


def status(view: SwarmView) -> dict[str, int]:
    """The counts the layout plots: robots, heard, settled, per mode, assigned, links."""
    alive = [r for r in view.robots if r.alive]
    heard = [r for r in alive if r.mode != NOT_HEARD]
    ids = {int(r.id) for r in alive}
    out = {'agents': len(alive), 'heard': len(heard),
           'settled': sum(1 for r in heard if r.settled),
           'assigned': sum(1 for r in heard if r.assigned_goal != NO_GOAL),
           'links': len({(min(a, b), max(a, b)) for a, b in view.links
                         if a != b and a in ids and b in ids})}
    for mode in (MODE_NORMAL, MODE_LOST, MODE_RETURN_HOME):
        out[MODE_NAMES[mode]] = sum(1 for r in heard if r.mode == mode)
    return out


STATUS_SCHEMA = {
    'type': 'object',
    'title': 'swarm_sim.SwarmStatus',
    'properties': {key: {'type': 'integer', 'description': text} for key, text in (
        ('agents', 'robots alive'), ('heard', 'robots whose agent state arrived'),
        ('settled', 'agents that report settled'),
        ('assigned', 'agents with an assigned goal'),
        ('links', 'radio links between robots alive'),
        ('normal', 'agents in mode normal'), ('lost', 'agents in mode lost'),
        ('return_home', 'agents returning home'))},
}


def links_from_routes(routes: Mapping[int, Iterable[tuple[int, int]]]) -> set[tuple[int, int]]:
    """Radio links from DSDV tables: owner -> (destination, hop count) rows; a one-hop
    route is a neighbour heard directly (thesis 3.1.2). Pairs are (low id, high id)."""
    out = set()
    for owner, rows in routes.items():
        for dest, hops in rows:
            if int(hops) == 1 and int(dest) != int(owner):
                out.add((min(int(owner), int(dest)), max(int(owner), int(dest))))
    return out


# ---------------------------------------------------------------- the layout


def foxglove_layout(extent_m: float = 100.0) -> dict:
    """The Foxglove layout shipped as ``config/foxglove_layout.json``: a 3D panel (top
    view of the ``map`` frame with a grid of ``extent_m``) on the scene, and a plot of
    agents settled and per mode from the status topic."""
    series = [('settled', '#2ca02c'), ('normal', '#1f77b4'), ('lost', '#ff7f0e'),
              ('return_home', '#d62728')]
    three_d = {
        'cameraState': {'perspective': False, 'distance': 1.2 * extent_m, 'phi': 0,
                        'thetaOffset': 0, 'target': [0, 0, 0], 'targetOffset': [0, 0, 0],
                        'targetOrientation': [0, 0, 0, 1], 'fovy': 45, 'near': 0.5,
                        'far': 5000},
        'followMode': 'follow-none',
        'followTf': FRAME,
        'scene': {'enableStats': False},
        'transforms': {},
        'topics': {SCENE_TOPIC: {'visible': True}},
        'layers': {'grid': {'visible': True, 'instanceId': 'grid', 'label': 'Grid',
                            'layerId': 'foxglove.Grid', 'frameId': FRAME, 'frameLocked': True,
                            'size': extent_m, 'divisions': int(extent_m // 5),
                            'lineWidth': 1, 'color': '#248eff55',
                            'position': [0, 0, 0], 'rotation': [0, 0, 0], 'order': 1}},
        'publish': {'type': 'point'},
    }
    plot = {
        'title': 'Agents settled / in each mode',
        'paths': [{'value': f'{STATUS_TOPIC}.{key}', 'enabled': True, 'label': key,
                   'color': colour, 'timestampMethod': 'receiveTime'}
                  for key, colour in series],
        'showLegend': True, 'legendDisplay': 'floating', 'showXAxisLabels': True,
        'showYAxisLabels': True, 'isSynced': True, 'xAxisVal': 'timestamp',
        'minYValue': 0, 'followingViewWidth': 300,
    }
    return {
        'configById': {'3D!swarm': three_d, 'Plot!status': plot},
        'globalVariables': {},
        'userNodes': {},
        'playbackConfig': {'speed': 1},
        'layout': {'first': '3D!swarm', 'second': 'Plot!status', 'direction': 'row',
                   'splitPercentage': 70},
    }
