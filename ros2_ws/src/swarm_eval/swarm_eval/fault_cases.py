"""The cases of the fault study and what each does when (issue 10).

A case is ``{'name', 'kind', 'value'}``; its fault plan (``fault_plan``) lists removals
and run-time settings (``swarm_sim.medium.RUNTIME_SETTINGS``) with their times, for the
headless swarm (``configure_fault``) and the ROS launcher alike. A new kind of case is
one more block in ``fault_cases`` and one more branch in ``fault_plan``.

Rogue cases (``rogue_KIND``, ``swarm_sim.rogue.ROGUE_KINDS``) put a transmitter without
the key on the radio from t = 0: the setting ``rogue`` (sim_node's parameter; headless,
``Scenario.rogues`` gets the same rogue class). Its frames carry a trailer when the
swarm authenticates (``config['auth']``, ``--no-auth`` turns it off to show the damage).
In every rogue case one non-beacon agent is removed at the fault time, so the mission
must notice a loss through the radio the rogue attacks; ``rogue_none`` is that run
without a rogue, the reference the others are compared with.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np

from swarm_eval.scenario import build_scenario, ScenarioSpec
from swarm_sim.headless import HeadlessSwarm, restart_event, ScenarioError
from swarm_sim.medium import apply_setting
from swarm_sim.rogue import make_rogue, ROGUE_KINDS

LOSSES = (0, 10, 20, 30, 50)
KILLS = (10, 30)
RESTARTS = (30,)
RANGES = (12.0, 8.0, 5.0, 3.0)
ROGUE_CASES = tuple(f'rogue_{k}' for k in ('none', *ROGUE_KINDS))
QUICK_CASES = ('loss_0', 'loss_30', 'kill_30', 'restart_30', 'beacons_one', 'range_2',
               'obstacle', *ROGUE_CASES)
ROS_CASES = ('loss_0', 'loss_20', 'loss_50', 'kill_30', 'beacons_half', 'range_2',
             'obstacle', 'rogue_none', 'rogue_adverts', 'rogue_replay')


def fault_cases(ranges: tuple[float, ...] = RANGES) -> list[dict[str, Any]]:
    """The fault cases of the study, in table order."""
    cases: list[dict[str, Any]] = [{'name': f'loss_{p}', 'kind': 'loss', 'value': p / 100.0}
                                   for p in LOSSES]
    cases += [{'name': f'kill_{p}', 'kind': 'kill', 'value': p / 100.0} for p in KILLS]
    cases += [{'name': f'restart_{p}', 'kind': 'restart', 'value': p / 100.0}
              for p in RESTARTS]
    cases.append({'name': 'beacons_one', 'kind': 'beacons', 'value': 1})
    cases.append({'name': 'beacons_half', 'kind': 'beacons', 'value': 0.5})
    cases += [{'name': f'range_{r:g}', 'kind': 'range', 'value': float(r)} for r in ranges]
    cases.append({'name': 'obstacle', 'kind': 'obstacle', 'value': 0.0})
    cases += [{'name': f'rogue_{k}', 'kind': 'rogue', 'value': k}
              for k in ('none', *ROGUE_KINDS)]
    return cases


# ---------------------------------------------------------------------------- faults
def fault_plan(case: dict, config: dict, seed: int, ids: list[int], beacon_ids: list[int],
               half_size: float) -> dict[str, Any]:
    """What the case does and when, for the headless swarm and the ROS launcher alike.

    ``removals``: [(time, [agent ids])]; ``settings``: [(time, name, value)] with the
    names of ``swarm_sim.medium.RUNTIME_SETTINGS`` (sim_node's run-time parameters);
    ``first``/``last``: time of the first fault and of the end of the last one.
    ``restarts``: [(time, [agent ids])] whose processes crash and come back (headless
    only: through ROS tests/e2e/test_restarts.py kills and respawns agent processes).
    A rogue transmits from t = 0 (setting ``rogue``: 1 + its index in ROGUE_KINDS) and
    one non-beacon agent is removed at the fault time.
    """
    kind, value = case['kind'], case['value']
    t_fault = float(config['fault_time'])
    rng = np.random.default_rng([seed, 10_007])
    plan: dict[str, Any] = {'removals': [], 'settings': [], 'restarts': [],
                            'first': t_fault, 'last': t_fault}
    if kind == 'loss':
        plan.update(settings=[(0.0, 'loss', value)], first=0.0, last=0.0)
    elif kind in ('kill', 'restart'):
        count = max(1, int(round(value * len(ids))))
        victims = rng.choice(ids, size=count, replace=False)
        times = np.sort(rng.uniform(t_fault, t_fault + config['fault_window'], size=count))
        plan.update({'removals' if kind == 'kill' else 'restarts':
                     [(float(t), [int(a)]) for t, a in zip(times, victims)]},
                    first=float(times[0]), last=float(times[-1]))
    elif kind == 'beacons':
        count = int(value) if value >= 1 else int(math.ceil(value * len(beacon_ids)))
        victims = rng.choice(beacon_ids, size=count, replace=False) if count else []
        plan['removals'] = [(t_fault, [int(a) for a in victims])]
    elif kind == 'range':
        plan['settings'] = [(t_fault, 'radio_range_m', float(value))]
    elif kind == 'obstacle':
        # A wall as long as the workspace sweeps across it at wall_speed, then vanishes.
        speed = float(config['wall_speed'])
        plan.update(settings=[(t_fault, 'radio_wall_speed_mps', speed)],
                    last=t_fault + 2.0 * half_size / speed)
    elif kind == 'rogue':
        if value != 'none' and value not in ROGUE_KINDS:
            raise ScenarioError(f'unknown rogue {value!r}; use one of {ROGUE_KINDS}')
        victim = int(rng.choice([a for a in ids if a not in set(beacon_ids)] or ids))
        plan['removals'] = [(t_fault, [victim])]
        if value != 'none':
            plan['settings'] = [(0.0, 'rogue', float(ROGUE_KINDS.index(value) + 1))]
    else:
        raise ScenarioError(f'unknown fault kind {kind!r}')
    return plan



def _setting_event(name: str, value: float):
    def apply(swarm: HeadlessSwarm, t: float) -> None:
        apply_setting(swarm.medium, name, value, t, swarm.scenario.half_size)
        swarm.mission.events.append(f't={t:.1f} s: {name} = {value:g}')
    return apply


def configure_fault(swarm: HeadlessSwarm, case: dict, config: dict, seed: int
                    ) -> tuple[float, float]:
    """Schedule the case's fault and its observation window; return (first, last) time."""
    sc = swarm.scenario
    plan = fault_plan(case, config, seed, list(swarm.ids),
                      [swarm.ids[i] for i in np.flatnonzero(swarm.is_beacon)], sc.half_size)
    sc.removals = plan['removals']
    events = [(t, restart_event(victims)) for t, victims in plan['restarts']]
    for t, name, value in plan['settings']:
        if name == 'rogue':   # the world hands it the deliveries (swarm_sim.world_model)
            sc.rogues = [make_rogue(ROGUE_KINDS[int(value) - 1], swarm.ids,
                                    trailer=sc.auth, start_s=t)]
        elif t <= 0.0:
            apply_setting(swarm.medium, name, value, 0.0, sc.half_size)
        else:
            events.append((t, _setting_event(name, value)))
        # A sweeping wall moves with every link update of the world (world_model.World),
        # as in sim_node: no events of its own.
    if case['kind'] != 'loss':
        # A swarm settled through the fault would otherwise stop one hold window after
        # it, before a lost beacon or a shorter range has shown its effect on
        # localization. Not an event: an event is a change, and restarts the hold.
        sc.min_duration_s = plan['last'] + config['observe']
    sc.events = events
    return plan['first'], plan['last']



def build_swarm(case: dict, config: dict, seed: int) -> HeadlessSwarm:
    """The case's swarm: the evaluator's scenario with the study's settings."""
    spec = ScenarioSpec(agents=int(config['agents']), beacons=int(config['beacons']),
                        shape=config['shape'], shape_scale=float(config['shape_scale']),
                        duration=float(config['duration']), method=config['method'],
                        auth=bool(config.get('auth', True)))
    scenario = build_scenario(spec, seed)
    scenario.half_size = config['half_size']
    return HeadlessSwarm(scenario)


def select_cases(cases: list[dict], spec: str, default: set[str] | None) -> list[dict] | None:
    """The cases named in ``spec`` (a comma list), else those in ``default`` (None: all).

    None, after a one-line error naming the known cases, when a name is unknown.
    """
    wanted = set(spec.split(',')) if spec else default
    if wanted is None:
        return cases
    unknown = wanted - {c['name'] for c in cases}
    if unknown:
        print(f'fault_study.py: unknown cases {sorted(unknown)}; known: '
              f'{[c["name"] for c in cases]}', file=sys.stderr)
        return None
    return [c for c in cases if c['name'] in wanted]



def override(base: dict[str, Any], args: argparse.Namespace, keys: tuple[str, ...]) -> None:
    """The arguments given explicitly (not None) replace the defaults in ``base``."""
    for key in keys:
        if getattr(args, key) is not None:
            base[key] = getattr(args, key)
    if args.ranges is not None:
        base['ranges'] = tuple(args.ranges)

