"""Speed of the bare pybullet world (swarm_sim.world, thesis 4.1), without ROS.

Builds the +/-50 m workspace with N robots of the three Table 4.1 types in the thesis
proportions (20:20:10), then steps it for ``--seconds`` of simulated time while a crude
velocity controller at ``--control-hz`` drives every robot towards a random velocity of
at most 0.5 m/s (new targets every 2 s), reading the state every ``--read-every``
physics steps (1, the default, is the worst case: a read after every step; ``--read
poses`` reads velocities only at the control rate, as sim_node does at its IMU rate).
Prints one JSON line::

    scripts/env.sh python scripts/sim_benchmark.py --robots 50 --terrain rough

``real_time_factor`` is simulated seconds per wall second; ``cpu_real_time_factor`` the
same per CPU second of this process, which a loaded machine disturbs less.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from swarm_common.fleet import random_fleet
from swarm_common.robot_types import default_type_counts, GRAVITY, load_robot_types
from swarm_sim.world import DEFAULT_PHYSICS_HZ, PybulletBackend


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Command line."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--robots', type=int, default=50, help='number of robots (default 50)')
    ap.add_argument('--seconds', type=float, default=20.0, help='simulated seconds (20)')
    ap.add_argument('--terrain', choices=('rough', 'flat'), default='rough')
    ap.add_argument('--physics-hz', type=float, default=DEFAULT_PHYSICS_HZ,
                    help=f'physics rate (default {DEFAULT_PHYSICS_HZ:.0f} Hz)')
    ap.add_argument('--control-hz', type=float, default=50.0,
                    help='rate of the random-velocity controller (default 50 Hz)')
    ap.add_argument('--read-every', type=int, default=1,
                    help='read the state every K physics steps (default 1)')
    ap.add_argument('--read', choices=('both', 'poses'), default='both',
                    help='what each read fetches: poses and velocities (default) or poses '
                    'only (velocities then every control period)')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--half-size', type=float, default=50.0)
    args = ap.parse_args(argv)
    if args.robots <= 0 or args.seconds <= 0 or args.read_every <= 0:
        ap.error('--robots, --seconds and --read-every must be positive')
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print one JSON line."""
    args = parse_args(argv)
    rng = np.random.default_rng(args.seed)
    types = load_robot_types()
    fleet = random_fleet(default_type_counts(args.robots), 0, rng, half_size=args.half_size)
    t0 = time.perf_counter()
    world = PybulletBackend(fleet, types, half_size=args.half_size, terrain=args.terrain,
                            seed=args.seed, physics_hz=args.physics_hz)
    build_s = time.perf_counter() - t0
    n = len(fleet)
    rt = [types[r.type] for r in fleet]
    mass = np.array([t.mass for t in rt])[:, None]
    dry = np.array([t.dry_friction for t in rt])[:, None] * mass * GRAVITY
    fluid = np.array([t.fluid_friction for t in rt])[:, None]
    dt = 1.0 / args.physics_hz
    steps = int(round(args.seconds * args.physics_hz))
    control_every = max(1, int(round(args.physics_hz / args.control_hz)))
    target_every = int(round(2.0 * args.physics_hz))
    forces = np.zeros((n, 2))
    target = np.zeros((n, 2))
    vel = np.zeros((n, 2))
    max_tilt = 0.0
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for k in range(steps):
        if k % target_every == 0:
            heading = rng.uniform(-np.pi, np.pi, n)
            target = rng.uniform(0.0, 0.5, n)[:, None] * np.column_stack(
                [np.cos(heading), np.sin(heading)])
        if k % args.read_every == 0:
            world.positions()
            if args.read == 'both':
                vel = world.velocities()
        if k % control_every == 0:
            if args.read == 'poses':
                vel = world.velocities()
            err = target - vel
            direction = target / np.maximum(np.linalg.norm(target, axis=1, keepdims=True), 1e-9)
            forces = dry * direction + fluid * target + 2.0 * mass * err
        world.step(dt, forces)
    wall_s = time.perf_counter() - wall0
    cpu_s = time.process_time() - cpu0
    max_tilt = float(np.degrees(world.tilts().max()))
    sim_s = world.time
    pos = world.positions()
    ground = world.heightmap.height_at(pos) if world.heightmap else np.zeros(n)
    clearance = float((world.heights() - ground).min())   # < 0: fell through the ground
    result = {
        'robots': n,
        'terrain': args.terrain,
        'physics_hz': args.physics_hz,
        'sim_s': round(sim_s, 6),
        'steps': world.steps,
        'wall_s': round(wall_s, 3),
        'cpu_s': round(cpu_s, 3),
        'real_time_factor': round(sim_s / wall_s, 2),
        'cpu_real_time_factor': round(sim_s / cpu_s, 2) if cpu_s > 0 else None,
        'ms_per_step': round(1e3 * wall_s / world.steps, 4),
        'physics_share': round(world.physics_wall_s / wall_s, 3),
        'build_s': round(build_s, 3),
        'read_every': args.read_every,
        'read': args.read,
        'max_tilt_deg': round(max_tilt, 2),
        'inside_workspace': bool(np.all(np.abs(pos) <= args.half_size)),
        'min_ground_clearance_m': round(clearance, 4),
        'max_slope_deg': round(world.heightmap.max_slope_deg, 2) if world.heightmap else 0.0,
        'load_avg_1min': round(os.getloadavg()[0], 2),
        'cpus': os.cpu_count(),
    }
    world.close()
    print(json.dumps(result))
    return 0



if __name__ == '__main__':
    sys.exit(main())
