"""A run's processes as data: the one launch source of the simulated swarm.

A plan is a list of ``NodeSpec``: which executable of which package runs, under which
node name and namespace, with which parameters, parameter files and remappings. Two
renderers read the same plan, so they cannot disagree: ``ros_arguments`` gives the
command line ``scripts/launch_swarm.py`` starts (swarm_bringup.launcher), and
``launch/swarm.launch.py`` hands ``node_kwargs`` to ``launch_ros.actions.Node``.

The graph (thesis 4.1, 4.3): the world (``sim_node``, owner of ``/clock``), the mission
(``mission_node``: shape, partition, goal broadcast) and the agents (thesis Ch. 3), either
one ``agent_node`` process per robot named ``agent_K`` (the faithful deployment) or all
of them in one ``composed_node`` process (for scale), whose nodes keep the names they
give themselves (``agent_K`` too). A run with a ``bag`` path starts the
``recorder_node`` first, which writes every topic into that MCAP bag; the sim then waits
for it to hear ``swarm/truth`` before t = 0, so the bag starts with the run. Pure: no
ROS import.

Agent processes and the mission node are respawned when they exit on their own (a
crash): after ``RESPAWN_DELAY_S``, at most ``RESPAWN_RETRIES`` times, by launch_ros
(``respawn``, ``respawn_delay``, ``respawn_max_retries``) and by the launcher alike. A
restarted agent rejoins the mesh with DSDV sequence numbers above its old ones
(``swarm_agent.dsdv.boot_sequence``) and gets the shape and goals again from their
transient-local topics; a restarted mission node publishes them again. The simulator is
never respawned: it owns the clock and the record, and its exit ends the run.

Names are relative (``agent_K/state``, ``radio/tx``, ``swarm/goals``), so a run with a
``namespace`` puts every node of the plan in it and two swarms share one ROS domain
without crosstalk. The ROS-global names the nodes use as ROS tools expect, ``/clock``
(rclpy's time source) and ``/tf``, ``/tf_static`` (tf2), are remapped into the namespace
too (``GLOBAL_REMAPPINGS``, as nav2's multi-robot bringup does for TF): each swarm has its
own clock and TF tree, whose frame ids (``map``, ``agent_K/base_link``) stay those of a
swarm without namespace; ``rviz2 --ros-args -r /tf:=/swarm_a/tf`` shows one of them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
import pathlib
from typing import Any
import uuid

DEFAULT_BEACON_SHARE = 0.15   # beacons per agent when no count is given (at least 3)
MIN_BEACONS = 3               # trilateration needs three anchors (thesis 3.2)
BAG_NAME = 'run.mcap'         # the bag of a recorded run, in its output folder
MISSION_STATE_NAME = 'mission_state.json'   # the mission node's state, in the same folder
# Absolute names remapped into a run's namespace (module docstring).
GLOBAL_REMAPPINGS = (('/clock', 'clock'), ('/tf', 'tf'), ('/tf_static', 'tf_static'))
RESPAWN_DELAY_S = 1.0         # wait before a crashed process is started again
RESPAWN_RETRIES = 3           # restarts of one process at most (then its exit is a crash)


class NamespaceError(ValueError):
    """A namespace that is not a ROS namespace; the message names the fix."""


def checked_namespace(text: str) -> str:
    """``text`` as an absolute namespace (``swarm_a`` -> ``/swarm_a``; '' or ``/``: none,
    ''), or NamespaceError."""
    tokens = text.strip().strip('/').split('/') if text.strip().strip('/') else []
    for token in tokens:
        if not token or not (token[0].isalpha() or token[0] == '_') or \
                not all(c.isascii() and (c.isalnum() or c == '_') for c in token):
            raise NamespaceError(f'namespace {text!r} is not a ROS namespace: tokens of '
                                 'letters, digits and _ that do not start with a digit, '
                                 'e.g. /swarm_a')
    return '/' + '/'.join(tokens) if tokens else ''


@dataclass(frozen=True)
class NodeSpec:
    """One process of a run.

    ``name`` None keeps the names the process gives its nodes (a composed process holds
    one node per robot: a name would rename them all). ``process`` names the process and
    its log file; ``fork`` starts it from a server that has imported the module once
    (swarm_agent.prefork); ``respawn``: started again when it exits on its own (module
    docstring).
    """

    package: str
    executable: str
    process: str
    name: str | None = None
    namespace: str | None = None
    parameters: Mapping[str, Any] = field(default_factory=dict)
    params_files: tuple[str, ...] = ()
    remappings: tuple[tuple[str, str], ...] = ()
    fork: bool = False
    respawn: bool = False

    @property
    def module(self) -> str:
        """The Python module run as ``python -m`` (every executable is its module)."""
        return f'{self.package}.{self.executable}'


@dataclass(frozen=True)
class SwarmRun:
    """What the plan of a simulated swarm needs to know about the run."""

    fleet_file: str
    shape: str
    method: str = 'bubble'
    seed: int = 0
    composed: bool = False
    decentralized: bool = False
    control_rate_hz: float = 50.0
    real_time_factor: float = 0.0
    record_dir: str = ''
    gui: bool = False
    half_size: float = 50.0
    markers: bool = False
    remesh: str = 'incremental'
    morph: str = ''
    sequence_file: str = ''
    truth_subscribers: int = 0    # observers the sim waits for before t = 0 (the monitor)
    bag: str = ''                 # MCAP bag of every topic (recorder_node); '': none
    params_files: tuple[str, ...] = ()
    namespace: str = ''           # every node's namespace (e.g. /swarm_a); '': none
    # The mission node keeps its state here and a respawned one resumes it
    # (swarm_mission.mission_state); run_id tells this run's file from another's.
    mission_state_file: str = ''
    run_id: str = ''
    swarm_key_file: str = ''      # the agents' radio key file; '': the development key


def mission_state(out: str | pathlib.Path) -> dict[str, str]:
    """The ``SwarmRun`` fields of a run writing into ``out``: the mission's state file
    there, under an id of its own (a later run in the same folder does not resume it)."""
    return {'mission_state_file': str(pathlib.Path(out) / MISSION_STATE_NAME),
            'run_id': uuid.uuid4().hex}


def scoped(run: SwarmRun) -> dict[str, Any]:
    """The ``namespace`` and ``remappings`` of every node of ``run`` (module docstring)."""
    namespace = checked_namespace(run.namespace)
    return {'namespace': namespace or None,
            'remappings': GLOBAL_REMAPPINGS if namespace else ()}


def type_counts_text(counts: Mapping[int, int]) -> str:
    """``{1: 4, 2: 3}`` as the ``type_counts`` parameter ``'1:4,2:3'``."""
    return ','.join(f'{t}:{c}' for t, c in sorted(counts.items()))


def default_beacons(agents: int) -> int:
    """The beacon count of a run that names none: 15 % of the agents, at least 3."""
    return max(MIN_BEACONS, round(DEFAULT_BEACON_SHARE * agents))


def counts_of(fleet: Iterable) -> dict[int, int]:
    """Robots per type of a fleet."""
    counts: dict[int, int] = {}
    for r in fleet:
        counts[r.type] = counts.get(r.type, 0) + 1
    return counts


def fleet_counts(agents: int, types: str = '') -> dict[int, int]:
    """Robots per type of a run of ``agents``: ``types`` ``TYPE:COUNT,...`` or, empty,
    the default composition (Table 4.1 shares). Raises RobotTypeError (a ValueError)
    naming a bad count."""
    from swarm_common.robot_types import default_type_counts, parse_type_counts

    return parse_type_counts(types) if types else default_type_counts(agents)


def generate_fleet(counts: Mapping[int, int], beacons: int, seed: int, half_size: float,
                   shape) -> list:
    """The fleet of a run given by counts: ids 0..N-1 in type order placed at random
    (seeded) in the workspace outside the shape's obstacles, beacons spread far apart
    (swarm_common.fleet.random_fleet; FleetError, a ValueError, names a bad count)."""
    import numpy as np

    from swarm_common.fleet import random_fleet

    return random_fleet(counts, beacons, np.random.default_rng(seed), half_size=half_size,
                        obstacles=list(shape.obstacles))


def recorder_nodes(run: SwarmRun) -> list[NodeSpec]:
    """The recorder of the run's topics into ``run.bag`` (none without a bag)."""
    if not run.bag:
        return []
    return [NodeSpec('swarm_bringup', 'recorder_node', 'recorder', name='recorder',
                     parameters={'output': run.bag, 'use_sim_time': True},
                     params_files=run.params_files, **scoped(run))]


