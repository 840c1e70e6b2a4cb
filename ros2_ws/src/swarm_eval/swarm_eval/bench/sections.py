"""Benchmark sections measured in this process: DSDV convergence, trilateration,
partition, cost rows and assignment, the radio medium (``benchmarks/run_all.py``)."""

from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np

from swarm_eval.bench.common import log, median, thesis_density_points, timed


def bench_dsdv_section(sizes: Sequence[int], repeats: int, limit_s: float) -> list[dict]:
    from swarm_eval.bench import dsdv as bench_dsdv

    rows = []
    for n in sizes:
        runs = [bench_dsdv.bench(n, seed, limit_s) for seed in range(repeats)]
        row = {'agents': n, 'graphs': len(runs),
               'diameter': median([r['diameter'] for r in runs]),
               'mean_degree': median([r['mean_degree'] for r in runs]),
               'wall_s': median([r['wall_s'] for r in runs]),
               'full_dump_period_s': bench_dsdv.DsdvConfig().full_dump_period_s}
        for key in ('cold_start_s', 'link_break_s', 'link_addition_s'):
            row[key] = median([r.get(key) for r in runs])
            row[key[:-2] + '_periods'] = (None if row[key] is None else
                                          row[key] / row['full_dump_period_s'])
            row[key[:-2] + '_not_converged'] = sum(r.get(key) is None for r in runs)
        for key in ('routing_bytes_per_s_per_agent',
                    'routing_bytes_per_s_per_agent_with_overhead', 'frames_per_s_per_agent'):
            row[key] = median([r[key] for r in runs])
        rows.append(row)
        log(f'  dsdv {n:5d} agents: link break {row["link_break_s"]} s, cold start '
            f'{row["cold_start_s"]} s (simulated), wall {row["wall_s"]:.1f} s per graph')
    return rows


def localization_round(agents: Sequence, heard: Sequence) -> list:
    """Every agent's localization tick (t = 3 s) with the beacons it hears."""
    return [a.localize(3.0, h) for a, h in zip(agents, heard)]


def bench_trilateration(sizes: Sequence[int], repeats: int, seed: int,
                        beacons_per_agent: int = 4) -> list[dict]:
    from swarm_agent.localization import LocalizationConfig, Localizer
    from swarm_sim.medium import MediumConfig

    radio = MediumConfig()
    rows = []
    for n in sizes:
        rng = np.random.default_rng(seed)
        truth, _ = thesis_density_points(n, rng)
        # Each agent hears `beacons_per_agent` beacons somewhere within radio range.
        angle = rng.uniform(0, 2 * np.pi, (n, beacons_per_agent))
        dist = rng.uniform(2.0, radio.range_m, (n, beacons_per_agent))
        beacons = truth[:, None, :] + dist[..., None] * np.stack(
            [np.cos(angle), np.sin(angle)], axis=-1)
        ranges = dist + rng.normal(0.0, radio.range_noise_std, dist.shape)
        heard = [[(beacons[i, k], ranges[i, k], radio.range_noise_std)
                  for k in range(beacons_per_agent)] for i in range(n)]
        config = LocalizationConfig()
        localization_round([Localizer(config, p) for p in truth], heard)   # warm-up
        times, localized = [], []
        for _ in range(repeats):
            agents = [Localizer(config, truth[i] + rng.normal(0.0, 1.0, 2)) for i in range(n)]
            wall, modes = timed(localization_round, agents, heard)
            times.append(wall)
            localized.append(float(np.mean([int(m) == 0 for m in modes])))
        row = {'agents': n, 'beacons_per_agent': beacons_per_agent,
               'round_s': median(times), 'per_agent_s': median(times) / n,
               'localized_share': median(localized)}
        rows.append(row)
        log(f'  trilateration {n:5d} agents: round {row["round_s"] * 1e3:.1f} ms '
            f'({row["per_agent_s"] * 1e6:.0f} us per agent)')
    return rows


