"""Robot messages of the XBee link and the omni-wheel kinematics (thesis eqs. 5.1-5.3).

Pure module. Every constant mirrors firmware/include/swarm_protocol.h, the single
definition of the link (tests/unit/bridge checks that the values are identical), and
:func:`mix_fixed` is the bit-exact twin of firmware/src/mixer.c.

Conventions. The thesis gives the wheel speeds of a three-omni-wheel robot as

    V_A = |Vel| cos(150 - alpha)    (5.1)
    V_B = |Vel| cos( 30 - alpha)    (5.2)
    V_C = |Vel| cos(270 - alpha)    (5.3)

with alpha the direction of motion measured clockwise from the robot's forward axis.
ROS (REP 103) measures angles counter-clockwise with y to the left, so a body-frame
velocity (vx forward, vy left) has alpha = atan2(-vy, vx), and wheel i drives along the
unit vector at counter-clockwise angle -phi_i.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

# -- message types, lengths, codes (swarm_protocol.h) --------------------------------------
MSG_CMD_VEL = 0x01
MSG_STOP = 0x02
MSG_STATUS = 0x81
MSG_ACK = 0x82
LEN_CMD_VEL = 6
LEN_STOP = 2
LEN_STATUS = 14
LEN_ACK = 4

ACK_OK = 0
ACK_BAD_LENGTH = 1
ACK_UNKNOWN_TYPE = 2
ACK_BAD_VALUE = 3
ACK_NAMES = {ACK_OK: 'ok', ACK_BAD_LENGTH: 'bad length', ACK_UNKNOWN_TYPE: 'unknown type',
             ACK_BAD_VALUE: 'bad value'}

FAULT_WATCHDOG = 0x01
FAULT_BAD_FRAME = 0x02
FAULT_RATE_LIMIT = 0x04
FAULT_UART = 0x08
FAULT_BAD_MSG = 0x10
FAULT_FOREIGN = 0x20                 # a frame from another address than the coordinator
FAULT_RESET = 0x80
FAULT_STICKY = FAULT_WATCHDOG
FAULT_NAMES = {FAULT_WATCHDOG: 'watchdog', FAULT_BAD_FRAME: 'bad_frame',
               FAULT_RATE_LIMIT: 'rate_limit', FAULT_UART: 'uart', FAULT_BAD_MSG: 'bad_msg',
               FAULT_FOREIGN: 'foreign', FAULT_RESET: 'reset'}

# -- units and fixed point ---------------------------------------------------------------
SPEED_UNITS_PER_M_S = 10000          # 0.1 mm/s per unit
SPEED_MAX_UNITS = 0xFFFF
DIRECTION_FULL_TURN = 360            # degrees, clockwise from forward
WHEEL_PHI_A = 150                    # eq. 5.1
WHEEL_PHI_B = 30                     # eq. 5.2
WHEEL_PHI_C = 270                    # eq. 5.3
WHEEL_PHI = (WHEEL_PHI_A, WHEEL_PHI_B, WHEEL_PHI_C)
WHEEL_NAMES = ('wheel_a', 'wheel_b', 'wheel_c')
SIN_SHIFT = 15
SIN_TABLE_LEN = 91
SIN_Q15_TABLE = tuple(round(math.sin(math.radians(d)) * (1 << SIN_SHIFT))
                      for d in range(SIN_TABLE_LEN))

HALF_STEPS_PER_REV = 4096
WHEEL_DIAMETER_UM = 58000
STEPS_SHIFT = 12
STEPS_PER_UNIT_Q12 = round(HALF_STEPS_PER_REV / (math.pi * WHEEL_DIAMETER_UM / 1000.0)
                           / 10.0 * (1 << STEPS_SHIFT))
MAX_STEP_RATE = 800                  # half-steps per second per wheel

TICK_HZ = 1000
CMD_TIMEOUT_MS = 500
HEARTBEAT_MS = 200
BAUD = 9600

HALF_STEPS_PER_M = HALF_STEPS_PER_REV / (math.pi * WHEEL_DIAMETER_UM * 1e-6)
# Fastest wheel surface speed, m/s; a robot speed up to this never clips any wheel.
MAX_WHEEL_SPEED_M_S = MAX_STEP_RATE / HALF_STEPS_PER_M


class MessageError(ValueError):
    """RF data that is not a well-formed robot message."""


# -- messages ----------------------------------------------------------------------------
@dataclass(frozen=True)
class CmdVel:
    """Velocity command: speed (0.1 mm/s units) towards direction (deg clockwise)."""

    seq: int
    speed: int
    direction: int

    def encode(self) -> bytes:
        """Return the RF data."""
        if not 0 <= self.speed <= SPEED_MAX_UNITS:
            raise MessageError(f'speed {self.speed} outside 0..{SPEED_MAX_UNITS} units')
        if not 0 <= self.direction < DIRECTION_FULL_TURN:
            raise MessageError(f'direction {self.direction} outside 0..359 degrees')
        return (bytes((MSG_CMD_VEL, self.seq & 0xFF)) + self.speed.to_bytes(2, 'big')
                + self.direction.to_bytes(2, 'big'))


@dataclass(frozen=True)
class Stop:
    """Stop all wheels now."""

    seq: int

    def encode(self) -> bytes:
        """Return the RF data."""
        return bytes((MSG_STOP, self.seq & 0xFF))


@dataclass(frozen=True)
class Status:
    """Heartbeat of a board: what it is doing and what went wrong since the last one."""

    seq: int
    last_cmd_seq: int
    cmd_age_ms: int
    rates: tuple[int, int, int]      # half-steps per second, signed (wheels A, B, C)
    faults: int
    bad_frames: int
    foreign: int = 0                 # frames dropped: not from the coordinator (mod 256)

    def encode(self) -> bytes:
        """Return the RF data."""
        body = b''.join(r.to_bytes(2, 'big', signed=True) for r in self.rates)
        return (bytes((MSG_STATUS, self.seq & 0xFF, self.last_cmd_seq & 0xFF))
                + min(self.cmd_age_ms, 0xFFFF).to_bytes(2, 'big') + body
                + bytes((self.faults, self.bad_frames & 0xFF, self.foreign & 0xFF)))

    def fault_names(self) -> list[str]:
        """Return the names of the fault flags set."""
        return [name for bit, name in FAULT_NAMES.items() if self.faults & bit]

    def wheel_speeds(self) -> tuple[float, float, float]:
        """Return the wheel surface speeds in m/s implied by the step rates."""
        return tuple(r / HALF_STEPS_PER_M for r in self.rates)


@dataclass(frozen=True)
class Ack:
    """Acknowledgement of a command, with a result code (ACK_*)."""

    seq: int
    acked_type: int
    result: int

    def encode(self) -> bytes:
        """Return the RF data."""
        return bytes((MSG_ACK, self.seq & 0xFF, self.acked_type, self.result))


Message = CmdVel | Stop | Status | Ack
_LENGTHS = {MSG_CMD_VEL: LEN_CMD_VEL, MSG_STOP: LEN_STOP, MSG_STATUS: LEN_STATUS,
            MSG_ACK: LEN_ACK}


def decode_message(data: bytes) -> Message:
    """Parse RF data into a message; raise MessageError on unknown types or bad lengths."""
    if len(data) < 2:
        raise MessageError(f'message of {len(data)} bytes is too short (at least 2)')
    kind = data[0]
    if kind not in _LENGTHS:
        raise MessageError(f'unknown message type 0x{kind:02X}')
    if len(data) != _LENGTHS[kind]:
        raise MessageError(f'message type 0x{kind:02X} must be {_LENGTHS[kind]} bytes, '
                           f'got {len(data)}')
    if kind == MSG_CMD_VEL:
        direction = int.from_bytes(data[4:6], 'big')
        if direction >= DIRECTION_FULL_TURN:
            raise MessageError(f'direction {direction} outside 0..359 degrees')
        return CmdVel(data[1], int.from_bytes(data[2:4], 'big'), direction)
    if kind == MSG_STOP:
        return Stop(data[1])
    if kind == MSG_ACK:
        return Ack(data[1], data[2], data[3])
    rates = tuple(int.from_bytes(data[5 + 2 * i:7 + 2 * i], 'big', signed=True)
                  for i in range(3))
    return Status(data[1], data[2], int.from_bytes(data[3:5], 'big'), rates, data[11], data[12],
                  data[13])


# -- kinematics --------------------------------------------------------------------------
def map_to_body(vx: float, vy: float, yaw: float) -> tuple[float, float]:
    """Rotate a map-frame velocity into the body frame of a robot with heading ``yaw``.

    ``yaw`` is counter-clockwise from the map x axis (REP 103), as the camera measures
    it (the thesis measures a clockwise bearing; the camera adapter converts).
    """
    c, s = math.cos(yaw), math.sin(yaw)
    return c * vx + s * vy, -s * vx + c * vy


def body_to_polar(vx: float, vy: float) -> tuple[float, float]:
    """Return (|Vel| m/s, alpha deg clockwise from forward in [0, 360)) of eqs. 5.1-5.3."""
    speed = math.hypot(vx, vy)
    alpha = math.degrees(math.atan2(-vy, vx)) % 360.0 if speed > 0.0 else 0.0
    return speed, alpha


def wheel_speeds(speed: float, alpha_deg: float) -> tuple[float, float, float]:
    """Wheel surface speeds (m/s) of eqs. 5.1-5.3 for |Vel| = speed towards alpha."""
    return tuple(speed * math.cos(math.radians(phi - alpha_deg)) for phi in WHEEL_PHI)


def body_velocity_from_wheels(rates: tuple[float, float, float]) -> tuple[float, float]:
    """Least-squares inverse of eqs. 5.1-5.3: body (vx, vy) m/s from wheel speeds m/s.

    The three drive directions are 120 degrees apart, so the inverse is
    ``(2/3) * sum(V_i d_i)`` with d_i the unit drive direction of wheel i.
    """
    vx = 2.0 / 3.0 * sum(v * math.cos(math.radians(phi)) for v, phi in zip(rates, WHEEL_PHI))
    vy = 2.0 / 3.0 * sum(-v * math.sin(math.radians(phi)) for v, phi in zip(rates, WHEEL_PHI))
    return vx, vy


def quantize(speed: float, alpha_deg: float) -> tuple[int, int]:
    """Return the CmdVel fields (speed units, whole degrees) nearest to speed, alpha."""
    units = min(SPEED_MAX_UNITS, max(0, round(speed * SPEED_UNITS_PER_M_S)))
    return units, round(alpha_deg) % DIRECTION_FULL_TURN


def _sin_q15(deg: int) -> tuple[int, bool]:
    negative = deg >= 180
    if negative:
        deg -= 180
    if deg > 90:
        deg = 180 - deg
    return SIN_Q15_TABLE[deg], negative


def mix_fixed(speed: int, direction: int) -> tuple[tuple[int, int, int], bool]:
    """Bit-exact twin of firmware mixer_mix(): wheel rates in half-steps/s and clipping.

    Each wheel: ``w = round(speed * |cos(phi - alpha)|)`` in speed units from the Q15 sine
    table, ``rate = min(MAX_STEP_RATE, round(w * STEPS_PER_UNIT_Q12 / 2^12))`` with the
    sign of the cosine.
    """
    rates = []
    clipped = False
    for phi in WHEEL_PHI:
        angle = (phi + 90 + DIRECTION_FULL_TURN - direction) % DIRECTION_FULL_TURN
        magnitude, negative = _sin_q15(angle)
        wheel = ((speed * magnitude + (1 << (SIN_SHIFT - 1))) >> SIN_SHIFT) & 0xFFFF
        steps = (wheel * STEPS_PER_UNIT_Q12 + (1 << (STEPS_SHIFT - 1))) >> STEPS_SHIFT
        if steps > MAX_STEP_RATE:
            steps, clipped = MAX_STEP_RATE, True
        rates.append(-steps if negative else steps)
    return (rates[0], rates[1], rates[2]), clipped


def body_command(vx_body: float, vy_body: float, max_speed: float, seq: int) -> CmdVel:
    """Turn a body-frame velocity (m/s, x forward, y left: REP 103, as ``cmd_vel``) into
    the CmdVel of eqs. 5.1-5.3.

    The speed is limited to ``max_speed`` (m/s) keeping the direction, so that no wheel
    of eqs. 5.1-5.3 exceeds its step rate when max_speed <= MAX_WHEEL_SPEED_M_S.
    """
    speed, alpha = body_to_polar(vx_body, vy_body)
    units, direction = quantize(min(speed, max_speed), alpha)
    return CmdVel(seq & 0xFF, units, direction)


def command_for(vx_map: float, vy_map: float, yaw: float, max_speed: float,
                seq: int) -> CmdVel:
    """Turn a map-frame velocity into the CmdVel for a robot heading ``yaw``
    (``body_command`` of the velocity rotated into the body frame)."""
    return body_command(*map_to_body(vx_map, vy_map, yaw), max_speed, seq)