def world_nodes(run: SwarmRun) -> list[NodeSpec]:
    """The recorder (when the run has a bag), the simulator, the mission node and its
    radio."""
    sim = {'fleet_file': run.fleet_file, 'shape': run.shape,
           'real_time_factor': float(run.real_time_factor), 'record_dir': run.record_dir,
           'gui': run.gui, 'seed': run.seed, 'half_size': run.half_size,
           'marker_rate_hz': 1.0 if run.markers else 0.0,
           # Composed agents take every robot's imu, ranges and radio deliveries in one
           # message per step (swarm_msgs/SensorBatch).
           'sensor_batch': bool(run.composed),
           # Composed agents answer every control step in one ForceBatch, so the world
           # waits for them step by step: the 50 Hz inner loop runs as it does headless
           # and on a robot, however loaded the machine (swarm_sim.pacing).
           **({'max_agent_lag_s': 1.0 / run.control_rate_hz} if run.composed else {}),
           # The recorder is one more truth subscriber: the sim starts once it listens.
           'truth_subscribers': run.truth_subscribers + (1 if run.bag else 0)}
    mission = {'shape': run.shape, 'method': run.method, 'fleet_file': run.fleet_file,
               'seed': run.seed, 'remesh': run.remesh, 'decentralized': run.decentralized,
               'use_sim_time': True}
    if run.morph:
        mission['morph'] = run.morph
    if run.sequence_file:
        mission['sequence_file'] = run.sequence_file
    if run.mission_state_file:
        mission.update(state_file=run.mission_state_file, run_id=run.run_id)
    # The mission computer's radio (sim_node's mission_radio): the mission learns over it
    # which agents are alive.
    radio = {'fleet_file': run.fleet_file, 'use_sim_time': True}
    if run.swarm_key_file:
        radio['swarm_key_file'] = run.swarm_key_file
    return recorder_nodes(run) + [
        NodeSpec('swarm_sim', 'sim_node', 'sim', name='sim', parameters=sim,
                 params_files=run.params_files, **scoped(run)),
        NodeSpec('swarm_mission', 'mission_node', 'mission', name='mission',
                 parameters=mission, params_files=run.params_files, respawn=True,
                 **scoped(run)),
        NodeSpec('swarm_agent', 'mission_radio_node', 'mission_radio', name='mission_radio',
                 parameters=radio, params_files=run.params_files, respawn=True,
                 **scoped(run))]