def bench_partition_section(sizes: Sequence[int], repeats: int) -> list[dict]:
    from swarm_eval.bench import partition as bench_partition

    rows = []
    for n in sizes:
        for row in bench_partition.bench(n, 'circle_314', repeats):
            rows.append(row)
            log(f'  partition {row["method"]:8s} {n:5d} agents: {row["seconds_median"]:.2f} s')
    return rows


def cost_setup(n: int, seed: int) -> dict:
    """Thesis workspace scaled to n agents: shape, obstacles, goals, agent starts."""
    from swarm_common.fleet import random_fleet
    from swarm_common.robot_types import default_type_counts, load_robot_types
    from swarm_common.shapes import load_shape
    from swarm_mission.partition import partition

    scale = math.sqrt(n / 50.0)
    shape = load_shape('thesis_workspace').scaled(scale)
    types = load_robot_types()
    radii = {t: r.coverage_radius for t, r in types.items()}
    counts = default_type_counts(n)
    rng = np.random.default_rng(seed)
    goals = partition(shape, counts, radii, 'bubble', seed=seed).goals
    fleet = random_fleet(counts, 0, rng, half_size=50.0 * scale,
                         obstacles=list(shape.obstacles))
    return {'shape': shape, 'radii': radii, 'goals': goals, 'fleet': fleet}


def all_cost_rows(by_type: dict, goal_xy: np.ndarray
                  ) -> tuple[dict, list[float], list[tuple[float, int, int]]]:
    """Every agent's row, as ``assign`` takes them, and the time of each row.

    ``by_type``: type -> (grown obstacles, graph, goal columns, starts, agent ids).
    """
    rows, per_agent, worst = {}, [], []
    for t, (_, graph, cols, starts, ids) in by_type.items():
        for agent, start in zip(ids, starts):
            wall, costs = timed(graph.cost_row, start, goal_xy[cols])
            full = np.full(len(goal_xy), np.inf)
            full[cols] = costs
            rows[agent] = (t, full)
            per_agent.append(wall)
            worst.append((wall, t, agent))
    return rows, per_agent, worst


def bench_costs(sizes: Sequence[int], repeats: int, seed: int
                ) -> tuple[list[dict], list[dict]]:
    """Cost rows and the Hungarian assignment over them, per size."""
    from swarm_agent.assignment import assign
    from swarm_agent.costs import VisibilityGraph
    from swarm_agent.free_space import grow_obstacles

    cost_rows, assignment_rows = [], []
    for n in sizes:
        s = cost_setup(n, seed)
        obstacles = list(s['shape'].obstacles)
        goal_types = np.array([g.type for g in s['goals']])
        goal_ids = np.array([g.id for g in s['goals']])
        goal_xy = np.array([[g.x, g.y] for g in s['goals']])
        by_type = {}
        build_times = []
        for t in sorted({r.type for r in s['fleet']}):
            grown = grow_obstacles(obstacles, s['radii'][t])
            wall, graph = timed(VisibilityGraph, grown)
            build_times.append(wall)
            cols = np.flatnonzero(goal_types == t)
            starts = np.array([[r.x, r.y] for r in s['fleet'] if r.type == t])
            ids = [r.id for r in s['fleet'] if r.type == t]
            by_type[t] = (grown, graph, cols, starts, ids)
        # first round: every graph builds its goal-vertex table
        first_wall, (rows, _, worst) = timed(all_cost_rows, by_type, goal_xy)
        steady, agent_times = [], []
        for _ in range(repeats):
            wall, (rows, per_agent, _) = timed(all_cost_rows, by_type, goal_xy)
            steady.append(wall)
            agent_times.extend(per_agent)
        # The slowest agent of the first round, again on a fresh graph of its own (every
        # brain has its own VisibilityGraph): its first row after new goals.
        _, worst_type, worst_agent = max(worst)
        grown, _, cols, starts, ids = by_type[worst_type]
        start = starts[ids.index(worst_agent)]
        first_rows = []
        for _ in range(repeats):
            graph = VisibilityGraph(grown)
            first_rows.append(timed(graph.cost_row, start, goal_xy[cols])[0])
        row = {'agents': n, 'obstacles': len(obstacles), 'goals': len(goal_xy),
               'graph_build_s': median(build_times),
               'row_median_s': median(agent_times),
               'row_worst_first_s': median(first_rows),
               'all_rows_s': median(steady), 'all_rows_first_round_s': first_wall,
               'unreachable_share': float(np.mean([
                   (~np.isfinite(r[1][goal_types == r[0]])).mean() for r in rows.values()]))}
        cost_rows.append(row)
        log(f'  cost rows {n:5d} agents: one row {row["row_median_s"] * 1e3:.2f} ms (worst '
            f'first {row["row_worst_first_s"] * 1e3:.1f} ms), all rows '
            f'{row["all_rows_s"]:.3f} s')
        result = assign(rows, goal_types, goal_ids)   # warm-up
        times = [timed(assign, rows, goal_types, goal_ids)[0] for _ in range(repeats)]
        t1 = min(by_type)
        one_type = {a: r for a, r in rows.items() if r[0] == t1}
        times_one = [timed(assign, one_type, goal_types, goal_ids)[0] for _ in range(repeats)]
        arow = {'agents': n, 'assign_all_s': median(times),
                'assign_one_type_s': median(times_one), 'one_type_agents': len(one_type),
                'assigned_share': len(result) / n}
        assignment_rows.append(arow)
        log(f'  assignment {n:5d} agents: {arow["assign_all_s"] * 1e3:.1f} ms (one type, '
            f'{len(one_type)} agents: {arow["assign_one_type_s"] * 1e3:.1f} ms)')
    return cost_rows, assignment_rows


