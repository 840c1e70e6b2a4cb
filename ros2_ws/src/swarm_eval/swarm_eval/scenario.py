"""The evaluator's scenario of one trial from its options (thesis 4.3), and the trial.

``ScenarioSpec`` holds the options of ``evaluate`` (the same names and defaults);
``build_scenario`` turns them into the ``swarm_sim.headless.Scenario`` of a seed and
``run_trial`` runs it. The studies call these directly. The default beacon count and
the ``--remove`` parser are the launcher's (``swarm_bringup``), so a headless and a ROS
run of the same options start the same swarm and remove the same agents.
"""

from __future__ import annotations

from collections.abc import Sequence
import dataclasses
from dataclasses import dataclass, field

from swarm_bringup.launch_plan import default_beacons
from swarm_bringup.scenario import check_before_end, LaunchError, parse_robot_fault
from swarm_common.robot_types import default_type_counts, parse_type_counts
from swarm_common.shapes import load_shape
from swarm_mission.mission import load_sequence, parse_morph
from swarm_sim.headless import HeadlessSwarm, Scenario, ScenarioError, TrialRecord
from swarm_sim.medium import MediumConfig
from swarm_sim.metrics import SETTLE_HOLD_S


@dataclass
class ScenarioSpec:
    """The options of one evaluation (``evaluate --help`` says what each means)."""

    method: str = 'bubble'
    shape: str = 'circle_314'
    shape_scale: float = 1.0
    agents: int = 50
    types: str = ''                     # TYPE:COUNT,...; '' is the thesis 40/40/20 %
    beacons: int | None = None          # None: the launcher's default_beacons(agents)
    duration: float = 600.0
    settle_hold: float = SETTLE_HOLD_S
    sequence: str = ''                  # YAML/JSON shape sequence file
    morph: str = ''                     # KIND:AMOUNT@START+DURATION
    remesh: str = 'incremental'
    remove: Sequence[str] = field(default_factory=list)   # TIME:ID,ID
    loss: float = 0.0
    control_rate: float = 50.0
    auth: bool = True                   # authenticated radio frames (--no-auth: off)
    swarm_key_file: str = ''            # '' : the development key

    @classmethod
    def from_namespace(cls, args) -> ScenarioSpec:
        """The spec of the parsed command line ``args`` (its other options ignored)."""
        return cls(**{f.name: getattr(args, f.name) for f in dataclasses.fields(cls)})


def build_scenario(spec: ScenarioSpec, seed: int) -> Scenario:
    """Scenario of one trial; raises ShapeError/ScenarioError/RobotTypeError on bad input."""
    shape = load_shape(spec.shape, scale=spec.shape_scale)
    counts = parse_type_counts(spec.types) if spec.types else default_type_counts(spec.agents)
    if sum(counts.values()) != spec.agents:
        raise ScenarioError(f'--types {spec.types} sums to {sum(counts.values())} agents but '
                            f'--agents is {spec.agents}')
    beacons = spec.beacons if spec.beacons is not None else default_beacons(spec.agents)
    sequence = load_sequence(spec.sequence, scale=spec.shape_scale) if spec.sequence else ()
    if sequence and sequence[0].time <= 0.0:
        shape, sequence = sequence[0].shape, sequence[1:]
    if spec.morph:
        if spec.sequence:
            raise ScenarioError('give either --sequence or --morph, not both')
        sequence = parse_morph(spec.morph, shape)
    if not spec.settle_hold >= 0.0:
        raise ScenarioError(f'--settle-hold must be >= 0 s, got {spec.settle_hold}')
    try:   # the launcher's parser and checks: one meaning of --remove for both
        removals = [parse_robot_fault('--remove', s, spec.agents) for s in spec.remove]
        check_before_end('--remove', [t for t, _ in removals], spec.duration)
    except LaunchError as exc:
        raise ScenarioError(str(exc)) from None
    return Scenario(shape=shape, method=spec.method, type_counts=counts, n_beacons=beacons,
                    seed=seed, duration_s=spec.duration, sequence=sequence,
                    removals=removals, medium=MediumConfig(loss=spec.loss),
                    control_dt=1.0 / spec.control_rate, remesh=spec.remesh,
                    settle_hold_s=spec.settle_hold, auth=spec.auth,
                    swarm_key_file=spec.swarm_key_file or None)


def run_trial(spec: ScenarioSpec, seed: int) -> TrialRecord:
    """Run one trial (in a worker process); its metrics carry the seed."""
    record = HeadlessSwarm(build_scenario(spec, seed)).run()
    record.metrics['seed'] = seed
    return record