def agent_nodes(run: SwarmRun, fleet: Sequence, counts: Mapping[int, int],
                local_ids: Iterable[int] | None = None) -> list[NodeSpec]:
    """The agents of ``local_ids`` (default: the whole fleet): one composed process, or
    one process per robot."""
    type_counts = type_counts_text(counts)
    all_ids = [r.id for r in fleet]
    local = set(all_ids if local_ids is None else local_ids)
    if not local:
        return []
    if run.composed:
        params: dict[str, Any] = {
            'fleet_file': run.fleet_file, 'method': run.method, 'seed': run.seed,
            'control_rate_hz': run.control_rate_hz, 'use_sim_time': True,
            'partition_locally': run.decentralized, 'type_counts': type_counts,
            'sensor_batch': True}   # the world sends one batch per step (world_nodes)
        if len(local) < len(all_ids):
            params['agent_ids'] = sorted(local)
        if run.swarm_key_file:
            params['swarm_key_file'] = run.swarm_key_file
        return [NodeSpec('swarm_agent', 'composed_node', 'agents', parameters=params,
                         params_files=run.params_files, respawn=True, **scoped(run))]
    return [NodeSpec('swarm_agent', 'agent_node', f'agent_{r.id}', name=f'agent_{r.id}',
                     fork=True, params_files=run.params_files, respawn=True, **scoped(run),
                     parameters={
                         'agent_id': r.id, 'agent_type': r.type, 'is_beacon': r.is_beacon,
                         'initial_x': r.x, 'initial_y': r.y, 'method': run.method,
                         'seed': run.seed + r.id, 'control_rate_hz': run.control_rate_hz,
                         'partition_locally': run.decentralized, 'type_counts': type_counts,
                         'use_sim_time': True,
                         **({'swarm_key_file': run.swarm_key_file}
                            if run.swarm_key_file else {})})
            for r in fleet if r.id in local]


def swarm_plan(run: SwarmRun, fleet: Sequence, counts: Mapping[int, int]) -> list[NodeSpec]:
    """Every process of a simulated swarm on one host: world, mission, agents."""
    return world_nodes(run) + agent_nodes(run, fleet, counts)


def parameter_text(value: Any) -> str:
    """A parameter value as ``-p name:=VALUE`` writes it (YAML)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(str(v) for v in value) + ']'
    return str(value)


def ros_arguments(spec: NodeSpec) -> list[str]:
    """The ``--ros-args`` of a process: namespace, name, parameter files, then the
    parameters (which win over the files) and the remappings."""
    args = ['--ros-args']
    if spec.namespace:
        args += ['-r', f'__ns:={spec.namespace}']
    if spec.name:
        args += ['-r', f'__node:={spec.name}']
    for path in spec.params_files:
        args += ['--params-file', path]
    for key, value in spec.parameters.items():
        args += ['-p', f'{key}:={parameter_text(value)}']
    for old, new in spec.remappings:
        args += ['-r', f'{old}:={new}']
    return args


def node_kwargs(spec: NodeSpec) -> dict[str, Any]:
    """The keyword arguments of ``launch_ros.actions.Node`` for a process."""
    kwargs: dict[str, Any] = {
        'package': spec.package, 'executable': spec.executable,
        'parameters': [*spec.params_files, dict(spec.parameters)],
        'remappings': list(spec.remappings), 'output': 'screen'}
    if spec.name:
        kwargs['name'] = spec.name
    if spec.namespace:
        kwargs['namespace'] = spec.namespace
    if spec.respawn:
        kwargs.update(respawn=True, respawn_delay=RESPAWN_DELAY_S,
                      respawn_max_retries=RESPAWN_RETRIES)
    return kwargs