def send_and_deliver(medium, packets: Sequence, t: float) -> int:
    """Transmit every packet at ``t``; deliver everything due by t + 0.5 s; count it."""
    for packet in packets:
        medium.transmit(t, packet)
    return len(medium.deliver(t + 0.5))


def bench_medium(sizes: Sequence[int], repeats: int, seed: int,
                 payload_bytes: int = 24) -> list[dict]:
    from swarm_agent.packet import BROADCAST, Kind, Packet
    from swarm_common.shapes import load_shape
    from swarm_sim.medium import MediumConfig, RadioMedium

    rows = []
    for n in sizes:
        rng = np.random.default_rng(seed)
        positions, _ = thesis_density_points(n, rng)
        obstacles = list(load_shape('thesis_workspace').scaled(math.sqrt(n / 50.0)).obstacles)
        medium = RadioMedium(MediumConfig(), np.random.default_rng(seed), obstacles)
        ids = list(range(n))
        packets = [Packet(i, BROADCAST, Kind.HEARTBEAT, 0, 1, bytes(payload_bytes))
                   for i in ids]
        medium.update_positions(ids, positions)   # warm-up
        send_and_deliver(medium, packets, -1.0)
        links, traffic, delivered = [], [], []
        for k in range(repeats):
            moved = positions + rng.normal(0.0, 0.05, positions.shape)
            links.append(timed(medium.update_positions, ids, moved)[0])
            wall, count = timed(send_and_deliver, medium, packets, float(k))
            traffic.append(wall)
            delivered.append(count)
        row = {'agents': n, 'obstacles': len(obstacles), 'payload_bytes': payload_bytes,
               'links_s': median(links), 'transmit_deliver_s': median(traffic),
               'step_s': median(np.add(links, traffic)), 'deliveries': median(delivered),
               'mean_degree': median(delivered) / n}
        rows.append(row)
        log(f'  medium {n:5d} agents: links {row["links_s"] * 1e3:.1f} ms, transmit+deliver '
            f'{row["transmit_deliver_s"] * 1e3:.1f} ms ({row["deliveries"]:.0f} deliveries)')
    return rows

