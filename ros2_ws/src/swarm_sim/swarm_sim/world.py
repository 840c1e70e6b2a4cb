"""The pybullet world of the swarm: the thesis's Gazebo environment of section 4.1.

What the thesis built in Gazebo/ODE (4.1, Figs. 4.1-4.2, Table 4.1) and how it is built
here, behind ``swarm_sim.physics.PhysicsBackend`` (as the point-mass model is):

Terrain
    A +/-``half_size`` square (50 m in 4.1) of rough ground: a pybullet
    ``GEOM_HEIGHTFIELD`` from the seeded generator of ``swarm_sim.terrain``
    (``terrain='rough'``, RMS height ``roughness``), or a plane (``terrain='flat'``).
    Walls of ``wall_height`` bound the workspace.
Obstacles
    The shapely polygons of the shape spec, extruded into vertical prisms. A convex
    polygon becomes one convex hull; any other polygon (concave, with holes) is split by
    a constrained Delaunay triangulation into triangles, each extruded into its own
    convex prism. Why not the convex hull of the whole polygon: it would fill the
    concave bays robots must be able to enter. Why not one concave triangle mesh: a
    mesh is a hollow shell that a robot pushed into it tunnels through, while solid
    convex prisms push it back out, and convex-convex contacts are Bullet's fast path.
Robots
    One rigid body per robot, as in 4.1: "collision surfaces composed of four spheres
    [...] bound by cylindrical links". The body is a compound of four spheres of radius
    ``s = 0.2 r_c`` at the corners of a square, placed so the circle of radius ``r_c``
    (the coverage radius of Table 4.1) just covers them; the links are visual only (in
    the GUI), so only the spheres touch the world ("point interaction with the
    environment"). The centre of mass is at the spheres' centres, low enough that the
    body cannot tip over below a ~70 degree slope; roll and pitch are further held by
    a strong angular damping (``angular_damping`` 0.99: rotation decays e-fold in
    0.22 s; it slows spin too), so robots stay upright and follow the ground. Robots
    touch each other through their spheres as well, like the thesis's collision
    surfaces; a robot much smaller than another could in principle slip between its
    spheres, which the agents' separation forces never let happen.
Friction (Table 4.1)
    Dry friction mu_1 is the contact friction: the robot's spheres have
    ``lateralFriction = mu_1`` and every static body 1.0, and Bullet multiplies the two,
    so a robot sliding on flat ground feels mu_1 m g, as in the point-mass model of
    ``swarm_agent.dynamics``. Fluid friction mu_2 (N s/m, force -mu_2 v) is Bullet's
    linear damping, which Bullet applies in C++ as ``v *= (1 - d) ** h`` every step:
    ``d = 1 - exp(-mu_2 / m)`` is exactly the decay of dv/dt = -(mu_2 / m) v, with no
    Python work per step. (It damps the vertical velocity too, which only slows
    settling on bumps a little.)
Input
    A planar force (N, map frame) per robot, applied at the centre of mass with
    ``applyExternalForce`` in the world frame. The application point is the centre of
    mass extrapolated from the last reads (``p + v * elapsed``), so reading the state
    every step is not needed to avoid spurious torques. Forces are held over a
    step (zero-order hold, like the agents' controllers).
Stepping
    A fixed physics step of ``1 / physics_hz`` (100 Hz by default, sim_node's rate):
    ``step(dt)`` runs ``ceil(dt * physics_hz)`` equal sub-steps of at most that length,
    so ``dt = 1 / physics_hz`` is one Bullet step. The state is read lazily, once per
    step at most, when asked for: poses (positions, yaws, tilts) and velocities
    separately, as each costs one pybullet call per robot; ``accelerations`` are the
    mean over the steps since the previous velocity read (the last step's when read
    every step, the mean an IMU integrates otherwise). Robots are dropped from just above the
    ground (found by ray casts) and settle for 0.25 s before t = 0. Why 100 Hz: the
    fastest rate at which Bullet's contacts stay accurate here (terminal velocities
    within 0.2 % of Table 4.1's, see tests/unit/sim/test_world.py) is not the limit;
    cost is: each of a robot's four sphere contacts on the heightfield costs about
    1.5-2 us per step, so 240 Hz would cost 2.4x for no visible gain. No continuous
    collision detection: at the controllers' forces (<= 3 N, speeds <= 0.5 m/s) a body
    moves 5 mm per step, far less than any sphere radius or wall.
Performance
    Every static body (ground, walls, obstacle prisms) is a maximal-coordinate rigid
    body: as a fixed-base multibody (pybullet's default) each robot contact goes
    through the multibody solver and stepping costs three times as much. Robots are
    rigid bodies too. pybullet has no batched state query, so the per-step Python
    work is one ``applyExternalForce`` per pushed robot plus, when read, two state
    queries per robot, all in plain loops (for tens of robots cheaper than numpy).
    ``scripts/sim_benchmark.py`` measures it.
Bad input
    Robots of unknown types, outside the workspace, inside (or overlapping) obstacles
    or overlapping each other raise ``WorldError`` (a ``ValueError``) at construction,
    naming the robot and the fix (``swarm_sim.physics.check_world``). Non-finite forces
    are replaced by zero and forces above ``max_force`` are scaled down to it; both are
    counted (``rejected_forces``, ``clipped_forces``) and the simulation runs on.

DIRECT mode (no window) by default; ``gui=True`` opens pybullet's viewer.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import math
import time

import numpy as np
import pybullet as pb
import shapely
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

from swarm_common.robot_types import GRAVITY, OTHER_COLOUR, RobotType, TYPE_COLOURS
from swarm_sim.physics import check_world, WorldError
from swarm_sim.terrain import (
    DEFAULT_CELL,
    DEFAULT_FEATURE,
    DEFAULT_ROUGHNESS,
    HeightMap,
    rough_terrain,
)

DEFAULT_PHYSICS_HZ = 100.0
SPHERE_FRACTION = 0.2          # contact sphere radius / coverage radius


def robot_geometry(rtype: RobotType) -> tuple[float, float]:
    """(sphere radius, corner offset) of a robot type's four contact spheres (4.1).

    The spheres sit at (+/-a, +/-a) with radius s = 0.2 r_c and a = (r_c - s) / sqrt(2),
    so the coverage circle of radius r_c (Table 4.1) is the smallest circle covering
    the collision surface, as thesis 3.2.1.1 defines it.
    """
    s = SPHERE_FRACTION * rtype.coverage_radius
    return s, (rtype.coverage_radius - s) / math.sqrt(2.0)


def fluid_damping(rtype: RobotType) -> float:
    """Bullet's linear damping d reproducing the fluid friction -mu_2 v of Table 4.1."""
    return 1.0 - math.exp(-rtype.fluid_friction / rtype.mass)


