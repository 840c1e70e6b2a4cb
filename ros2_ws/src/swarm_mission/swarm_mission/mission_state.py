"""What a mission node holds, kept in a file so a restarted node goes on where it stopped.

The thesis's mission computer announces the shape and its goals (4.1, 4.3.4). Under the
launcher and the launch plan its node is respawned when it dies; the shape and goals it
published (transient local) die with its publishers. ``MissionState`` is what the node
needs to publish the same again and continue: the shape (set by parameter, topic or
service), the goals, both version counters, how far a shape sequence had got, and the
agents it had declared lost. ``save`` writes it atomically (a temporary file renamed
over the old one: a kill while writing leaves the previous state whole); ``load`` reads
it back, and only for the same ``run_id``: the state of another run in the same folder
is ignored, so a new run never resumes an old one.

A restarted node publishes the very goals of its last version, under that version, so
the agents (which adopt a goal list by its version, ``AgentBrain.set_goals``) keep their
assignment: nothing is re-partitioned and no round is lost.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
import json
import os
import pathlib

from swarm_common.goals import Goal
from swarm_common.shapes import Shape, shape_from_json, shape_json, ShapeError
from swarm_mission.mission import Mission

FORMAT = 1   # bumped when the file layout changes; other formats are not read


class MissionStateError(ValueError):
    """A state file that cannot be used; the message names the file and the fix."""


@dataclass
class MissionState:
    """The mission node's state between restarts (see the module docstring)."""

    run_id: str
    shape: Shape | None = None
    shape_version: int = 0
    goals: list[Goal] = field(default_factory=list)
    goal_version: int = 0
    next_step: int = 0                  # the next step of the shape sequence
    sequence_start: float | None = None  # sim time the sequence's times count from
    lost: list[int] = field(default_factory=list)

    def to_json(self) -> dict:
        """The file's JSON object."""
        return {'format': FORMAT, 'run_id': self.run_id,
                'shape': None if self.shape is None else {
                    'name': self.shape.name, **shape_json(self.shape)},
                'shape_version': self.shape_version,
                'goals': [asdict(g) for g in self.goals], 'goal_version': self.goal_version,
                'next_step': self.next_step, 'sequence_start': self.sequence_start,
                'lost': sorted(self.lost)}

    @classmethod
    def from_json(cls, data, where: str) -> MissionState:
        """The state of a decoded file; MissionStateError names ``where`` and the field."""
        if not isinstance(data, dict) or data.get('format') != FORMAT:
            raise MissionStateError(f'{where} is not a mission state file of format '
                                    f'{FORMAT}; delete it to start the mission afresh')
        try:
            shape = data['shape']
            start = data['sequence_start']
            return cls(
                run_id=str(data['run_id']),
                shape=None if shape is None else shape_from_json(shape, str(shape['name']),
                                                                 where),
                shape_version=int(data['shape_version']),
                goals=[Goal(int(g['id']), int(g['type']), float(g['x']), float(g['y']),
                            float(g['radius']), bool(g.get('beacon', False)))
                       for g in data['goals']],
                goal_version=int(data['goal_version']), next_step=int(data['next_step']),
                sequence_start=None if start is None else float(start),
                lost=[int(a) for a in data['lost']])
        except (KeyError, TypeError, ValueError, ShapeError) as exc:
            raise MissionStateError(f'{where} holds a broken mission state ({type(exc).__name__}'
                                    f' {exc}); delete it to start the mission afresh') from None


def save(path: str | pathlib.Path, state: MissionState) -> None:
    """Write ``state`` to ``path`` atomically (OSError when the folder is not writable)."""
    path = pathlib.Path(path)
    temporary = path.with_name(path.name + '.tmp')
    temporary.write_text(json.dumps(state.to_json()), encoding='utf-8')
    os.replace(temporary, path)


def load(path: str | pathlib.Path, run_id: str) -> MissionState | None:
    """The state saved at ``path`` by the run ``run_id``; None when there is no file or it
    belongs to another run. MissionStateError for a file that cannot be read."""
    path = pathlib.Path(path)
    try:
        text = path.read_text(encoding='utf-8')
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise MissionStateError(f'cannot read the mission state file {path}: '
                                f'{exc.strerror}') from None
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise MissionStateError(f'mission state file {path} is not valid JSON ({exc}); '
                                'delete it to start the mission afresh') from None
    state = MissionState.from_json(data, f'mission state file {path}')
    return state if state.run_id == run_id else None


def capture(mission: Mission, run_id: str, next_step: int,
            sequence_start: float | None) -> MissionState:
    """The state of ``mission`` now."""
    return MissionState(run_id, mission.shape, mission.shape_version, list(mission.goals),
                        mission.goal_version, next_step, sequence_start, sorted(mission.lost))


def resume(mission: Mission, state: MissionState, t: float) -> None:
    """Put ``state`` back into ``mission`` at time ``t`` (``Mission.resume``)."""
    mission.resume(state.shape, state.shape_version, state.goals, state.goal_version,
                   state.lost, t)
