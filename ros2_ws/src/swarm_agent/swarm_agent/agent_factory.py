"""Build a fully configured ``AgentBrain`` from a few parameters and the YAML defaults.

The agent node and the headless evaluator both build their brains here, so the two
paths run identical configurations.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import dataclasses
import time
from typing import Any

import numpy as np

from swarm_agent.brain import AgentBrain
from swarm_agent.brain_config import BrainConfig, BrainConfigError
from swarm_agent.frame_auth import FrameAuth, Keyring, load_keyring, ReplayStore
from swarm_agent.localization import LocalizationConfig
from swarm_agent.lqr import design_lqr
from swarm_agent.route_table import RouteStore
from swarm_common.parameters import configured
from swarm_common.paths import package_file
from swarm_common.robot_types import (
    GRAVITY,
    load_lqr_design,
    load_robot_types,
    parse_type_counts,
    robot_type,
)

# The development key shipped in config/: published, so it authenticates nothing against
# an attacker who has this repository; deployments pass their own (docs/security.md).
DEFAULT_KEY_FILE = package_file('swarm_agent', 'config/swarm_keys.yaml')


def swarm_keyring(swarm_key_file: str | None = None) -> Keyring:
    """The keyring of ``swarm_key_file`` (default: the development key).

    Raises ``frame_auth.FrameAuthError`` with one line naming the file and the fix.
    """
    return load_keyring(str(swarm_key_file or DEFAULT_KEY_FILE))


def make_brain(*, agent_id: int, agent_type: int, is_beacon: bool = False,
               method: str = 'bubble', initial_position: Sequence[float] = (0.0, 0.0),
               seed: int = 0, outer_period_s: float = 0.5,
               consensus_period_s: float = 2.0,
               localization_period_s: float | None = None,
               robot_types_file: str | None = None, external_pose: bool = False,
               localization: LocalizationConfig | None = None,
               initial_position_std: float | None = None,
               settings: Mapping[str, Any] | None = None,
               keyring: Keyring | None = None, auth: bool = True,
               boot_time_s: float | None = None,
               route_store: RouteStore | None = None,
               replay_store: ReplayStore | None = None) -> AgentBrain:
    """An AgentBrain for one robot, with the LQR gains of its type (eqs. 3.108-3.111).

    ``initial_position`` is the robot's deployment prior, the position it was configured
    to stand at, and ``initial_position_std`` (m per axis) its stated uncertainty (the
    placement error, ``swarm_common.fleet.place_fleet``); None keeps the localization
    config's. The estimate becomes the robot's own with its first GPS or trilateration fix.
    ``settings`` are generated parameters (``swarm_common.parameters``, dotted names) set
    on the brain's configuration last; ParameterError names a bad one.
    Radio frames are authenticated under ``keyring`` (default: ``swarm_keyring()``, the
    development key); ``auth=False`` turns that off, for the with/without comparison.
    ``boot_time_s`` (s) seeds the first DSDV sequence number so that a restarted agent's
    numbers are newer than its previous run's (``dsdv.boot_sequence``): None takes the
    wall clock, which survives a process restart; the headless evaluator passes its
    simulated time, so its runs stay reproducible. Brains of one process share
    ``route_store`` and ``replay_store`` (``swarm_agent.route_table``,
    ``frame_auth.ReplayStore``: a frame's receivers opened and routed in one call each).
    """
    types = load_robot_types(robot_types_file)
    robot = robot_type(types, agent_type)
    design = load_lqr_design(robot_types_file)
    gains = design_lqr(robot, design)
    loc = localization or LocalizationConfig()
    if localization_period_s is not None:
        loc = dataclasses.replace(loc, period_s=localization_period_s)
    if initial_position_std is not None:
        if not (np.isfinite(initial_position_std) and initial_position_std >= 0.0):
            raise BrainConfigError(f'initial_position_std must be a finite number >= 0 m, got '
                                   f'{initial_position_std}; use the placement error, e.g. 0.3')
        loc = dataclasses.replace(loc, initial_position_std=float(initial_position_std))
    config = BrainConfig(
        agent_id=agent_id, agent_type=agent_type, is_beacon=is_beacon or external_pose,
        method=method, outer_period_s=outer_period_s,
        consensus_period_s=consensus_period_s, localization=loc,
        type_radii={t: r.coverage_radius for t, r in types.items()})
    if settings:
        config = configured(config, settings)
    # eq. 3.111's u_max shapes the LQR weights of the linear model; the actuator must
    # also overcome Coulomb friction (mu_1 m g is 3.1 N for type 3, above u_max alone).
    u_limit = design.u_max + 2.0 * robot.dry_friction * robot.mass * GRAVITY
    frame_auth = FrameAuth(keyring or swarm_keyring(), store=replay_store) if auth else None
    return AgentBrain(config, robot, gains, initial_position,
                      np.random.default_rng(seed), u_max=u_limit, auth=frame_auth,
                      boot_time_s=time.time() if boot_time_s is None else boot_time_s,
                      route_store=route_store)


def type_counts_from(spec: str | dict[int, int]) -> dict[int, int]:
    """Swarm composition from a ``1:20,2:20,3:10`` string or a mapping."""
    return dict(spec) if isinstance(spec, dict) else parse_type_counts(spec)