def _quat_yaw(yaw: float) -> list[float]:
    return [0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)]


class PybulletBackend:
    """Rigid-body swarm on rough terrain; see the module docstring."""

    name = 'pybullet'

    def __init__(self, fleet, types: dict[int, RobotType], *,
                 obstacles: Sequence[Polygon] = (), half_size: float = 50.0,
                 terrain: str = 'rough', seed: int = 0, gui: bool = False,
                 physics_hz: float = DEFAULT_PHYSICS_HZ,
                 roughness: float = DEFAULT_ROUGHNESS, feature: float = DEFAULT_FEATURE,
                 cell: float = DEFAULT_CELL, max_force: float = 50.0, wall_height: float = 1.0,
                 obstacle_height: float = 1.0, angular_damping: float = 0.99,
                 solver_iterations: int = 10, visuals: bool | None = None) -> None:
        self.fleet = list(fleet)
        self.half_size = float(half_size)
        self.physics_hz = float(physics_hz)
        self.max_force = float(max_force)
        self.terrain_kind = str(terrain)
        # Validation before any pybullet call, so a bad input leaks nothing.
        self.robot_types, self.obstacles = check_world(
            self.fleet, types, obstacles, self.half_size, self.physics_hz, self.max_force,
            self.terrain_kind)
        self.n = len(self.fleet)
        self.heightmap: HeightMap | None = None
        if self.terrain_kind == 'rough':
            self.heightmap = rough_terrain(self.half_size, seed, roughness=roughness,
                                           feature=feature, cell=cell)
        self.time = 0.0
        self.steps = 0
        self.rejected_forces = 0
        self.physics_wall_s = 0.0     # wall time inside Bullet's stepSimulation
        self.clipped_forces = 0
        # Robot pairs whose bodies began to touch (count_body_contacts; a pair that stays
        # in contact counts once); the pairs touching at the last count.
        self.body_contacts = 0
        self._touching: set[tuple[int, int]] = set()
        self.alive = np.ones(self.n, dtype=bool)
        self._cid = pb.connect(pb.GUI if gui else pb.DIRECT)
        if self._cid < 0:
            raise WorldError('pybullet could not connect (gui=True needs a display)')
        self._visuals = gui if visuals is None else visuals
        try:
            self._build(wall_height, obstacle_height, angular_damping, solver_iterations)
        except Exception:
            self.close()
            raise

    # -- construction
    def _build(self, wall_height: float, obstacle_height: float, angular_damping: float,
               solver_iterations: int) -> None:
        cid = self._cid
        pb.resetSimulation(physicsClientId=cid)
        pb.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=cid)
        self._h = 1.0 / self.physics_hz
        pb.setPhysicsEngineParameter(fixedTimeStep=self._h, numSubSteps=0,
                                     numSolverIterations=int(solver_iterations),
                                     physicsClientId=cid)
        if self._visuals:
            pb.configureDebugVisualizer(pb.COV_ENABLE_RENDERING, 0, physicsClientId=cid)
        z_lo, z_hi = self._build_ground()
        self._build_walls(z_lo, z_hi + wall_height)
        self._obstacle_bodies = [self._build_obstacle(o, z_lo, z_hi + obstacle_height)
                                 for o in self.obstacles]
        self._build_robots(angular_damping, z_lo, z_hi)
        self._settle()
        if self._visuals:
            pb.configureDebugVisualizer(pb.COV_ENABLE_RENDERING, 1, physicsClientId=cid)
            pb.resetDebugVisualizerCamera(0.9 * self.half_size, 30.0, -50.0, [0, 0, 0],
                                          physicsClientId=cid)

    def _build_ground(self) -> tuple[float, float]:
        cid = self._cid
        if self.heightmap is None:
            shape = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
            self._ground = pb.createMultiBody(0, shape, useMaximalCoordinates=True,
                                              physicsClientId=cid)
            z_lo = z_hi = 0.0
        else:
            hm = self.heightmap
            n_y, n_x = hm.shape
            # Bullet reads data[iy * n_x + ix] with ix along x ("rows" = samples along x)
            # and centres the field on its height range.
            shape = pb.createCollisionShape(
                pb.GEOM_HEIGHTFIELD, meshScale=[hm.cell, hm.cell, 1.0],
                heightfieldData=hm.z.ravel().tolist(), numHeightfieldRows=n_x,
                numHeightfieldColumns=n_y, physicsClientId=cid)
            z_lo, z_hi = float(hm.z.min()), float(hm.z.max())
            self._ground = pb.createMultiBody(0, shape, basePosition=[0, 0, 0.5 * (z_lo + z_hi)],
                                              useMaximalCoordinates=True, physicsClientId=cid)
            if self._visuals:
                pb.changeVisualShape(self._ground, -1, rgbaColor=[0.55, 0.5, 0.4, 1],
                                     physicsClientId=cid)
        pb.changeDynamics(self._ground, -1, lateralFriction=1.0, restitution=0.0,
                          physicsClientId=cid)
        return z_lo, z_hi

    def _static_box(self, centre, half_extents) -> int:
        cid = self._cid
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half_extents,
                                        physicsClientId=cid)
        visual = -1
        if self._visuals:
            visual = pb.createVisualShape(pb.GEOM_BOX, halfExtents=half_extents,
                                          rgbaColor=[0.6, 0.6, 0.6, 1], physicsClientId=cid)
        body = pb.createMultiBody(0, shape, visual, basePosition=centre,
                                  useMaximalCoordinates=True, physicsClientId=cid)
        pb.changeDynamics(body, -1, lateralFriction=1.0, restitution=0.0, physicsClientId=cid)
        return body

    def _build_walls(self, z_lo: float, z_top: float) -> None:
        L, t = self.half_size, 0.5
        bottom = z_lo - 1.0
        hz = 0.5 * (z_top - bottom)
        zc = 0.5 * (z_top + bottom)
        self._walls = [
            self._static_box([0, s * (L + t), zc], [L + 2 * t, t, hz]) for s in (-1, 1)
        ] + [
            self._static_box([s * (L + t), 0, zc], [t, L + 2 * t, hz]) for s in (-1, 1)
        ]

    def _build_obstacle(self, polygon: Polygon, z_lo: float, z_top: float) -> list[int]:
        """Static convex prisms of one obstacle (see the module docstring)."""
        hull = polygon.convex_hull
        convex = not polygon.interiors and hull.area - polygon.area <= 1e-9 * max(hull.area, 1)
        if convex:
            pieces = [polygon]
        else:
            pieces = [p for p in shapely.constrained_delaunay_triangles(polygon).geoms
                      if p.area > 1e-12]
        bottom = z_lo - 1.0
        bodies = []
        cid = self._cid
        for piece in pieces:
            ring = np.asarray(orient(piece, 1.0).exterior.coords)[:-1]   # counter-clockwise
            centre = ring.mean(axis=0)
            local = ring - centre
            verts = [[x, y, z] for z in (bottom, z_top) for x, y in local]
            shape = pb.createCollisionShape(pb.GEOM_MESH, vertices=verts, physicsClientId=cid)
            visual = -1
            if self._visuals:
                visual = pb.createVisualShape(pb.GEOM_MESH, vertices=verts,
                                              indices=_prism_indices(len(local)),
                                              rgbaColor=[0.3, 0.6, 0.3, 1], physicsClientId=cid)
            body = pb.createMultiBody(0, shape, visual,
                                      basePosition=[centre[0], centre[1], 0.0],
                                      useMaximalCoordinates=True, physicsClientId=cid)
            pb.changeDynamics(body, -1, lateralFriction=1.0, restitution=0.0,
                              physicsClientId=cid)
            bodies.append(body)
        return bodies

    def _robot_shapes(self, rtype: RobotType) -> tuple[int, int]:
        cid = self._cid
        s, a = robot_geometry(rtype)
        corners = [[a, a, 0.0], [-a, a, 0.0], [-a, -a, 0.0], [a, -a, 0.0]]
        col = pb.createCollisionShapeArray([pb.GEOM_SPHERE] * 4, radii=[s] * 4,
                                           collisionFramePositions=corners,
                                           physicsClientId=cid)
        vis = -1
        if self._visuals:
            # The thesis's cylindrical links bind neighbouring spheres (4.1).
            colour = [*TYPE_COLOURS.get(rtype.type_id, OTHER_COLOUR), 1.0]
            along_x = pb.getQuaternionFromEuler([0.0, 0.5 * math.pi, 0.0])
            along_y = pb.getQuaternionFromEuler([0.5 * math.pi, 0.0, 0.0])
            vis = pb.createVisualShapeArray(
                [pb.GEOM_SPHERE] * 4 + [pb.GEOM_CYLINDER] * 4,
                radii=[s] * 4 + [0.3 * s] * 4, lengths=[0.0] * 4 + [2 * a] * 4,
                rgbaColors=[colour] * 8,
                visualFramePositions=corners + [[0, a, 0], [0, -a, 0], [a, 0, 0], [-a, 0, 0]],
                visualFrameOrientations=[[0, 0, 0, 1]] * 4 + [along_x] * 2 + [along_y] * 2,
                physicsClientId=cid)
        return col, vis

    def _spawn_heights(self, z_lo: float, z_hi: float) -> np.ndarray:
        """Body heights that put every robot's lowest sphere just above the ground."""
        n = self.n
        if self.heightmap is None:
            return np.array([robot_geometry(t)[0] for t in self.robot_types]) + 0.005
        starts, ends = [], []
        for r, t in zip(self.fleet, self.robot_types):
            s, a = robot_geometry(t)
            c, si = math.cos(r.yaw), math.sin(r.yaw)
            for dx, dy in ((a, a), (-a, a), (-a, -a), (a, -a), (0.0, 0.0)):
                x, y = r.x + c * dx - si * dy, r.y + si * dx + c * dy
                starts.append([x, y, z_hi + 1.0])
                ends.append([x, y, z_lo - 1.0])
        ground = np.array(self.ground_height_rays(starts, ends)).reshape(n, 5)
        radius = np.array([robot_geometry(t)[0] for t in self.robot_types])
        return ground.max(axis=1) + radius + 0.01

    def _build_robots(self, angular_damping: float, z_lo: float, z_hi: float) -> None:
        cid = self._cid
        shapes: dict[int, tuple[int, int]] = {}
        z0 = self._spawn_heights(z_lo, z_hi)
        self._bodies: list[int] = []
        for k, (r, t) in enumerate(zip(self.fleet, self.robot_types)):
            if t.type_id not in shapes:
                shapes[t.type_id] = self._robot_shapes(t)
            col, vis = shapes[t.type_id]
            body = pb.createMultiBody(t.mass, col, vis, basePosition=[r.x, r.y, z0[k]],
                                      baseOrientation=_quat_yaw(r.yaw),
                                      useMaximalCoordinates=True, physicsClientId=cid)
            pb.changeDynamics(body, -1, lateralFriction=t.dry_friction, restitution=0.0,
                              rollingFriction=0.0, spinningFriction=0.0,
                              linearDamping=fluid_damping(t), angularDamping=angular_damping,
                              activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING,
                              physicsClientId=cid)
            self._bodies.append(body)
        self._pos = np.column_stack([[r.x for r in self.fleet], [r.y for r in self.fleet], z0])
        self._quat = np.array([_quat_yaw(r.yaw) for r in self.fleet])
        self._vel = np.zeros((self.n, 3))
        self._acc = np.zeros((self.n, 2))
        self._t_pose = self._t_vel = 0.0
        self._poses_stale = self._vels_stale = False
        # Per robot (x, y, z, vx, vy, vz) at the last read, None once removed.
        self._com_state: list[tuple | None] = [
            (float(x), float(y), float(z), 0.0, 0.0, 0.0) for x, y, z in self._pos]

    def _settle(self, seconds: float = 0.25) -> None:
        """Let the dropped robots land before t = 0, so the first push meets friction."""
        for _ in range(int(round(seconds / self._h))):
            pb.stepSimulation(physicsClientId=self._cid)
        self._poses_stale = self._vels_stale = True
        self._read_poses()
        self._read_velocities()
        self._acc[:] = 0.0
        self._t_pose = self._t_vel = 0.0

    # -- the Backend interface
    def step(self, dt: float, forces) -> None:
        """Advance by ``dt`` seconds under planar ``forces`` (N, 2) in newtons, map frame."""
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f'step dt must be a positive number of seconds, got {dt!r}')
        f = np.asarray(forces, dtype=float)
        if f.shape != (self.n, 2):
            raise ValueError(f'forces must have shape ({self.n}, 2), got {f.shape}')
        substeps = max(1, math.ceil(dt * self.physics_hz - 1e-9))
        h = dt / substeps
        cid = self._cid
        if h != self._h:
            pb.setPhysicsEngineParameter(fixedTimeStep=h, physicsClientId=cid)
            self._h = h
        # Plain Python over the robots: for tens of robots it beats a chain of small numpy
        # calls, and the applyExternalForce calls need the Python loop anyway.
        limit, limit_sq, isfinite = self.max_force, self.max_force ** 2, math.isfinite
        pushes = []
        for body, (fx, fy), state in zip(self._bodies, f.tolist(), self._com_state):
            if state is None:                      # removed
                continue
            if not (isfinite(fx) and isfinite(fy)):
                self.rejected_forces += 1
                continue
            sq = fx * fx + fy * fy
            if sq == 0.0:
                continue
            if sq > limit_sq:
                self.clipped_forces += 1
                scale = limit / math.sqrt(sq)
                fx, fy = fx * scale, fy * scale
            pushes.append((body, (fx, fy, 0.0), state))
        apply, world, stepsim = pb.applyExternalForce, pb.WORLD_FRAME, pb.stepSimulation
        clock = time.perf_counter
        for _ in range(substeps):
            # Centre of mass extrapolated from the last read (module docstring).
            e = self.time - self._t_pose
            for body, force, (px, py, pz, vx, vy, vz) in pushes:
                # Positional client id: keyword parsing costs ~1 us a call.
                apply(body, -1, force, (px + vx * e, py + vy * e, pz + vz * e), world, cid)
            t0 = clock()
            stepsim(cid)
            self.physics_wall_s += clock() - t0
            self.steps += 1
            self.time += h
        self._poses_stale = self._vels_stale = True

    def count_body_contacts(self, pairs: Iterable[tuple[int, int]]) -> int:
        """Of the robot pairs (fleet indices) given, how many bodies touch now; pairs that
        did not at the last count add to ``body_contacts``.

        A body lies within its coverage circle, so only pairs whose circles overlap can
        touch: give those (``SeparationTracker.overlapping_pairs``), after every step.
        Asking Bullet for all contact points instead costs 0.6 ms a step with 50 robots
        (their ground contacts), a sixth of the step.
        """
        touching = set()
        for i, j in pairs:
            if self.alive[i] and self.alive[j] and pb.getContactPoints(
                    self._bodies[i], self._bodies[j], physicsClientId=self._cid):
                touching.add((i, j) if i < j else (j, i))
        self.body_contacts += len(touching - self._touching)
        self._touching = touching
        return len(touching)

    def _read_poses(self) -> None:
        """Read every living body's pose, once per step at most (positions, yaws, tilts)."""
        if not self._poses_stale:
            return
        self._poses_stale = False
        cid, get_pose, com = self._cid, pb.getBasePositionAndOrientation, self._com_state
        rows, living = [], []
        for i, body in enumerate(self._bodies):
            state = com[i]
            if state is None:
                continue
            p, q = get_pose(body, cid)
            com[i] = p + state[3:]
            rows.append(p + q)
            living.append(i)
        if rows:
            arr = np.array(rows)
            if len(living) == self.n:
                self._pos, self._quat = arr[:, :3], arr[:, 3:]
            else:
                self._pos[living], self._quat[living] = arr[:, :3], arr[:, 3:]
        self._t_pose = self.time

    def _read_velocities(self) -> None:
        """Read every living body's velocity, once per step at most (and accelerations)."""
        if not self._vels_stale:
            return
        self._vels_stale = False
        cid, get_vel, com = self._cid, pb.getBaseVelocity, self._com_state
        rows, living = [], []
        for i, body in enumerate(self._bodies):
            state = com[i]
            if state is None:
                continue
            v = get_vel(body, cid)[0]
            com[i] = state[:3] + v
            rows.append(v)
            living.append(i)
        elapsed = self.time - self._t_vel
        if rows:
            vel = np.array(rows)
            if len(living) == self.n:
                if elapsed > 0:
                    self._acc = (vel[:, :2] - self._vel[:, :2]) / elapsed
                self._vel = vel
            else:
                if elapsed > 0:
                    self._acc[living] = (vel[:, :2] - self._vel[living, :2]) / elapsed
                self._vel[living] = vel
        self._t_vel = self.time

    def positions(self) -> np.ndarray:
        """Planar positions (N, 2) in metres; removed robots keep their last one."""
        self._read_poses()
        return self._pos[:, :2].copy()

    def velocities(self) -> np.ndarray:
        """Planar velocities (N, 2) in m/s; zero for removed robots."""
        self._read_velocities()
        return self._vel[:, :2].copy()

    def accelerations(self) -> np.ndarray:
        """Mean planar accelerations (N, 2) since the previous velocity read (m/s^2)."""
        self._read_velocities()
        return self._acc.copy()

    def yaws(self) -> np.ndarray:
        """Heading of every body (rad, about the world z axis)."""
        self._read_poses()
        x, y, z, w = self._quat.T
        return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

    def heights(self) -> np.ndarray:
        """Height of every body's centre of mass (m)."""
        self._read_poses()
        return self._pos[:, 2].copy()

    def tilts(self) -> np.ndarray:
        """Angle between every body's up axis and the world's (rad): 0 is upright."""
        self._read_poses()
        x, y = self._quat[:, 0], self._quat[:, 1]
        return np.arccos(np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0))

    # -- faults and queries
    def remove(self, i: int) -> None:
        """Take robot ``i`` (fleet index) out of the world (a fault); idempotent."""
        if not 0 <= i < self.n:
            raise IndexError(f'robot index {i} outside 0..{self.n - 1}')
        if self.alive[i]:
            self._read_poses()
            self._read_velocities()
            pb.removeBody(self._bodies[i], physicsClientId=self._cid)
            self.alive[i] = False
            self._com_state[i] = None
            self._vel[i] = 0.0
            self._acc[i] = 0.0

    def move_obstacle(self, k: int, dx: float, dy: float) -> None:
        """Translate obstacle ``k`` by (dx, dy) metres (a changing environment)."""
        from shapely import affinity
        if not 0 <= k < len(self._obstacle_bodies):
            raise IndexError(f'obstacle index {k} outside 0..{len(self._obstacle_bodies) - 1}')
        cid = self._cid
        for body in self._obstacle_bodies[k]:
            pos, orn = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
            pb.resetBasePositionAndOrientation(body, [pos[0] + dx, pos[1] + dy, pos[2]], orn,
                                               physicsClientId=cid)
        self.obstacles[k] = affinity.translate(self.obstacles[k], dx, dy)

    def ground_height_rays(self, starts, ends) -> list[float]:
        """Height of the first hit of each vertical ray (NaN when a ray hits nothing)."""
        out: list[float] = []
        for k in range(0, len(starts), 4096):
            hits = pb.rayTestBatch(starts[k:k + 4096], ends[k:k + 4096],
                                   physicsClientId=self._cid)
            out.extend(h[3][2] if h[0] >= 0 else math.nan for h in hits)
        return out

    def ground_height(self, xy) -> np.ndarray:
        """Height of whatever is topmost at planar points (M, 2) by ray casting."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        starts = [[x, y, 100.0] for x, y in xy]
        ends = [[x, y, -100.0] for x, y in xy]
        return np.array(self.ground_height_rays(starts, ends))

    def close(self) -> None:
        """Disconnect from pybullet; idempotent."""
        if getattr(self, '_cid', -1) >= 0:
            try:
                pb.disconnect(physicsClientId=self._cid)
            except pb.error:
                pass
            self._cid = -1

    def __enter__(self) -> PybulletBackend:
        return self

    def __exit__(self, *_) -> None:
        self.close()


def _prism_indices(m: int) -> list[int]:
    """Triangles of a convex prism with ``m`` bottom vertices then ``m`` top ones."""
    idx = []
    for k in range(1, m - 1):
        idx += [0, k + 1, k]                 # bottom, facing down
        idx += [m, m + k, m + k + 1]         # top, facing up
    for k in range(m):
        j = (k + 1) % m
        idx += [k, j, m + j, k, m + j, m + k]
    return idx
