"""The bridge's logic, free of ROS and of the serial port (time is an argument).

Inputs: agents' body-frame velocity setpoints (``cmd_vel``, REP 103: the agent rotates
its setpoint by the camera's yaw, swarm_agent.conversions), camera poses, bytes from the
coordinator XBee. Outputs: bytes to write to it (0x10 frames carrying CmdVel / Stop),
board statuses, counters, and events to log (each cause once, until it clears).

Per robot, every ``poll``:
- a fresh setpoint (younger than ``cmd_timeout``) and a fresh pose (younger than
  ``pose_timeout``) give the CmdVel of that body-frame setpoint (protocol.body_command,
  eqs. 5.1-5.3), sent when it changes and every ``resend_period`` (the board stops by
  itself 500 ms after the last command, SWP_CMD_TIMEOUT_MS);
- a robot that was moving and loses either input is sent Stop once (the agent watchdog;
  without a camera pose the agent's heading, so the frame of its command, is stale);
- a board heard from neither status nor ack for ``board_timeout`` counts as silent.

Who is heard: a 0x90 frame from a 64-bit address that is not in the fleet is dropped
before it is decoded (it never reaches a link, so no agent sees it), counted
(``unknown_address`` frames, ``unknown_senders`` addresses) and logged once per address.
A board's status counts the frames *it* dropped because they did not come from the
coordinator (``foreign``, firmware/PROTOCOL.md): the bridge adds them up per robot
(``foreign_frames``) and warns once per robot that another transmitter is sending it
commands.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
import math

from swarm_bridge import protocol, xbee
from swarm_common.fleet import RobotSpec


@dataclass(frozen=True)
class BridgeParams:
    """Timing and limits of the bridge; defaults equal config/bridge.yaml."""

    max_speed: float = 0.035
    # agent_node publishes cmd_vel when it changes, at most once per outer period
    # (0.5 s, thesis 2 Hz): the timeout must span a few periods or moving robots stutter.
    cmd_timeout: float = 1.5
    pose_timeout: float = 1.0
    resend_period: float = 0.1
    board_timeout: float = 1.0

    def __post_init__(self) -> None:
        """Reject values the link cannot honour, naming the parameter and the fix."""
        if not 0.0 < self.max_speed:
            raise ValueError(f'max_speed must be positive, got {self.max_speed}')
        if self.resend_period * 1000.0 >= protocol.CMD_TIMEOUT_MS:
            raise ValueError(
                f'resend_period {self.resend_period} s must be shorter than the board '
                f'watchdog ({protocol.CMD_TIMEOUT_MS} ms) or robots stutter; use <= 0.25 s')
        for name in ('cmd_timeout', 'pose_timeout', 'board_timeout'):
            if getattr(self, name) <= 0.0:
                raise ValueError(f'{name} must be positive, got {getattr(self, name)}')


@dataclass(frozen=True)
class Event:
    """Something worth one log line: ``level`` is 'info' or 'warn'."""

    level: str
    text: str


@dataclass
class RobotLink:
    """What the bridge knows about one robot."""

    robot: RobotSpec
    setpoint: tuple[float, float] | None = None
    setpoint_time: float = -math.inf
    pose: tuple[float, float, float] | None = None
    pose_time: float = -math.inf
    seq: int = 0
    sent: protocol.CmdVel | None = None
    sent_time: float = -math.inf
    moving: bool = False
    first_sent_time: float | None = None
    heard_time: float | None = None
    silent: bool = False
    status: protocol.Status | None = None
    counters: Counter = field(default_factory=Counter)

    def note_status(self, status: protocol.Status) -> int:
        """Keep a board's status; return how many frames the board dropped as foreign
        since the previous one (its counter is modulo 256 and restarts at power-up)."""
        previous, self.status = self.status, status
        if previous is None or status.faults & protocol.FAULT_RESET:
            return status.foreign
        return (status.foreign - previous.foreign) & 0xFF


class Bridge:
    """Agents' setpoints to XBee frames and board statuses back; see the module doc."""

    def __init__(self, robots: list[RobotSpec], params: BridgeParams | None = None) -> None:
        self.params = params or BridgeParams()
        self.links = {r.id: RobotLink(r) for r in robots}
        self._by_address = {r.address: r.id for r in robots}
        self.decoder = xbee.FrameDecoder()
        self.counters: Counter = Counter()
        self.unknown_senders: Counter = Counter()   # address -> frames dropped
        self.events: list[Event] = []
        self._reported: set[str] = set()
        self._frame_id = 0
        self._pending: dict[int, int] = {}   # frame id -> agent id
        self._seen = xbee.DecoderStats()

    # -- events ------------------------------------------------------------------------
    def _report(self, key: str, text: str, level: str = 'warn') -> None:
        if key not in self._reported:
            self._reported.add(key)
            self.events.append(Event(level, text))

    def _clear(self, key: str, text: str | None = None) -> None:
        if key in self._reported:
            self._reported.discard(key)
            if text:
                self.events.append(Event('info', text))

    def take_events(self) -> list[Event]:
        """Return and forget the events since the last call."""
        events, self.events = self.events, []
        return events

    def report_port_problem(self, cause: str) -> None:
        """Record a serial port failure (the node reopens the port)."""
        self.counters['port_errors'] += 1
        self._report('port', f'serial port failed: {cause}; retrying')

    def report_port_ok(self, port: str) -> None:
        """Record that the serial port is open (again)."""
        self._clear('port', f'serial port {port} open again')

    # -- inputs ------------------------------------------------------------------------
    def on_setpoint(self, agent_id: int, vx: float, vy: float, now: float) -> None:
        """A body-frame velocity setpoint (m/s, ``cmd_vel``) of agent ``agent_id``."""
        link = self.links.get(agent_id)
        if link is None:
            return
        if not (math.isfinite(vx) and math.isfinite(vy)):
            self.counters['bad_setpoints'] += 1
            self._report(f'nan{agent_id}', f'agent {agent_id}: non-finite cmd_vel ignored')
            return
        link.setpoint, link.setpoint_time = (vx, vy), now

    def on_pose(self, agent_id: int, x: float, y: float, yaw: float, now: float) -> None:
        """A camera pose of agent ``agent_id``'s robot (yaw counter-clockwise, rad)."""
        link = self.links.get(agent_id)
        if link is not None and math.isfinite(yaw):
            link.pose, link.pose_time = (x, y, yaw), now

    def on_bytes(self, data: bytes, now: float) -> list[int]:
        """Bytes from the coordinator XBee; return the agent ids with a new status."""
        updated = []
        for frame_data in self.decoder.feed(data):
            agent = self._on_frame(frame_data, now)
            if agent is not None:
                updated.append(agent)
        self._note_decoder()
        return updated

    def _note_decoder(self) -> None:
        stats = self.decoder.stats
        for name in ('bad_checksums', 'truncated', 'oversize', 'garbage_bytes', 'bad_escapes'):
            delta = getattr(stats, name) - getattr(self._seen, name)
            if delta:
                self.counters[name] += delta
                self._report(name, f'serial line: {name.replace("_", " ")} from the XBee '
                             f'(first {delta}); the decoder resynchronises, counting them')
        self._seen = xbee.DecoderStats(**vars(stats))

    def _on_frame(self, frame_data: bytes, now: float) -> int | None:
        try:
            frame = xbee.parse_api_frame(frame_data)
        except xbee.FrameError as exc:
            self.counters['other_frames'] += 1
            self._report(f'api{frame_data[0]:02X}', f'ignoring XBee frame: {exc}', 'info')
            return None
        if isinstance(frame, xbee.TxStatus):
            agent = self._pending.pop(frame.frame_id, None)
            if agent is not None and frame.delivery != xbee.DELIVERY_OK:
                link = self.links[agent]
                link.counters['delivery_failures'] += 1
                self.counters['delivery_failures'] += 1
                self._report(f'delivery{agent}', f'agent {agent}: XBee could not deliver to '
                             f'{link.robot.address_hex} (status 0x{frame.delivery:02X})')
            elif agent is not None:
                self._clear(f'delivery{agent}')
            return None
        if not isinstance(frame, xbee.RxPacket):
            self.counters['other_frames'] += 1
            return None
        agent = self._by_address.get(frame.address)
        if agent is None:
            self.counters['unknown_address'] += 1
            self.unknown_senders[frame.address] += 1
            self.counters['unknown_senders'] = len(self.unknown_senders)
            self._report(f'addr{frame.address:016X}', f'frames from XBee {frame.address:016X}'
                         ', which is not in the fleet, are dropped (counted in '
                         'unknown_address); if it is one of our robots, add it to the fleet '
                         'file')
            return None
        link = self.links[agent]
        try:
            msg = protocol.decode_message(frame.data)
        except protocol.MessageError as exc:
            link.counters['bad_messages'] += 1
            self.counters['bad_messages'] += 1
            self._report(f'msg{agent}', f'agent {agent}: bad message from the board: {exc}')
            return None
        self._heard(link, now)
        if isinstance(msg, protocol.Status):
            foreign = link.note_status(msg)
            link.counters['statuses'] += 1
            if foreign:
                link.counters['foreign_frames'] += foreign
                self.counters['foreign_frames'] += foreign
                self._report(f'foreign{agent}', f'agent {agent}: its board dropped {foreign} '
                             'frame(s) from an XBee other than the coordinator: another '
                             'transmitter is sending it commands (counted in foreign_frames)')
            return agent
        if isinstance(msg, protocol.Ack):
            link.counters['acks'] += 1
            if msg.result != protocol.ACK_OK:
                link.counters['nacks'] += 1
                self.counters['nacks'] += 1
                self._report(f'nack{agent}', f'agent {agent}: board refused command '
                             f'{msg.seq}: {protocol.ACK_NAMES.get(msg.result, msg.result)}')
        return None

    def _heard(self, link: RobotLink, now: float) -> None:
        link.heard_time = now
        if link.silent:
            link.silent = False
            self._clear(f'silent{link.robot.id}',
                        f'agent {link.robot.id}: board answering again')

    # -- outputs -----------------------------------------------------------------------
    def _frame(self, link: RobotLink, message: protocol.Message, now: float) -> bytes:
        self._frame_id = self._frame_id % 255 + 1
        self._pending[self._frame_id] = link.robot.id
        link.seq = (link.seq + 1) & 0xFF
        if link.first_sent_time is None:
            link.first_sent_time = now
        return xbee.encode(xbee.TxRequest(self._frame_id, link.robot.address, message.encode()))

    def poll(self, now: float) -> bytes:
        """Return the frames due at ``now`` (commands, stops) for the serial port."""
        out = bytearray()
        p = self.params
        for agent, link in self.links.items():
            fresh_cmd = now - link.setpoint_time <= p.cmd_timeout
            fresh_pose = now - link.pose_time <= p.pose_timeout
            if fresh_cmd and fresh_pose:
                self._clear(f'stale{agent}', f'agent {agent}: commands resumed')
                cmd = protocol.body_command(*link.setpoint, p.max_speed, link.seq + 1)
                changed = link.sent is None or (cmd.speed, cmd.direction) != (
                    link.sent.speed, link.sent.direction)
                if changed or now - link.sent_time >= p.resend_period:
                    out += self._frame(link, cmd, now)
                    link.sent, link.sent_time, link.moving = cmd, now, True
                    link.counters['commands'] += 1
            elif link.moving:
                cause = 'stopped publishing cmd_vel' if not fresh_cmd else 'has no camera pose'
                self._report(f'stale{agent}', f'agent {agent} {cause}: robot sent STOP')
                out += self._frame(link, protocol.Stop(link.seq + 1), now)
                link.moving, link.sent = False, None
                link.counters['stops'] += 1
                self.counters['watchdog_stops'] += 1
            elif fresh_cmd and link.pose is None:
                self._report(f'nopose{agent}', f'agent {agent}: no camera pose yet; '
                             'robot held still')
            self._check_silence(link, now)
        return bytes(out)

    def _check_silence(self, link: RobotLink, now: float) -> None:
        since = link.heard_time if link.heard_time is not None else link.first_sent_time
        if since is None or link.silent or now - since <= self.params.board_timeout:
            return
        link.silent = True
        link.counters['silences'] += 1
        self.counters['silent_boards'] += 1
        self._report(f'silent{link.robot.id}',
                     f'agent {link.robot.id}: board {link.robot.address_hex} stopped '
                     f'answering (nothing for {now - since:.1f} s)')

    def stop_all(self) -> bytes:
        """Return Stop frames for every robot (shutdown)."""
        out = bytearray()
        for link in self.links.values():
            out += self._frame(link, protocol.Stop(link.seq + 1), 0.0)
            link.moving, link.sent = False, None
        return bytes(out)

    def all_counters(self) -> dict[str, int]:
        """Return the bridge's counters (decoder and links) as plain ints."""
        return dict(self.counters)
